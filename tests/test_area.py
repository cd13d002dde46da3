"""The area criterion end to end: the library's D-slot depth pass and per-cell pass against the float64 references.

The per-cell kernel of the area criterion against its float64 reference, fed the reference's D-slot keys.

The exact visible-area references: the planar core on degenerate configurations, and the per-lamp areas."""

import numpy as np
import pytest
import warp as wp
from helpers import (
    DEVICES,
    device_arrays,
    first_surface_raster,
    polydisperse_scene,
    raster_tolerance,
    raster_visible_areas,
)

import warp_lamp as wl
from warp_lamp.kernels import area as KA
from warp_lamp.kernels.lamp import LampParticles
from warp_lamp.lamp import lamp_mask
from warp_lamp.measures import visible_area_error
from warp_lamp.reference import area_depth_slots, area_estimate_reference, visible_area_reference
from warp_lamp.reference.area import (
    EXACT_UNIT,
    _pair_relations,
    _surface_order,
    ordered_key,
    visible_disk_areas,
    visible_sphere_areas,
)
from warp_lamp.scenes import scene_overlapping_polydisperse


def area_lamp(centers, radii, device, **options):
    return wl.lamp_update(centers, radii, criterion="area", device=device, **options)


def scenes(rng):
    c, r = polydisperse_scene(rng, n=150)
    yield "random", c, r
    yield "snapped", np.round(c * 4) / 4, np.round(r * 8 + 1) / 8
    yield "dense", rng.uniform(0, 4, (300, 3)), rng.uniform(0.25, 0.42, 300)


@pytest.mark.parametrize("depth_slots", [1, 3, 4, 6])
def test_depth_slots_equal_the_reference_bitwise(device, rng, depth_slots):
    """The D-slot depth pass on the cell corners keeps bitwise the reference's D smallest (depth, id) keys per
    corner ray and lamp, cold and warm-started from other positions, for any split of its work."""
    for _, c, r in scenes(rng):
        grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3)
        want, _ = area_depth_slots(c, r, grid, depth_slots=depth_slots)
        for split in (1, 4):
            lamp = wl.ShiningLamp(grid, criterion="area", depth_slots=depth_slots, split=split, device=device)
            pos, rad = device_arrays(grid.to_frame(c), r, device)
            other, _ = device_arrays(grid.to_frame(c + rng.normal(scale=0.1, size=c.shape)), r, device)
            lamp.update(other, rad, in_frame=True)
            lamp.update(pos, rad, in_frame=True)
            np.testing.assert_array_equal(lamp.keys.numpy(), want)


@pytest.mark.parametrize("resolver", ["subpoints", "exact"])
def test_units_equal_the_estimator_reference(device, rng, resolver):
    """Sub-points: every particle's units equal the reference's exactly. Exact resolver (float32 against
    float64): no particle is off by more than 2 units of 4096 per cell and axis. Balance is exact."""
    for name, c, r in scenes(rng):
        lamp = area_lamp(c, r, device, resolver=resolver, cells_per_diameter=3)
        ref = area_estimate_reference(c, r, lamp.grid, resolver=resolver)
        got = lamp.counts_numpy()
        assert lamp.unit == ref.unit
        if resolver == "subpoints":
            np.testing.assert_array_equal(got, ref.units, err_msg=name)
        else:
            assert np.abs(got - ref.units).max() <= 2, name
        np.testing.assert_array_equal(got.sum(axis=0), [0, 0, 0])


def test_forces_are_exactly_balanced_and_converge_to_the_visible_area(device, rng):
    """lamp_forces with criterion='area': the float64 forces sum to exactly zero, and on random disjoint spheres at
    3 cells per diameter the per-particle force error against P times the exact visible areas, RMS over P pi r^2,
    stays below 1.5% (sub-points; measured 1.0%) and 0.1% (exact; measured 0.05%), where criterion 1 on the same
    cells errs by over 10% (measured 22%)."""
    c = rng.uniform(0, 5, (400, 3))
    r = rng.uniform(0.2, 0.35, 400)
    keep = np.ones(len(r), dtype=bool)
    for i in range(len(r)):  # drop overlaps: the visible areas are exact for disjoint spheres
        d = np.linalg.norm(c[:i][keep[:i]] - c[i], axis=1)
        keep[i] = np.all(d > r[:i][keep[:i]] + r[i])
    c, r = c[keep], r[keep]
    exact = visible_area_reference(c, r)
    net = exact[:, 0::2] - exact[:, 1::2]
    scale = np.pi * np.mean(r) ** 2
    err = {}
    for name, options in {
        "subpoints": {"criterion": "area"},
        "exact": {"criterion": "area", "resolver": "exact"},
        "c1": {"criterion": 1},
    }.items():
        f = wl.lamp_forces(c, r, 1.0, cells_per_diameter=3, device=device, **options)
        assert np.array_equal(f.sum(axis=0), np.zeros(3)), name
        err[name] = np.sqrt(np.mean(np.sum((f - net) ** 2, axis=1))) / scale
    assert err["subpoints"] < 0.015 and err["exact"] < 0.001 and err["c1"] > 0.10, err


def test_lone_sphere_loads_its_disk(device):
    """A lone sphere at random offsets: the exact resolver loads pi r^2 per lamp to 1e-3, both lamps of an axis
    alike, so its net force is zero; criterion 1 at the same cells is off by up to 20%."""
    rng = np.random.default_rng(4)
    r = 0.5
    grid = wl.LampGrid([-1.0] * 3, [1.0] * 3, 1.0 / 3.0)
    for off in rng.uniform(0, 1.0 / 3.0, (6, 3)):
        lamp = area_lamp(off[None, :], [r], device, grid=grid, resolver="exact", lamps=["-x", "-y", "-z"])
        load = lamp.counts_numpy()[0] * grid.cell_area / lamp.unit
        np.testing.assert_allclose(load, np.pi * r * r, rtol=1e-3)
        f = wl.lamp_forces(off[None, :], [r], 1.0, grid=grid, criterion="area", resolver="exact", device=device)
        np.testing.assert_array_equal(f, 0.0)


def test_shining_lamp_area_mode_is_capturable_and_adds_lamp_forces(device, rng):
    """ShiningLamp with criterion='area': forces added equal float32(lamp_forces), and a captured update replays
    to the eager result."""
    c, r = polydisperse_scene(rng, n=200)
    c = c.astype(np.float32).astype(np.float64)
    grid = wl.LampGrid([-1.0] * 3, [6.0] * 3, 0.125)
    expected = wl.lamp_forces(c, r, 1.0e5, grid=grid, criterion="area", device=device)
    lamp = wl.ShiningLamp(grid, criterion="area", device=device)
    pos, rad = device_arrays(c, r, device)
    forces = wp.zeros(len(r), dtype=wp.vec3, device=device)
    lamp.apply(pos, rad, forces, 1.0e5)
    np.testing.assert_array_equal(forces.numpy(), expected.astype(np.float32))
    with wp.ScopedCapture(device=device) as capture:
        forces.zero_()
        lamp.apply(pos, rad, forces, 1.0e5)
    lamp.keys.fill_(0)
    wp.capture_launch(capture.graph)
    np.testing.assert_array_equal(forces.numpy(), expected.astype(np.float32))


def test_area_memory_is_checked_before_allocation():
    """The D keys per corner ray and lamp are counted against max_bytes before anything is allocated."""
    grid = wl.LampGrid([0, 0, 0], [1, 1, 1], 0.01)
    with pytest.raises(ValueError, match=r"depth_slots: 4 keys per lamp on 30,603 rays need 1,958,592 bytes"):
        wl.ShiningLamp(grid, criterion="area", depth_slots=4, max_bytes=1_000_000, device="cpu")
    for kwargs, match in (
        ({"depth_slots": 7}, r"depth_slots: expected an integer in \[1, 6\]"),
        ({"resolver": "fast"}, r"resolver: expected one of"),
        ({"subpoints": 0}, r"subpoints: expected an integer in \[1, 16\]"),
        ({"criterion": "areas"}, r"criterion: expected 0"),
    ):
        with pytest.raises(ValueError, match=match):
            wl.ShiningLamp(grid, device="cpu", **{"criterion": "area", **kwargs})


def test_cpu_and_cuda_bitwise_equal_for_subpoints(cuda_device, rng):
    """Sub-point units and the D-slot keys on CUDA are bitwise those of the CPU."""
    for _, c, r in scenes(rng):
        cpu = area_lamp(c, r, "cpu", cells_per_diameter=3)
        gpu = area_lamp(c, r, cuda_device, cells_per_diameter=3)
        np.testing.assert_array_equal(cpu.keys.numpy(), gpu.keys.numpy())
        np.testing.assert_array_equal(cpu.counts_numpy(), gpu.counts_numpy())


def test_nested_sphere_gets_no_force(device):
    """The issue's example: a sphere wholly inside another (r = 0.1 at x = 0.2 in r = 0.5), lamp +x alone: it took
    0.93 of its disk by centre depth; now nothing, with either resolver, and the big one its whole disk."""
    for resolver in ("exact", "subpoints"):
        f = wl.lamp_forces(
            [[0, 0, 0], [0.2, 0, 0]], [0.5, 0.1], 1.0, criterion="area", lamps=["+x"], resolver=resolver, device=device
        )
        assert np.all(f[1] == 0.0)
        assert f[0, 0] == pytest.approx(-np.pi * 0.25, rel=2e-3 if resolver == "exact" else 5e-3)


@pytest.mark.parametrize("resolver", ["exact", "subpoints"])
def test_two_overlapping_unequal_spheres(device, resolver):
    """The issue's example: centres (0, 0, 0) and (0.45, 0.05, 0), radii 0.5 and 0.15; the small sphere's load from
    -y and from +y equals its visible area by a 2048 x 2048 first-surface raster (0.02416 and 0.03176) to 3e-4
    at 8 cells per diameter (measured: 3e-5 and 1e-4 at most), where the order by centre depth gave 0.02267 and
    0.0707 (its whole disk)."""
    c = np.array([[0.0, 0.0, 0.0], [0.45, 0.05, 0.0]])
    r = np.array([0.5, 0.15])
    for lamp, sign in (("-y", 1.0), ("+y", -1.0)):
        view = np.column_stack([c[:, 2], c[:, 0], sign * c[:, 1]])  # the -y lamp's plane is (z, x)
        want, _ = first_surface_raster(view, r, (-0.15, 0.3, 0.15, 0.6), 2048)
        f = wl.lamp_forces(
            c, r, 1.0, criterion="area", lamps=[lamp], resolver=resolver, cells_per_diameter=8, device=device
        )
        assert abs(sign * f[1, 1] - want[1]) < 3e-4, (lamp, sign * f[1, 1], want[1])


def test_overlapping_packing_meets_the_targets(device):
    """A polydisperse ball (radius ratio 3) whose spheres overlap by up to 30% of the smaller radius, at 4 cells
    per mean diameter: per-particle force RMS against a first-surface raster of 256 rays per mean diameter is
    under 0.06% of P pi rbar^2 with the exact resolver (measured 0.039%, 0.034% against 512 rays; the raster
    itself moves 0.024% between the two) and 0.6% with sub-points (measured 0.53%; the 1,000-sphere ball, against
    128 rays per diameter, 0.96% and 1.06% by centre depth, 0.08% and 0.46% now); balance stays exact."""
    s = scene_overlapping_polydisperse(300)
    areas, _ = raster_visible_areas(s.centers, s.radii, 256)
    rms = {}
    for resolver in ("exact", "subpoints"):
        f = wl.lamp_forces(s.centers, s.radii, 1.0, criterion="area", resolver=resolver, device=device)
        assert np.all(f.sum(axis=0) == 0.0)
        rms[resolver] = visible_area_error(f, areas, 1.0, float(s.radii.mean()))["rms"]
    assert rms["exact"] < 0.0006 and rms["subpoints"] < 0.006, rms


@pytest.mark.parametrize("resolver", ["subpoints", "exact"])
def test_deferred_undecided_cells_equal_the_one_thread_pass(device, resolver):
    """Undecided cells resolved by a thread per row of points (the GPU's default) give bitwise the counts and
    counters of one thread per cell, on a packing of overlapping spheres (many undecided cells, some past the
    work list's room, which the cell pass then resolves itself)."""
    scene = scene_overlapping_polydisperse(n=300)
    grid = wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=3)
    pos = wp.array(grid.to_frame(scene.centers).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    out = []
    for defer in (False, True):
        lamp = wl.ShiningLamp(grid, criterion="area", resolver=resolver, device=device)
        lamp.estimator.defer = defer
        lamp.update(pos, rad, in_frame=True)
        d = lamp.diagnostics()
        out.append((lamp.counts_numpy(), d.area_overflow, d.area_one_sided))
        if defer:
            asked = int(lamp.estimator._work["count"].numpy()[0])
            assert asked > lamp.estimator._work["cells"].shape[0]  # the list overflowed: both paths ran
    np.testing.assert_array_equal(out[0][0], out[1][0])
    assert out[0][1:] == out[1][1:]


LOW = ("-x", "-y", "-z")

HIGH = ("+x", "+y", "+z")


def run_area_kernel(
    centers,
    radii,
    grid,
    device,
    *,
    depth_slots=3,
    resolver="exact",
    subpoints=8,
    lamps="all",
    active=None,
    keys=None,
):
    """The kernel on the keys of the NumPy depth pass; returns (units (N, 3) int64, diag (2,))."""
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    r = np.broadcast_to(np.asarray(radii, dtype=np.float64), (len(c),))
    if keys is None:
        keys, _ = area_depth_slots(c, r, grid, depth_slots=depth_slots, lamps=lamps, active=active)
    nu, nv = grid.counts[:, 0], grid.counts[:, 1]
    sample_offset = np.concatenate([[0], np.cumsum((nu + 1) * (nv + 1))[:2]])
    n = len(c)
    counts = wp.zeros(3 * max(n, 1), dtype=wp.int64, device=device)
    diag = wp.zeros(2, dtype=wp.int32, device=device)
    particles = LampParticles()
    particles.positions = wp.array((c - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
    particles.radii = wp.array(r.astype(np.float32), dtype=wp.float32, device=device)
    particles.active = wp.empty(0, dtype=wp.int32, device=device)
    particles.n = n
    wp.launch(
        KA.area_cells,
        dim=grid.n_cells,
        inputs=[
            grid.params(*grid.pose_arrays(device, in_frame=True)),
            particles,
            wp.array(keys, dtype=wp.uint64, device=device),
            depth_slots,
            wp.vec3i(*(int(x) for x in sample_offset)),
            lamp_mask(lamps),
            KA.RESOLVER_EXACT if resolver == "exact" else KA.RESOLVER_SUBPOINTS,
            subpoints,
            EXACT_UNIT if resolver == "exact" else subpoints * subpoints,
        ],
        outputs=[counts, diag],
        device=device,
    )
    return counts.numpy()[: 3 * n].reshape(n, 3), diag.numpy()


def kernel_scenes(rng):
    """Random polydisperse (heavily overlapping), snapped to a coarse lattice (ties), and disjoint-ish dense."""
    c, r = polydisperse_scene(rng, n=150)
    yield "random", c, r
    yield "snapped", np.round(c * 4) / 4, np.round(r * 8 + 1) / 8
    c = rng.uniform(0, 4, (300, 3))
    yield "dense", c, rng.uniform(0.25, 0.42, 300)


def test_subpoints_equal_the_reference_unit_for_unit(device, rng):
    """Sub-point resolver: every particle's units equal the reference's exactly, for several D, S and grids,
    and the overflow and one-sided counters agree."""
    for name, c, r in kernel_scenes(rng):
        for cpd, d, s in ((2, 3, 8), (3.3, 4, 5), (3, 2, 16)):
            grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=cpd)
            got, diag = run_area_kernel(c, r, grid, device, depth_slots=d, resolver="subpoints", subpoints=s)
            ref = area_estimate_reference(c, r, grid, depth_slots=d, resolver="subpoints", subpoints=s)
            np.testing.assert_array_equal(got, ref.units, err_msg=f"{name} cpd={cpd} D={d} S={s}")
            assert diag.tolist() == [ref.stats["overflow"], ref.stats["one_sided"]]
            assert np.abs(got).sum() > 0


def test_exact_resolver_matches_the_reference_up_to_float32_rounding(device, rng):
    """Exact resolver (float32 in the kernel, float64 in the reference): a rounding may move one unit (of
    4096 per cell) between seeds or lamps; no particle is off by more than 2 units per axis, and under 5% of the
    entries differ at all (2% before issue 19: a raster correction gives a seed a whole number of units, which in a
    fully covered cell lies on the payout's floor boundary, where float32 and float64 may round apart)."""
    for name, c, r in kernel_scenes(rng):
        for cpd, d in ((2, 3), (3.3, 4)):
            grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=cpd)
            got, _ = run_area_kernel(c, r, grid, device, depth_slots=d, resolver="exact")
            ref = area_estimate_reference(c, r, grid, depth_slots=d, resolver="exact")
            diff = np.abs(got - ref.units)
            assert diff.max() <= 2, f"{name} cpd={cpd}: max {diff.max()}"
            assert np.count_nonzero(diff) <= 0.05 * diff.size, f"{name} cpd={cpd}: {np.count_nonzero(diff)}"


@pytest.mark.parametrize("resolver", ["exact", "subpoints"])
def test_balance_is_exact_and_launches_are_deterministic(device, rng, resolver):
    """Units sum to exactly zero per axis on random, tied and overlapping scenes; two launches agree bitwise."""
    for _, c, r in kernel_scenes(rng):
        grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3)
        a, _ = run_area_kernel(c, r, grid, device, resolver=resolver)
        b, _ = run_area_kernel(c, r, grid, device, resolver=resolver)
        np.testing.assert_array_equal(a.sum(axis=0), [0, 0, 0])
        assert a.tobytes() == b.tobytes()


def partial_cells(center_uv, r, grid, axis):
    """Cells of grid ``axis`` that the circle's boundary crosses (those whose area a rounding can touch)."""
    (cu, cv), (hu, hv), (nu, nv) = grid.corner[axis], grid.cell[axis], grid.counts[axis]
    x0 = cu + np.arange(nu)[:, None] * hu - center_uv[0]
    y0 = cv + np.arange(nv)[None, :] * hv - center_uv[1]
    near = np.hypot(np.maximum(np.maximum(x0, -(x0 + hu)), 0), np.maximum(np.maximum(y0, -(y0 + hv)), 0))
    far = np.hypot(np.maximum(np.abs(x0), np.abs(x0 + hu)), np.maximum(np.abs(y0), np.abs(y0 + hv)))
    return int(((near < r) & (far > r)).sum())


@pytest.mark.parametrize("cpd", [2, 3, 4])
def test_lone_sphere_is_exact_to_the_unit(device, cpd):
    """A lone sphere at random offsets: each lamp's units are pi r^2 / A * 4096 to within half a unit per cell
    its outline crosses (each cell rounds once); the sub-point resolver gives the float32 count of sub-points in
    the disk."""
    rng = np.random.default_rng(cpd)
    r = 0.5
    h = 2 * r / cpd
    grid = wl.LampGrid([-1.0] * 3, [1.0] * 3, h)
    for off in rng.uniform(0.0, h, (12, 3)):
        c = off[None, :]
        target = np.pi * r * r / (h * h) * EXACT_UNIT
        low, _ = run_area_kernel(c, [r], grid, device, lamps=LOW)
        high, _ = run_area_kernel(c, [r], grid, device, lamps=HIGH)
        for a in range(3):
            bound = 0.5 * partial_cells(off[[(a + 1) % 3, (a + 2) % 3]], r, grid, a)
            assert abs(low[0, a] - target) <= bound
            assert -high[0, a] == low[0, a]
        sub, _ = run_area_kernel(c, [r], grid, device, lamps=LOW, resolver="subpoints")
        t = (np.arange(8 * cpd * 2, dtype=np.float32) + np.float32(0.5)) * np.float32(h / 8) - np.float32(1.0)
        for a in range(3):
            du = t - np.float32(off[(a + 1) % 3])
            dv = t - np.float32(off[(a + 2) % 3])
            inside = du[:, None] ** 2 + dv[None, :] ** 2 <= np.float32(r * r)
            assert abs(int(sub[0, a]) - int(inside.sum())) <= 2  # the float32 rounding of the two forms


def test_touching_cubic_lattice_loads_n2_pi_r2(device):
    """n = 5, r = 1, spacing 2 (the issue's 78.5 case) at 3 cells per diameter: columns of coincident disks
    that touch their neighbours load exactly n^2 pi r^2 per lamp (exact resolver, to rounding), and n^2 times one
    disk's sub-point count (sub-point resolver)."""
    n, r = 5, 1.0
    g = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), axis=-1).reshape(-1, 3) * 2.0
    radii = np.full(len(g), r)
    grid = wl.LampGrid.enclosing(g, radii, cells_per_diameter=3)
    for lamps in (LOW, HIGH):
        got, _ = run_area_kernel(g, radii, grid, device, lamps=lamps)
        load = np.abs(got.sum(axis=0)) * grid.cell_area / EXACT_UNIT
        np.testing.assert_allclose(load, n * n * np.pi * r * r, rtol=2e-5)
        sub, _ = run_area_kernel(g, radii, grid, device, lamps=lamps, resolver="subpoints")
        ref = area_estimate_reference(g, radii, grid, lamps=lamps, resolver="subpoints")
        np.testing.assert_array_equal(sub, ref.units)
        per_disk = np.abs(sub.sum(axis=0))
        assert np.all(per_disk % (n * n) == 0)
        np.testing.assert_allclose(per_disk / 64 * grid.cell_area, n * n * np.pi, rtol=0.01)


def fcc_ball(n_cells=3, r=0.5):
    a = 2 * np.sqrt(2) * r
    k = np.arange(-n_cells, n_cells + 1)
    cube = np.stack(np.meshgrid(k, k, k, indexing="ij"), axis=-1).reshape(-1, 3)
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    p = (cube[:, None, :] + basis[None]).reshape(-1, 3) * a
    keep = np.linalg.norm(p, axis=1) + r <= n_cells * a
    return p[keep], np.full(int(keep.sum()), r)


def test_aligned_fcc_ball_against_the_exact_areas(device):
    """The axis-aligned FCC ball (touching spheres, coincident columns on every axis): per-particle force error
    against the exact visible areas, RMS / (P pi r^2), below 0.05% (exact resolver) and 1.5% (sub-points) at 3
    cells per diameter, where criterion 1 at 4 cells per diameter is above 4%."""
    c, r = fcc_ball()
    exact = visible_area_reference(c, r)
    net = exact[:, 0::2] - exact[:, 1::2]
    scale = np.pi * 0.25
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3)
    rms = {}
    for resolver in ("exact", "subpoints"):
        got, _ = run_area_kernel(c, r, grid, device, resolver=resolver)
        unit = EXACT_UNIT if resolver == "exact" else 64
        f = got * grid.cell_area / unit
        rms[resolver] = np.sqrt(np.mean(np.sum((f - net) ** 2, axis=1))) / scale
    f1 = wl.lamp_forces(c, r, 1.0, cells_per_diameter=4, device=device)
    rms["c1"] = np.sqrt(np.mean(np.sum((f1 - net) ** 2, axis=1))) / scale
    assert rms["exact"] < 5e-4 and rms["subpoints"] < 0.015 and rms["c1"] > 0.04, rms


def test_coincident_spheres_go_to_the_lowest_index(device):
    """Two identical spheres (and a third elsewhere): every unit of every lamp goes to the lower index."""
    c = np.array([[0.0, 0.0, 0.0], [3.0, 3.0, 3.0], [0.0, 0.0, 0.0]])
    r = np.array([1.0, 0.5, 1.0])
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3)
    for resolver in ("exact", "subpoints"):
        for lamps in (LOW, HIGH):
            got, _ = run_area_kernel(c, r, grid, device, resolver=resolver, lamps=lamps)
            assert np.all(got[2] == 0) and np.all(got[0] != 0)


def test_nearly_tangent_and_nearly_coincident_pairs(device):
    """Float32 robustness: pairs of disks 1e-7 (relative) from external tangency, internal tangency and
    coincidence give the reference's units to within one unit, and both lamps stay balanced."""
    r = 0.5
    eps = 1e-7
    grid = wl.LampGrid([-2.0] * 3, [2.0] * 3, 1.0 / 3.0)
    cases = [
        ([0.1, 0.02, 0.03], [0.1 + 2 * r * (1 - eps), 0.02, 0.03], r, r),
        ([0.1, 0.02, 0.03], [0.1 + 2 * r * (1 + eps), 0.02, 0.03], r, r),
        ([0.1, 0.02, 0.03], [0.6, 0.02 + r * (1 - eps), 0.03], 2 * r, r),
        ([0.1, 0.02, 0.03], [0.9, 0.02 + r * eps, 0.03], r, r),
        ([0.1, 0.02, 0.03], [0.9, 0.02, 0.03], r, r * (1 + eps)),
    ]
    for p0, p1, r0, r1 in cases:
        c = np.array([p0, p1])
        rr = np.array([r0, r1])
        got, _ = run_area_kernel(c, rr, grid, device)
        ref = area_estimate_reference(c, rr, grid)
        assert np.abs(got - ref.units).max() <= 1
        np.testing.assert_array_equal(got.sum(axis=0), [0, 0, 0])


def test_overflow_keeps_the_front_seeds_and_is_counted(device, rng):
    """A column of 40 small spheres jittered around one cell with D = 8 gathers more than 16 seeds: the kernel
    counts the overflow, keeps the 16 frontmost exactly as the reference does, and still balances."""
    c = np.column_stack([rng.normal(0.0, 0.05, 40), rng.normal(0.0, 0.05, 40), np.linspace(-3, 3, 40)])
    r = np.full(40, 0.12)
    grid = wl.LampGrid([-0.5, -0.5, -3.5], [0.5, 0.5, 3.5], 0.1)
    got, diag = run_area_kernel(c, r, grid, device, depth_slots=8, resolver="subpoints", lamps=("-z", "+z"))
    ref = area_estimate_reference(c, r, grid, depth_slots=8, resolver="subpoints", lamps=("-z", "+z"))
    assert diag[0] > 0 and diag[0] == ref.stats["overflow"]
    np.testing.assert_array_equal(got, ref.units)
    assert got[:, 2].sum() == 0


def test_lamp_subset_and_active_mask(device, rng):
    """Lamps that are off give nothing; inactive particles get nothing and cast no shadow; the rest equals the
    reference, sub-points unit for unit."""
    c, r = polydisperse_scene(rng, n=100)
    active = rng.random(100) > 0.3
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3)
    lamps = ["-x", "+x", "+y", "-z"]
    got, _ = run_area_kernel(c, r, grid, device, resolver="subpoints", lamps=lamps, active=active)
    ref = area_estimate_reference(c, r, grid, resolver="subpoints", lamps=lamps, active=active)
    np.testing.assert_array_equal(got, ref.units)
    assert np.all(got[~active] == 0)
    assert got[:, 0].sum() == 0 and np.all(got[:, 1] <= 0) and np.all(got[:, 2] >= 0)


@pytest.mark.skipif(len(DEVICES) < 2, reason="needs a CUDA device")
def test_cpu_and_cuda_bitwise_equal_for_subpoint_units(rng):
    """Sub-point units on CUDA are bitwise those of the CPU (fuse_fp off; no transcendental functions)."""
    for _, c, r in kernel_scenes(rng):
        grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3)
        cpu, _ = run_area_kernel(c, r, grid, "cpu", resolver="subpoints")
        for dev in DEVICES[1:]:
            gpu, _ = run_area_kernel(c, r, grid, dev, resolver="subpoints")
            np.testing.assert_array_equal(cpu, gpu)


def one_cell_units(views, radii, device, resolver="exact", h=1.0):
    """The kernel on one cell [0, h]^2 of the -x lamp, every sphere a seed: ``views`` (K, 3) as (u, v, depth)
    = (y, z, x). The keys name the spheres at corner (0, 0) (the kernel gathers, orders and resolves them itself).
    Returns the -x units of each sphere, shape (K,)."""
    k = len(radii)
    centers = np.column_stack([views[:, 2], views[:, 0], views[:, 1]])
    grid = wl.LampGrid([0.0, 0.0, 0.0], [h, h, h], h)
    keys = np.full(2 * 4 * 3 * k, np.uint64(0xFFFFFFFFFFFFFFFF), dtype=np.uint64)
    keys[:k] = ordered_key(np.zeros(k), np.arange(k))  # sample 0 of grid x, low lamp, slots 0 .. k-1
    units, _ = run_area_kernel(centers, radii, grid, device, depth_slots=k, resolver=resolver, lamps=("-x",), keys=keys)
    return units[:, 0]


def cap_stack(rng, decided):
    """MAX_SEEDS = 16 spheres over one unit cell, as (u, v, depth) views and radii (float32 values): centres on a
    ring of radius 0.07 about the cell centre, radii 0.63-0.64, so that every circle crosses all four cell edges and
    meets every other circle in two points (15 + 4 intervals, 39 cuts: the clip's 40-cut vector full), and no disk
    holds all four corners (none is culled). ``decided``: depths 1.5 apart (disjoint spheres, one order for the whole
    cell); else depths within 0.2 (the spheres intersect: undecided, the raster corrects the clip)."""
    k = 16
    t = rng.uniform(0, 2 * np.pi) + np.arange(k) * 2 * np.pi / k
    u = 0.5 + 0.07 * np.cos(t) + rng.uniform(-0.004, 0.004, k)
    v = 0.5 + 0.07 * np.sin(t) + rng.uniform(-0.004, 0.004, k)
    depth = rng.permutation(k) * 1.5 if decided else rng.uniform(-0.2, 0.2, k)
    views = np.column_stack([u, v, depth]).astype(np.float32).astype(np.float64)
    return views, (0.63 + rng.uniform(0.0, 0.01, k)).astype(np.float32).astype(np.float64)


def test_exact_resolver_at_the_seed_cap_matches_a_brute_force_raster(device):
    """The exact resolver with MAX_SEEDS seeds in one cell, each circle cut by the other 15 and all four edges
    (the clip's cut vector full): each sphere's -x units against a float64 1024 x 1024 first-surface raster. Where
    one order holds on the cell, every seed but the largest is within [-1, 0] units of it (the payout floors, the
    largest takes the remainder, at most 15) plus 0.5 for the raster (measured 0.03 against the exact areas);
    where the spheres intersect, within 16 units (the 64 x 64 raster correction's bound; measured 6.3). A clip that
    overran its cut vector (one more edge interval) corrupts these by far more."""
    rng = np.random.default_rng(35)
    cell = (0.0, 0.0, 1.0, 1.0)
    for trial in range(8):
        decided = trial % 2 == 0
        views, r = cap_stack(rng, decided)
        k = len(r)
        assert k == KA.MAX_SEEDS
        # The precondition that makes this the cap: every circle cut by all others and all four edges.
        d = np.hypot(*(views[:, None, :2] - views[None, :, :2]).transpose(2, 0, 1))
        np.fill_diagonal(d, 1.0)
        assert np.all((d > np.abs(r[:, None] - r[None])) & (d < r[:, None] + r[None]))
        assert np.all(np.minimum(views[:, :2], 1.0 - views[:, :2]) < r[:, None])
        assert np.all(np.hypot(np.maximum(views[:, 0], 1 - views[:, 0]), np.maximum(views[:, 1], 1 - views[:, 1])) > r)
        got = one_cell_units(views, r, device)
        truth = first_surface_raster(views, r, cell, 1024)[0] * EXACT_UNIT
        assert got.sum() == EXACT_UNIT
        err = got - truth
        big = np.argmax(got)
        rest = np.delete(err, big)
        if decided:
            assert rest.min() >= -1.5 and rest.max() <= 0.5 and abs(err[big]) <= k - 1 + 0.5, (trial, err)
        else:
            assert np.abs(err).max() <= 16, (trial, err)


def test_nested_sphere_takes_nothing(device, rng):
    """A sphere wholly inside another gets no unit from any lamp, with either resolver, nearer the lamp than the
    big one's centre or not (issue 19's example: it took 0.93 of its disk by centre depth)."""
    grid = wl.LampGrid([-1.0] * 3, [1.0] * 3, 0.125)
    for off in rng.uniform(-0.1, 0.1, (4, 3)):
        c = np.array([[0.0, 0.0, 0.0], [0.2, 0.0, 0.0]]) + off
        for resolver in ("exact", "subpoints"):
            got, _ = run_area_kernel(c, [0.5, 0.1], grid, device, resolver=resolver)
            assert np.all(got[1] == 0) and np.all(got[0] == 0), (resolver, got)  # both lamps: net zero
            low, _ = run_area_kernel(c, [0.5, 0.1], grid, device, resolver=resolver, lamps=LOW)
            high, _ = run_area_kernel(c, [0.5, 0.1], grid, device, resolver=resolver, lamps=HIGH)
            assert np.all(low[1] == 0) and np.all(high[1] == 0)
            assert np.all(low[0] > 0) and np.all(high[0] < 0)


def test_exact_resolver_cells_with_intersecting_spheres(device):
    """One cell, two or three intersecting spheres at random: each sphere's units equal its visible area by
    surface depth (the float64 reference, itself checked against brute-force rasters) to within 2 units of 4096
    where the seeds' order holds on the whole cell (the clip), and to within 16 units, RMS under 2.5, where the
    projected intersection circle may cross the cell and the kernel's 64 x 64 raster corrects the clip (measured
    on 1,710 such cells in float64: worst 14.75, RMS 1.5). Ordering by centre depth, as before issue 19, errs by
    over 1,000 units in some of these cells."""
    rng = np.random.default_rng(7)
    err, old, undecided = [], [], []
    f32 = np.float32
    for _ in range(200):
        k = int(rng.integers(2, 4))
        r = rng.uniform(0.5, 3.0, k)
        views = np.column_stack([rng.uniform(-1.5, 2.5, (k, 2)), rng.uniform(-2.0, 2.0, k)])
        views, r = views.astype(f32).astype(np.float64), r.astype(f32).astype(np.float64)
        truth = visible_sphere_areas(views, r, (0.0, 0.0, 1.0, 1.0)) * EXACT_UNIT
        got = one_cell_units(views, r, device)
        err.append(np.abs(got - truth).max())
        order = np.lexsort((np.arange(k), views[:, 2]))
        ok = np.ones((1, k), dtype=bool)
        rel = _pair_relations(*(x[order][None].astype(f32) for x in (*views.T, r)), ok, f32(1), f32(1))
        undecided.append(bool(_surface_order(rel, ok)[1][0]))
        by_centre = np.empty(k)
        by_centre[order] = visible_disk_areas(views[order, :2], r[order], (0.0, 0.0, 1.0, 1.0)) * EXACT_UNIT
        old.append(np.abs(by_centre - truth).max())
    err, undecided = np.array(err), np.array(undecided)
    assert 50 < undecided.sum() < len(err) - 50
    assert err[~undecided].max() <= 2
    raster = err[undecided]
    assert raster.max() <= 16 and np.sqrt(np.mean(raster**2)) < 2.5, (raster.max(), np.sqrt(np.mean(raster**2)))
    assert max(old) > 1000


PI = np.pi


def column_quadrature(centers, radii, rect, columns=20000):
    """Visible areas by another route: in each of ``columns`` vertical lines (midpoint rule across x), the exact
    length of every disk's chord not covered by an earlier disk's chord, by a 1-D sweep."""
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    r = np.asarray(radii, dtype=np.float64)
    x0, y0, x1, y1 = rect
    k = len(r)
    dx = (x1 - x0) / columns
    xs = x0 + (np.arange(columns) + 0.5) * dx
    s2 = r[None, :] ** 2 - (xs[:, None] - c[None, :, 0]) ** 2
    has = s2 > 0
    s = np.sqrt(np.where(has, s2, 0.0))
    lo = np.where(has, np.clip(c[None, :, 1] - s, y0, y1), y1)
    hi = np.where(has, np.clip(c[None, :, 1] + s, y0, y1), y0)
    cuts = np.sort(np.concatenate([np.full((columns, 1), y0), lo, hi, np.full((columns, 1), y1)], axis=1), axis=1)
    mid = 0.5 * (cuts[:, 1:] + cuts[:, :-1])
    inside = (mid[:, :, None] >= lo[:, None, :]) & (mid[:, :, None] <= hi[:, None, :])
    first = np.where(inside.any(axis=2), inside.argmax(axis=2), k)
    length = cuts[:, 1:] - cuts[:, :-1]
    out = np.zeros(k + 1)
    np.add.at(out, first.ravel(), length.ravel())
    return out[:k] * dx


def disjoint_spheres(rng, n, extent, rmin, rmax):
    """Random spheres in a cube, greedily thinned to a disjoint set."""
    c = rng.uniform(0, extent, (n, 3))
    r = rng.uniform(rmin, rmax, n)
    keep = np.ones(n, dtype=bool)
    for i in range(n):
        d = np.linalg.norm(c[:i] - c[i], axis=1)
        if np.any(keep[:i] & (d < r[:i] + r[i])):
            keep[i] = False
    return c[keep], r[keep]


def lens_area(r1, r2, d):
    """Area of the intersection of two disks, closed form."""
    if d >= r1 + r2:
        return 0.0
    if d <= abs(r1 - r2):
        return PI * min(r1, r2) ** 2
    a1 = np.arccos((d * d + r1 * r1 - r2 * r2) / (2 * d * r1))
    a2 = np.arccos((d * d + r2 * r2 - r1 * r1) / (2 * d * r2))
    return r1 * r1 * (a1 - 0.5 * np.sin(2 * a1)) + r2 * r2 * (a2 - 0.5 * np.sin(2 * a2))


def test_identical_disks_give_everything_to_the_first():
    """Two or five identical disks: the first takes the whole area, the others exactly zero."""
    for k in (2, 5):
        a = visible_disk_areas(np.tile([[0.3, -0.2]], (k, 1)), np.full(k, 0.7), (-2, -2, 2, 2))
        assert a[0] == pytest.approx(PI * 0.49, rel=1e-15)
        assert np.all(a[1:] == 0.0)


def test_tangent_disks_externally_and_internally():
    """External tangency: both disks whole. Internal tangency: the small one hidden behind the big one, or
    the big one an exact crescent behind the small one."""
    rect = (-6, -6, 6, 6)
    np.testing.assert_allclose(visible_disk_areas([[0, 0], [2, 0]], [1, 1], rect), [PI, PI], rtol=1e-15)
    np.testing.assert_allclose(visible_disk_areas([[0, 0], [0, 3]], [1, 2], rect), [PI, 4 * PI], rtol=1e-15)
    a = visible_disk_areas([[0.0, 0.0], [0.5, 0.0]], [1.0, 0.5], rect)
    assert a[0] == pytest.approx(PI, rel=1e-15) and abs(a[1]) < 1e-15
    a = visible_disk_areas([[0.5, 0.0], [0.0, 0.0]], [0.5, 1.0], rect)
    np.testing.assert_allclose(a, [0.25 * PI, 0.75 * PI], rtol=1e-14)


def test_reference_on_nearly_tangent_and_nearly_coincident_pairs():
    """Pairs 1e-12 (relative) away from tangency or coincidence get the closed-form lens and crescent areas."""
    rect = (-4, -4, 4, 4)
    eps = 1e-12
    for d in (2 * (1 - eps), 2 * (1 + eps)):  # externally, nearly tangent
        a = visible_disk_areas([[0, 0], [d, 0]], [1, 1], rect)
        assert a[0] == pytest.approx(PI, rel=1e-14)
        assert a[1] == pytest.approx(PI - lens_area(1, 1, d), rel=1e-14)
    for d in (0.5 * (1 - eps), 0.5 * (1 + eps)):  # internally, nearly tangent
        a = visible_disk_areas([[0, 0], [d, 0]], [0.5, 1], rect)
        assert a[1] == pytest.approx(PI - lens_area(0.5, 1, d), rel=1e-14)
        a = visible_disk_areas([[d, 0], [0, 0]], [1, 0.5], rect)
        assert abs(a[1] - (0.25 * PI - lens_area(1, 0.5, d))) < 1e-14
    # Nearly coincident: the second disk shows a crescent of about 2 r d, or an annulus of 2 pi r dr.
    d = eps
    a = visible_disk_areas([[0, 0], [d, 0]], [1, 1], rect)
    assert a[0] == pytest.approx(PI, rel=1e-15)
    assert a[1] == pytest.approx(2 * d, rel=1e-3)
    a = visible_disk_areas([[0, 0], [0, 0]], [1, 1 + eps], rect)
    assert a[1] == pytest.approx(2 * PI * eps, rel=1e-3)
    a = visible_disk_areas([[0, 0], [0, 0]], [1 + eps, 1], rect)
    assert a[1] == 0.0


def test_disks_meeting_the_rectangle_in_corners_and_edges():
    """Inscribed and circumscribed disks, disks centred on a corner or an edge, tangent to an edge."""
    sq = (-1, -1, 1, 1)
    assert visible_disk_areas([[0, 0]], [1], sq)[0] == pytest.approx(PI, rel=1e-15)  # inscribed: touches 4 edges
    assert visible_disk_areas([[0, 0]], [2**0.5], sq)[0] == pytest.approx(4.0, rel=1e-15)  # through all 4 corners
    assert visible_disk_areas([[1, 1]], [0.6], sq)[0] == pytest.approx(0.09 * PI, rel=1e-15)  # on a corner
    assert visible_disk_areas([[0, -1]], [0.6], sq)[0] == pytest.approx(0.18 * PI, rel=1e-15)  # on an edge
    assert visible_disk_areas([[0, -2]], [1], sq)[0] == 0.0  # tangent from outside
    assert visible_disk_areas([[0, -0.5]], [0.5], sq)[0] == pytest.approx(0.25 * PI, rel=1e-15)  # from inside
    # Through two corners exactly: the disk centred on an edge's midpoint reaching the far corners.
    a = visible_disk_areas([[0, -1]], [5**0.5], sq)[0]
    assert a == pytest.approx(4.0, rel=1e-15)
    # The corner (1, 1) lies exactly on this circle: (0.5)^2 + (1.5)^2 + ... checked against quadrature.
    c, r = [[0.5, -0.5]], [np.hypot(0.5, 1.5)]
    assert visible_disk_areas(c, r, sq)[0] == pytest.approx(column_quadrature(c, r, sq)[0], abs=2e-6)


def test_touching_square_lattice_of_columns():
    """Four columns of three coincident disks, touching each other and the rectangle edges: each column's
    front disk gets pi r^2, everything behind it zero (a naive arc clip gets this wrong)."""
    r = 0.5
    centres = np.array([[0.5, 0.5], [1.5, 0.5], [0.5, 1.5], [1.5, 1.5]])
    disks = np.concatenate([centres] * 3)
    a = visible_disk_areas(disks, np.full(12, r), (0, 0, 2, 2))
    np.testing.assert_allclose(a[:4], PI * r * r, rtol=1e-14)
    assert np.all(np.abs(a[4:]) <= 1e-15)
    # Cut into cells of a third of a diameter (as a lamp cell would see them): the pieces add up to pi r^2.
    total = np.zeros(12)
    h = 1.0 / 3.0
    for i in range(6):
        for j in range(6):
            total += visible_disk_areas(disks, np.full(12, r), (i * h, j * h, (i + 1) * h, (j + 1) * h))
    np.testing.assert_allclose(total[:4], PI * r * r, rtol=1e-13)
    assert np.all(np.abs(total[4:]) <= 1e-14)


def test_symmetric_configurations():
    """Two equal overlapping disks in either order; four disks in a square: exact lens arithmetic."""
    rect = (-5, -5, 5, 5)
    lens = lens_area(1, 1, 1.2)
    for order in ([0, 1], [1, 0]):
        c = np.array([[-0.6, 0.0], [0.6, 0.0]])[order]
        np.testing.assert_allclose(visible_disk_areas(c, [1, 1], rect), [PI, PI - lens], rtol=1e-14)
    # Four unit disks at (+-0.8, +-0.8): neighbours at 1.6 overlap, diagonals at 2.26 do not.
    c = np.array([[-0.8, -0.8], [0.8, -0.8], [0.8, 0.8], [-0.8, 0.8]])
    lens = lens_area(1, 1, 1.6)
    np.testing.assert_allclose(
        visible_disk_areas(c, np.ones(4), rect), [PI, PI - lens, PI - lens, PI - 2 * lens], rtol=1e-14
    )


@pytest.mark.parametrize("quantized", [False, True])
def test_random_disks_match_column_quadrature_and_union(rng, quantized):
    """Random disks (some snapped to a coarse lattice, so that tangencies and coincidences abound) match the
    column quadrature disk by disk, and their sum matches a Monte Carlo estimate of the union."""
    rect = (0.0, 0.0, 1.0, 0.75)
    for _ in range(8):
        k = int(rng.integers(1, 9))
        c = rng.uniform(-0.4, 1.4, (k, 2))
        r = rng.uniform(0.1, 0.8, k)
        if quantized:
            c = np.round(c * 4) / 4
            r = np.round(r * 4 + 0.5) / 4
            c[k // 2 :] = c[: k - k // 2]  # coincident centres
        a = visible_disk_areas(c, r, rect)
        q = column_quadrature(c, r, rect)
        np.testing.assert_allclose(a, q, atol=2e-6)
        assert np.all(a >= -1e-15)
        pts = rng.uniform((rect[0], rect[1]), (rect[2], rect[3]), (200000, 2))
        hit = (((pts[:, None, :] - c[None]) ** 2).sum(axis=2) <= r**2).any(axis=1)
        union = hit.mean() * 0.75
        sigma = np.sqrt(max(hit.mean() * (1 - hit.mean()), 1e-12) / len(pts)) * 0.75
        assert abs(a.sum() - union) <= 5 * sigma + 1e-12


def test_visible_disk_areas_rejects_bad_input():
    """Bad radii, centres and rectangles raise, naming the argument and the first bad disk."""
    with pytest.raises(ValueError, match="disk 1"):
        visible_disk_areas([[0, 0], [1, 1]], [1, 0], (0, 0, 1, 1))
    with pytest.raises(ValueError, match="disk 0"):
        visible_disk_areas([[np.nan, 0]], [1], (0, 0, 1, 1))
    with pytest.raises(ValueError, match="rect"):
        visible_disk_areas([[0, 0]], [1], (0, 0, -1, 1))
    with pytest.raises(ValueError, match="radii"):
        visible_disk_areas([[0, 0]], [1, 2], (0, 0, 1, 1))


def test_lone_sphere_and_hidden_pairs():
    """A lone sphere shows pi r^2 to every lamp; a sphere behind another along x shows nothing to one x lamp."""
    a = visible_area_reference([[0.1, 0.2, 0.3]], [0.7])
    np.testing.assert_allclose(a, PI * 0.49, rtol=1e-13)
    a = visible_area_reference([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]], [0.5, 0.5])
    np.testing.assert_allclose(a[:, 0], [PI / 4, 0.0], atol=1e-15)  # -x sees sphere 0
    np.testing.assert_allclose(a[:, 1], [0.0, PI / 4], atol=1e-15)  # +x sees sphere 1
    np.testing.assert_allclose(a[:, 2:], PI / 4, rtol=1e-13)


@pytest.mark.parametrize("n", [2, 4])
def test_touching_cubic_lattice_loads_n2_pi_r2_per_lamp(n):
    """r = spacing / 2: columns project to one disk and neighbouring disks touch; every lamp sees exactly
    n^2 pi r^2, all of it on the lattice's outer layer on that side."""
    g = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), axis=-1).reshape(-1, 3) * 1.0
    a = visible_area_reference(g + 0.123, np.full(len(g), 0.5))
    np.testing.assert_allclose(a.sum(axis=0), n * n * PI / 4, rtol=1e-13)
    for lamp in range(6):
        ax, side = divmod(lamp, 2)
        face = g[:, ax] == (0 if side == 0 else n - 1)
        np.testing.assert_allclose(a[face, lamp], PI / 4, rtol=1e-12)
        assert np.all(np.abs(a[~face, lamp]) < 1e-14)


def test_random_disjoint_spheres_match_planar_quadrature(rng):
    """Random disjoint spheres: each lamp's areas match column quadrature of the disks sorted by depth."""
    c, r = disjoint_spheres(rng, 60, 3.0, 0.1, 0.45)
    a = visible_area_reference(c, r)
    for lamp in range(6):
        ax, side = divmod(lamp, 2)
        u, v = (ax + 1) % 3, (ax + 2) % 3
        order = np.lexsort((np.arange(len(r)), c[:, ax] if side == 0 else -c[:, ax]))
        q = column_quadrature(c[order][:, [u, v]], r[order], (-1, -1, 4, 4), columns=40000)
        np.testing.assert_allclose(a[order, lamp], q, atol=5e-6)


def test_active_mask_and_lamp_subset():
    """Inactive spheres cast no shadow and get zero; lamps that are off get zero columns."""
    c = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    a = visible_area_reference(c, [0.5, 0.5], active=[0, 1])
    np.testing.assert_allclose(a[1], PI / 4, rtol=1e-13)
    assert np.all(a[0] == 0)
    a = visible_area_reference(c, [0.5, 0.5], lamps=["+z"])
    assert np.all(a[:, [0, 1, 2, 3, 4]] == 0) and np.all(a[:, 5] > 0)
    with pytest.raises(ValueError, match="radii"):
        visible_area_reference(c, [0.5, -1.0])
    with pytest.raises(ValueError, match="active"):
        visible_area_reference(c, 0.5, active=[1])
    with pytest.raises(ValueError, match="lamps"):
        visible_area_reference(c, 0.5, lamps=["up"])


def test_lamp_at_fine_resolution_converges_to_the_reference(rng):
    """Cross-check with the lamp kernel itself: criterion 1 at 16 cells per diameter is within 2% (RMS per
    particle, against P pi rbar^2) of the exact areas on a body of disjoint spheres, and 4x closer than at 2."""
    c, r = disjoint_spheres(rng, 400, 3.0, 0.2, 0.35)
    assert len(r) > 80
    exact = visible_area_reference(c, r)
    net = exact[:, 0::2] - exact[:, 1::2]
    scale = PI * np.mean(r) ** 2
    errs = []
    for cpd in (2, 16):
        f = wl.lamp_forces(c, r, 1.0, cells_per_diameter=cpd, device="cpu")
        errs.append(np.sqrt(np.mean(np.sum((f - net) ** 2, axis=1))) / scale)
    assert errs[1] < 0.02 and errs[1] < errs[0] / 4


def test_depth_slots_hold_the_d_nearest_spheres_of_each_ray(rng):
    """D-slot keys: per sample ray and lamp, the ids of the D first spheres along the ray (entry depth for the
    low lamp, exit depth for the high one), checked against float64 brute force where depths are not near-tied."""
    c, r = disjoint_spheres(rng, 200, 3.0, 0.15, 0.4)
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3)
    d = 3
    keys, offsets = area_depth_slots(c, r, grid, depth_slots=d)
    checked = 0
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        (cu, cv), (hu, hv), (nu, nv) = grid.corner[a], grid.cell[a], grid.counts[a]
        for i, j in rng.integers(0, [nu + 1, nv + 1], (200, 2)):
            du = cu + i * hu - c[:, u]
            dv = cv + j * hv - c[:, v]
            rem = r * r - du * du - dv * dv
            hit = np.flatnonzero(rem >= 0)
            s = np.sqrt(np.maximum(rem[hit], 0))
            for side, depth in ((0, c[hit, a] - s), (1, -(c[hit, a] + s))):
                order = hit[np.argsort(depth)][:d]
                gaps = np.diff(np.sort(depth)[: d + 1])
                if np.any(gaps < 1e-5) or np.any(np.abs(rem[order]) < 1e-5):
                    continue
                base = (2 * (offsets[a] + j * (nu + 1) + i) + side) * d
                k = keys[base : base + d]
                got = [int(x & 0xFFFFFFFF) for x in k if x != 0xFFFFFFFFFFFFFFFF]
                assert got == order.tolist()
                checked += 1
    assert checked > 300


@pytest.mark.parametrize("resolver", ["exact", "subpoints"])
def test_estimator_balances_exactly(rng, resolver):
    """Units sum to exactly zero per axis on random overlapping, tied (snapped) and one-lamp-off scenes."""
    c = rng.uniform(0, 4, (200, 3))
    r = rng.uniform(0.2, 0.6, 200)
    for cc, rr in ((c, r), (np.round(c * 4) / 4, np.round(r * 8 + 1) / 8)):
        for cpd in (2, 3.5):
            grid = wl.LampGrid.enclosing(cc, rr, cells_per_diameter=cpd)
            est = area_estimate_reference(cc, rr, grid, resolver=resolver)
            np.testing.assert_array_equal(est.units.sum(axis=0), [0, 0, 0])
            assert np.abs(est.units).sum() > 0
    est = area_estimate_reference(c, r, grid, resolver=resolver, lamps=["-x", "+x", "-y", "+y", "+z"])
    assert est.units[:, :2].sum() == 0 and np.all(est.units[:, 2] <= 0)


def test_estimator_lone_sphere_exact_to_the_unit():
    """Exact resolver on a lone sphere at random offsets: per lamp, pi r^2 / A * UNIT to within half a unit
    per cell (the per-cell rounding), on every lamp; the sub-point resolver counts the sub-points in the disk."""
    rng = np.random.default_rng(3)
    for cpd in (2, 3, 4):
        h = 1.0 / cpd
        grid = wl.LampGrid([-1.0] * 3, [1.0] * 3, h)
        for off in rng.uniform(0, h, (6, 3)):
            est = area_estimate_reference(off[None, :], [0.5], grid, details=True)
            target = np.pi * 0.25 / (h * h) * est.unit
            for d in est.cells.values():
                assert abs(d["units"].sum() - target) <= 0.5 * len(d["cell"])
                assert np.all(np.abs(d["units"].sum(axis=1) - d["share"].sum(axis=1)) <= 0.5 + 1e-9)


def test_estimator_converges_to_the_exact_areas(rng):
    """On a body of disjoint spheres the estimator's per-particle force error against the exact visible areas,
    RMS / (P pi rbar^2), is below 0.5% (exact resolver, D = 4, 3 cells per diameter) and 2% (sub-points), and
    criterion 1 at 16 cells per diameter, a cross-check of both, lies within 2% of the estimator."""
    c, r = disjoint_spheres(rng, 3000, 4.0, 0.2, 0.33)
    assert len(r) > 200
    exact = visible_area_reference(c, r)
    net = exact[:, 0::2] - exact[:, 1::2]
    scale = np.pi * np.mean(r) ** 2
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3)
    forces = {}
    for resolver in ("exact", "subpoints"):
        est = area_estimate_reference(c, r, grid, depth_slots=4, resolver=resolver)
        forces[resolver] = est.units * grid.cell_area / est.unit
    forces["c1"] = wl.lamp_forces(c, r, 1.0, cells_per_diameter=16, device="cpu")
    rms = {k: np.sqrt(np.mean(np.sum((f - net) ** 2, axis=1))) / scale for k, f in forces.items()}
    assert rms["exact"] < 0.005 and rms["subpoints"] < 0.02, rms
    cross = np.sqrt(np.mean(np.sum((forces["c1"] - forces["exact"]) ** 2, axis=1))) / scale
    assert cross < 0.02, cross


def test_estimator_rejects_bad_arguments():
    """Bad resolver, sub-point count, depth slots and seed bound raise, naming the argument."""
    grid = wl.LampGrid([-1.0] * 3, [1.0] * 3, 0.25)
    c = np.zeros((1, 3))
    for kw, name in (
        (dict(resolver="fast"), "resolver"),
        (dict(subpoints=0), "subpoints"),
        (dict(depth_slots=0), "depth_slots"),
        (dict(max_seeds=0), "max_seeds"),
    ):
        with pytest.raises(ValueError, match=name):
            area_estimate_reference(c, [0.5], grid, **kw)


def two_sphere_views():
    """The issue's two overlapping unequal spheres (centres (0, 0, 0), (0.45, 0.05, 0), radii 0.5, 0.15) seen
    from the -y and +y lamps: centres as (z, x, +-y), the -y lamp's plane being (z, x)."""
    c = np.array([[0.0, 0.0, 0.0], [0.45, 0.05, 0.0]])
    r = np.array([0.5, 0.15])
    return {sign: (np.stack([c[:, 2], c[:, 0], sign * c[:, 1]], axis=1), r) for sign in (1, -1)}


def test_two_overlapping_spheres_match_a_fine_raster():
    """The issue's example: the small sphere's visible area from -y and +y by the reference equals a 2048 x 2048
    brute-force raster of its bounding box to 1e-5 (0.02416 and 0.03176; measured 3e-6); ordering the disks by
    centre depth, as before issue 19, is off by more than 1e-3 (0.02267, and from +y the whole disk, 0.0707)."""
    for sign, (c, r) in two_sphere_views().items():
        ras, _ = first_surface_raster(c, r, (-0.15, 0.3, 0.15, 0.6), 2048)  # the small disk's bounding box
        ref = visible_sphere_areas(c, r, (-1, -1, 1, 1))
        assert abs(ref[1] - ras[1]) < 1e-5, (sign, ref[1], ras[1])
        order = np.argsort(c[:, 2])
        by_centre = np.empty(2)
        by_centre[order] = visible_disk_areas(c[order, :2], r[order], (-1, -1, 1, 1))
        assert abs(by_centre[1] - ras[1]) > 1e-3


def test_nested_sphere_is_hidden():
    """A sphere wholly inside another takes nothing from either side, wherever its centre is nearer the lamp."""
    rect = (-1, -1, 1, 1)
    for depth in (-0.2, 0.2, -0.39):
        a = visible_sphere_areas([[0.0, 0.0, 0.0], [0.05, -0.02, depth]], [0.5, 0.1], rect)
        assert a[1] == 0.0 and a[0] == pytest.approx(0.25 * PI, rel=1e-12)
    a = visible_area_reference([[0.0, 0.0, 0.0], [0.2, 0.0, 0.0]], [0.5, 0.1])
    assert np.all(a[1] == 0.0)
    np.testing.assert_allclose(a[0], 0.25 * PI, rtol=1e-12)


@pytest.mark.parametrize("kind", ["random", "equal depths", "nested and coincident"])
def test_visible_sphere_areas_match_a_brute_force_raster(rng, kind):
    """Random overlapping spheres in a rectangle (intersecting, some at equal depths, nested, coincident): each
    sphere's visible area is the 2048 x 2048 first-surface raster's to within the raster's error bound, and the
    areas add up to the union's."""
    rect = (0.0, 0.0, 1.0, 0.75)
    for _ in range(6):
        k = int(rng.integers(2, 7))
        c = np.column_stack([rng.uniform(-0.2, 1.2, (k, 2)), rng.uniform(-0.5, 0.5, k)])
        r = rng.uniform(0.15, 0.6, k)
        if kind == "equal depths":
            c[:, 2] = np.round(c[:, 2] * 2) / 2
        elif kind == "nested and coincident":
            c[1] = c[0] + [0.05, 0.0, 0.1]
            r[1] = 0.5 * r[0]
            c[-1], r[-1] = c[0], r[0]
        a = visible_sphere_areas(c, r, rect)
        ras, pixel = first_surface_raster(c, r, rect, 2048)
        assert np.all(np.abs(a - ras) <= raster_tolerance(r, pixel)), (a, ras)
        assert a.sum() == pytest.approx(ras.sum(), abs=raster_tolerance(r, pixel).sum())
        if kind == "nested and coincident":
            assert a[1] == 0.0 and a[-1] == 0.0


def test_visible_area_reference_on_an_overlapping_packing_matches_a_raster():
    """An overlapping polydisperse ball (radius ratio 3, overlaps up to 30% of the smaller radius): every sphere's
    visible area from every lamp is a 384-rays-per-diameter first-surface raster's to within its error bound,
    and the RMS difference is below 1.5e-4 of a mean disk (measured 5e-5, mostly the raster's); by centre depth
    (the reference before issue 19) the RMS difference is over 20 times that."""
    s = scene_overlapping_polydisperse(100)
    c, r = s.centers, s.radii
    a = visible_area_reference(c, r)
    ras, pixel = raster_visible_areas(c, r, 384)
    by_centre, _ = raster_visible_areas(c, r, 384, by_centre=True)
    disk = PI * r.mean() ** 2
    assert np.all(np.abs(a - ras) <= raster_tolerance(r, pixel)[:, None])
    rms = np.sqrt(np.mean((a - ras) ** 2)) / disk
    assert rms < 1.5e-4, rms
    assert np.sqrt(np.mean((by_centre - ras) ** 2)) / disk > 20 * rms


def test_reference_refuses_radii_that_do_not_match_the_centres():
    """The float64 reference checks its inputs like the library: radii of another length are refused naming both
    shapes."""
    with pytest.raises(ValueError, match=r"radii: expected shape \(5,\) to match centers, got \(4,\)"):
        visible_area_reference(np.zeros((5, 3)), np.ones(4))


def test_area_criterion_warns_of_fines_narrower_than_a_cell(device):
    """Fines narrower than a cell on a ball's surface: the area criterion warns (and rightly: some fines get no
    load at all); the same ball without fines warns of nothing."""
    import warnings

    from warp_lamp.scenes import scene_lattice_ball

    rng = np.random.default_rng(1)
    ball = scene_lattice_ball(diameter=0.03, particle_diameter=0.005)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        wl.lamp_forces(ball.centers, ball.radii, 1e6, criterion="area", device=device)
    d = rng.normal(size=(30, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    reach = np.linalg.norm(ball.centers - ball.center, axis=1).max() + ball.radii.max()
    c = np.vstack([ball.centers, ball.center + d * (reach + 2e-4)])
    r = np.concatenate([ball.radii, np.full(30, 2e-4)])
    with pytest.warns(UserWarning, match=r"criterion 'area': 30 particles narrower than a cell .* get no load"):
        f = wl.lamp_forces(c, r, 1e6, criterion="area", device=device)
    assert np.count_nonzero(np.abs(f[-30:]).sum(axis=1) == 0.0) > 0  # the warning is not idle


def test_hidden_spheres_are_invisible_and_leave_the_slots():
    """The spheres ``hidden_spheres`` finds behind one other sphere (a lattice ball's see-through columns) have no
    visible area from that lamp by the independent exact areas, and the depth pass without them never keeps them."""
    from warp_lamp.reference import hidden_spheres
    from warp_lamp.scenes import scene_lattice_ball

    sc = scene_lattice_ball(diameter=0.03, seed=3)
    grid = wl.LampGrid.enclosing(sc.centers, sc.radii, cells_per_diameter=4)
    hidden = hidden_spheres(sc.centers, sc.radii, grid, depth_slots=3, rounds=2)
    exact = visible_area_reference(sc.centers, sc.radii)
    assert hidden.sum() > 0.2 * hidden.size  # the columns hide many
    assert not (exact[hidden] > 0).any()
    keys, offsets = area_depth_slots(sc.centers, sc.radii, grid, depth_slots=3, hidden=hidden)
    for a in range(3):
        nu, nv = (int(x) for x in grid.counts[a])
        for side in range(2):
            k = keys.reshape(-1, 2, 3)[offsets[a] : offsets[a] + (nu + 1) * (nv + 1), side]
            owners = (k[k != np.uint64(2**64 - 1)] & np.uint64(0xFFFFFFFF)).astype(np.int64)
            assert not hidden[owners, 2 * a + side].any()


@pytest.mark.parametrize("rounds", [1, 2])
def test_hidden_rounds_equal_the_reference_bitwise(device, rounds):
    """The hidden-sphere rounds (flag what one key hides, rerun the depth pass without it) leave bitwise the
    reference's keys and sub-point units on a lattice ball and a random packing, and change the keys (they act)."""
    from warp_lamp.reference import hidden_spheres
    from warp_lamp.scenes import scene_lattice_ball

    rng = np.random.default_rng(5)
    ball = scene_lattice_ball(diameter=0.03, seed=3)
    for c, r in ((ball.centers, ball.radii), polydisperse_scene(rng, n=150)):
        grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4)
        hidden = hidden_spheres(c, r, grid, depth_slots=3, rounds=rounds)
        want, _ = area_depth_slots(c, r, grid, depth_slots=3, hidden=hidden)
        plain, _ = area_depth_slots(c, r, grid, depth_slots=3)
        ref = area_estimate_reference(c, r, grid, depth_slots=3, resolver="subpoints", _hidden_rounds=rounds)
        lamp = wl.ShiningLamp(grid, criterion="area", resolver="subpoints", depth_slots=3, device=device)
        lamp.estimator.hidden_rounds = rounds
        pos, rad = device_arrays(grid.to_frame(c), r, device)
        for _ in range(2):  # the second update starts from the first's keys
            lamp.update(pos, rad, in_frame=True)
            np.testing.assert_array_equal(lamp.keys.numpy(), want)
            np.testing.assert_array_equal(lamp.counts_numpy(), ref.units)
        assert (want != plain).any()
        assert lamp.diagnostics().invalid == 0


def test_both_lamps_gather_equals_the_reference_bitwise(device):
    """Seeds gathered from both lamps' keys (with the hidden rounds; 3 and 5 slots) give bitwise the reference's
    sub-point units and overflow count, on a lattice ball, and differ from the one-lamp gather (they act)."""
    from warp_lamp.scenes import scene_lattice_ball

    ball = scene_lattice_ball(diameter=0.03, seed=3)
    c, r = ball.centers, ball.radii
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4)
    pos, rad = device_arrays(grid.to_frame(c), r, device)
    for rounds, d in ((0, 3), (2, 3), (2, 5)):
        ref = area_estimate_reference(
            c, r, grid, depth_slots=d, resolver="subpoints", _cell_seeds="both", _hidden_rounds=rounds
        )
        one = area_estimate_reference(c, r, grid, depth_slots=d, resolver="subpoints", _hidden_rounds=rounds)
        lamp = wl.ShiningLamp(grid, criterion="area", resolver="subpoints", depth_slots=d, device=device)
        lamp.estimator.gather_both = True
        lamp.estimator.hidden_rounds = rounds
        lamp.update(pos, rad, in_frame=True)
        np.testing.assert_array_equal(lamp.counts_numpy(), ref.units)
        assert lamp.diagnostics().area_overflow == ref.stats["overflow"]
        if d == 3:  # five slots of one lamp already hold every sphere of this small ball
            assert (ref.units != one.units).any()


def test_gather_option_sets_the_deep_gather_and_refuses_bad_values():
    """``gather="deep"`` turns on both lamps' keys and two hidden rounds; a bad value, or the deep gather without
    the area criterion, raises naming ``gather``."""
    c = np.array([[0.0, 0.0, 0.0], [0.3, 0.1, 0.2]])
    r = np.array([0.25, 0.2])
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4)
    lamp = wl.ShiningLamp(grid, criterion="area", gather="deep", device="cpu")
    assert lamp.estimator.gather_both and lamp.estimator.hidden_rounds == 2
    front = wl.ShiningLamp(grid, criterion="area", device="cpu")
    assert not front.estimator.gather_both and front.estimator.hidden_rounds == 0
    with pytest.raises(ValueError, match=r"^gather: expected one of"):
        wl.ShiningLamp(grid, criterion="area", gather="all", device="cpu")
    with pytest.raises(ValueError, match=r"^gather: 'deep' is the area criterion's"):
        wl.ShiningLamp(grid, criterion=1, gather="deep", device="cpu")


def _side_pass_cases(rng):
    """(name, centres, radii, cells per diameter, lamp options, estimator settings): random overlapping spheres, a
    packing whose spheres overlap by up to 30% (many undecided cells), the lattice ball with the deep gather, and
    a lamp subset with inactive particles."""
    from warp_lamp.scenes import scene_lattice_ball

    c, r = polydisperse_scene(rng, n=150)
    yield "random", c, r, 4, {}, {}
    s = scene_overlapping_polydisperse(n=300)
    yield "overlapping", s.centers, s.radii, 3, {}, {}
    ball = scene_lattice_ball(diameter=0.03, seed=3)
    yield "lattice ball deep", ball.centers, ball.radii, 4, {"depth_slots": 4}, {"hidden_rounds": 2, "gather_both": 1}
    active = rng.random(150) > 0.3
    yield "subset", c, r, 3, {"lamps": ["-x", "+x", "+y", "-z"], "active": active}, {}


@pytest.mark.parametrize("resolver", ["subpoints", "exact"])
def test_side_pass_equals_the_cell_pass_bitwise(device, rng, resolver):
    """A thread per (lamp, cell) (``cell_pass="sides"``), with and without the work list of undecided lamps (and
    with one too small for them), gives bitwise the counts and counters of one thread per cell, on overlapping,
    lattice-ball (deep gather), subset and inactive cases; the sub-points also equal the reference unit for unit."""
    for name, c, r, cpd, opts, est in _side_pass_cases(rng):
        if resolver == "exact" and name == "lattice ball deep":
            continue  # the same gather as the sub-points': only the resolver differs, as in "overlapping"
        opts = dict(opts)
        active = opts.pop("active", None)
        grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=cpd)
        pos, rad = device_arrays(grid.to_frame(c), r, device)
        act = None if active is None else wp.array(active.astype(np.int32), dtype=wp.int32, device=device)
        out = {}
        for cell_pass in ("cells", "sides"):
            for defer in (False, True, "small"):
                lamp = wl.ShiningLamp(grid, criterion="area", resolver=resolver, device=device, **opts)
                lamp.estimator.hidden_rounds = est.get("hidden_rounds", 0)
                lamp.estimator.gather_both = bool(est.get("gather_both", False))
                lamp.estimator.defer = bool(defer)
                if defer == "small":
                    # Room for 64 cells (128 lamps): past it the thread resolves its lamp itself.
                    keep = lamp.estimator.WORK_FRACTION
                    lamp.estimator.defer = False
                    lamp.estimator.WORK_FRACTION = grid.n_cells
                    lamp.estimator.defer = True
                    lamp.estimator.WORK_FRACTION = keep
                lamp.estimator.cell_pass = cell_pass
                assert lamp.estimator.cell_pass == cell_pass
                lamp.update(pos, rad, in_frame=True, active=act)
                d = lamp.diagnostics()
                out[cell_pass, defer] = (lamp.counts_numpy(), d.area_overflow, d.area_one_sided)
                if defer == "small" and name == "overlapping" and cell_pass == "sides":
                    asked = int(lamp.estimator._work["count"].numpy()[0])
                    assert asked > lamp.estimator._work["seeds"].shape[0]  # both paths ran
        want = out["cells", False]
        assert np.abs(want[0]).sum() > 0
        for key, got in out.items():
            np.testing.assert_array_equal(got[0], want[0], err_msg=f"{name} {key}")
            assert got[1:] == want[1:], (name, key)
        if resolver == "subpoints":
            ref = area_estimate_reference(
                c,
                r,
                grid,
                resolver="subpoints",
                depth_slots=opts.get("depth_slots", 3),
                lamps=opts.get("lamps", "all"),
                active=active,
                _cell_seeds="both" if est.get("gather_both") else "side",
                _hidden_rounds=est.get("hidden_rounds", 0),
            )
            np.testing.assert_array_equal(out["sides", True][0], ref.units, err_msg=name)


def test_cell_pass_refuses_bad_values_and_counts_its_buffer():
    """``cell_pass`` takes "cells" or "sides" only, naming itself otherwise; the side pass's buffer (144 bytes per
    lamp and cell) is in ``nbytes`` and leaves it when switched off."""
    c = np.array([[0.0, 0.0, 0.0], [0.3, 0.1, 0.2]])
    r = np.array([0.25, 0.2])
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4)
    est = wl.ShiningLamp(grid, criterion="area", device="cpu").estimator
    base = est.nbytes
    est.cell_pass = "sides"
    assert est.nbytes == base + 2 * grid.n_cells * 144
    est.cell_pass = "cells"
    assert est.nbytes == base
    with pytest.raises(ValueError, match=r"^cell_pass: expected 'cells' or 'sides'"):
        est.cell_pass = "lanes"


@pytest.mark.parametrize("subpoints", [1, 3, 4, 8, 12])
def test_side_pass_subpoints_by_seed_equal_by_point_bitwise(device, subpoints):
    """The side pass's sub-points seed by seed over a mask of the points taken (S <= 8; S = 12 falls back to point
    by point) give bitwise the units of point by point and of the one-thread cell pass, on overlapping spheres."""
    rng = np.random.default_rng(11)
    c, r = polydisperse_scene(rng, n=150)
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4)
    pos, rad = device_arrays(grid.to_frame(c), r, device)
    out = []
    for cell_pass, rows in (("cells", False), ("sides", False), ("sides", True)):
        lamp = wl.ShiningLamp(grid, criterion="area", resolver="subpoints", subpoints=subpoints, device=device)
        lamp.estimator.cell_pass = cell_pass
        lamp.estimator.subpoint_rows = rows
        lamp.update(pos, rad, in_frame=True)
        out.append(lamp.counts_numpy())
    assert np.abs(out[0]).sum() > 0
    for got in out[1:]:
        np.testing.assert_array_equal(got, out[0])


def test_hidden_rounds_from_kept_keys_equal_from_emptied_slots(device):
    """Hidden rounds whose depth pass starts from the previous keys less the flagged spheres' (``hidden_warm``)
    leave bitwise the keys, units and counters of rounds from emptied slots, on a lattice ball with both lamps'
    gather, over two updates (the second seeded by the first)."""
    from warp_lamp.scenes import scene_lattice_ball

    ball = scene_lattice_ball(diameter=0.03, seed=3)
    grid = wl.LampGrid.enclosing(ball.centers, ball.radii, cells_per_diameter=4)
    pos, rad = device_arrays(grid.to_frame(ball.centers), ball.radii, device)
    out = []
    for warm in (False, True):
        lamp = wl.ShiningLamp(grid, criterion="area", depth_slots=4, gather="deep", device=device)
        lamp.estimator.hidden_warm = warm
        got = []
        for _ in range(2):
            lamp.update(pos, rad, in_frame=True)
            d = lamp.diagnostics()
            got.append((lamp.keys.numpy().copy(), lamp.counts_numpy(), d.area_overflow, d.invalid))
        out.append(got)
    for (k0, c0, o0, i0), (k1, c1, o1, i1) in zip(*out, strict=True):
        np.testing.assert_array_equal(k1, k0)
        np.testing.assert_array_equal(c1, c0)
        assert (o1, i1) == (o0, i0)
    assert np.abs(out[0][0][1]).sum() > 0
