"""The per-cell kernel of the area criterion against its float64 reference, fed the reference's D-slot keys."""

import numpy as np
import pytest
import warp as wp
from helpers import DEVICES, polydisperse_scene

import warp_lamp as wl
from warp_lamp.kernels import area as KA
from warp_lamp.kernels.lamp import LampParticles
from warp_lamp.lamp import lamp_mask
from warp_lamp.reference.area import (
    EXACT_UNIT,
    _pair_relations,
    _surface_order,
    area_depth_slots,
    area_estimate_reference,
    ordered_key,
    visible_area_reference,
    visible_disk_areas,
    visible_sphere_areas,
)

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


def scenes(rng):
    """Random polydisperse (heavily overlapping), snapped to a coarse lattice (ties), and disjoint-ish dense."""
    c, r = polydisperse_scene(rng, n=150)
    yield "random", c, r
    yield "snapped", np.round(c * 4) / 4, np.round(r * 8 + 1) / 8
    c = rng.uniform(0, 4, (300, 3))
    yield "dense", c, rng.uniform(0.25, 0.42, 300)


def test_subpoints_equal_the_reference_unit_for_unit(device, rng):
    """Sub-point resolver: every particle's units equal the reference's exactly, for several D, S and grids,
    and the overflow and one-sided counters agree."""
    for name, c, r in scenes(rng):
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
    for name, c, r in scenes(rng):
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
    for _, c, r in scenes(rng):
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
def test_cpu_and_cuda_bitwise_equal_for_subpoints(rng):
    """Sub-point units on CUDA are bitwise those of the CPU (fuse_fp off; no transcendental functions)."""
    for _, c, r in scenes(rng):
        grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3)
        cpu, _ = run_area_kernel(c, r, grid, "cpu", resolver="subpoints")
        for dev in DEVICES[1:]:
            gpu, _ = run_area_kernel(c, r, grid, dev, resolver="subpoints")
            np.testing.assert_array_equal(cpu, gpu)


# --- overlapping spheres: the surface seen first (issue 19) -------------------------------------------------


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
