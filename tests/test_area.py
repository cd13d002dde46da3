"""The area criterion end to end: the library's D-slot depth pass and per-cell pass against the float64 references."""

import numpy as np
import pytest
import warp as wp
from helpers import device_arrays, first_surface_raster, polydisperse_scene, raster_visible_areas

import warp_lamp as wl
from warp_lamp.measures import visible_area_error
from warp_lamp.reference import area_depth_slots, area_estimate_reference, visible_area_reference
from warp_lamp.scenes import scene_overlapping_polydisperse


def area_lamp(centers, radii, device, **options):
    return wl.lamp_update(centers, radii, criterion="area", device=device, **options)


def scenes(rng):
    c, r = polydisperse_scene(rng, n=150)
    yield "random", c, r
    yield "snapped", np.round(c * 4) / 4, np.round(r * 8 + 1) / 8
    yield "dense", rng.uniform(0, 4, (300, 3)), rng.uniform(0.25, 0.42, 300)


@pytest.mark.parametrize("depth_slots", [1, 3, 4])
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
        ({"depth_slots": 5}, r"depth_slots: expected an integer in \[1, 4\]"),
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


# --- overlapping spheres (issue 19) -------------------------------------------------------------------------


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
    under 0.4% of P pi rbar^2 with the exact resolver and 0.6% with sub-points (issue 19's targets; measured
    0.04% and 0.53% here; the 1,000-sphere ball, against 128 rays per diameter, 0.96% and 1.06% by centre
    depth, 0.08% and 0.46% now); balance stays exact."""
    s = scene_overlapping_polydisperse(300)
    areas, _ = raster_visible_areas(s.centers, s.radii, 256)
    rms = {}
    for resolver in ("exact", "subpoints"):
        f = wl.lamp_forces(s.centers, s.radii, 1.0, criterion="area", resolver=resolver, device=device)
        assert np.all(f.sum(axis=0) == 0.0)
        rms[resolver] = visible_area_error(f, areas, 1.0, float(s.radii.mean()))["rms"]
    assert rms["exact"] < 0.004 and rms["subpoints"] < 0.006, rms


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
