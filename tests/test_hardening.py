"""Issue 9: no silent wrong results, memory known before it is allocated, and API mistakes named clearly."""

import math
import time

import numpy as np
import pytest
import warp as wp
from helpers import device_arrays, polydisperse_scene

import warp_lamp as wl
from warp_lamp.lamp import pressure_area
from warp_lamp.reference import midpoint_sphere_offsets, porosity_reference

C3 = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
R3 = np.array([0.5, 0.5, 0.5])


# --- silent wrong results -----------------------------------------------------------------------------------


def test_midpoint_on_tall_cells_measures_a_sphere_not_an_ellipsoid(device):
    """A sphere in a cell twice as tall as wide: midpoint (cubic sub-cells) agrees with the exact volume to its
    resolution, as voxel does; stretched sub-cells used to count the sphere as an ellipsoid (0.800 vs 0.866)."""
    args = ([[0.5, 0.5, 1.0]], [0.4], [0, 0, 0], [1, 1, 2], (1, 1, 1))
    exact = wl.porosity(*args, method="exact", device=device)[0, 0, 0]
    mid = wl.porosity(*args, method="midpoint", subdivisions=32, device=device)[0, 0, 0]
    vox = wl.porosity(*args, method="voxel", subdivisions=32, device=device)[0, 0, 0]
    assert abs(vox - exact) < 2e-3
    assert abs(mid - exact) < 5e-3, (mid, exact)
    # The same call with the cubic sub-cells spelled out, and the reference, agree bitwise.
    per_axis = wl.porosity(*args, method="midpoint", subdivisions=(32, 32, 64), device=device)[0, 0, 0]
    assert per_axis == mid == porosity_reference(*args, method="midpoint", subdivisions=32)[0, 0, 0]


def test_midpoint_refuses_cells_that_cannot_be_cut_into_cubes():
    """Cells whose edges are not whole multiples of one sub-cell, and non-cubic per-axis counts, are refused."""
    with pytest.raises(ValueError, match=r"subdivisions: midpoint needs cubic sub-cells.*method='voxel'"):
        wl.porosity([[0.5, 0.5, 0.5]], [0.3], [0, 0, 0], [1.0, 1.0, 1.37], (1, 1, 1), method="midpoint")
    with pytest.raises(ValueError, match=r"subdivisions: midpoint needs cubic sub-cells, but \(8, 8, 8\)"):
        wl.porosity([[0.5, 0.5, 0.5]], [0.3], [0, 0, 0], [1, 1, 2], (1, 1, 1), method="midpoint", subdivisions=(8,) * 3)
    from warp_lamp.porosity import midpoint_subdivisions

    assert midpoint_subdivisions([1.0, 1.0, 2.0], 8, per_axis=False) == (8, 8, 16)
    assert midpoint_subdivisions([0.3, 0.1, 0.2], 5, per_axis=False) == (15, 5, 10)


@pytest.mark.filterwarnings("ignore:porosity. all 1 spheres")  # r <= 2: the clipped sphere misses the box
@pytest.mark.filterwarnings("ignore:subdivisions. with")  # r = 1 sub-cell: rounding warns, Table 1 is still exact
@pytest.mark.parametrize("r", [1, 2, 3, 9, 10, 17, 24])
def test_midpoint_kernel_marks_exactly_the_paper_recurrence(r):
    """The kernel's closed-form rows equal the literal midpoint recurrence, sub-cell by sub-cell, for a whole
    sphere and for one clipped by the box (centre outside it)."""
    n = 2 * r + 3
    for centre, box in (((r + 1.5,) * 3, (n, n, n)), ((-2.5, r / 2 + 0.5, r + 1.5), (r + 2, r + 1, n))):
        p = wl.porosity([centre], [float(r)], [0, 0, 0], box, box, method="midpoint", subdivisions=1, device="cpu")
        got = {tuple(int(x) for x in ijk) for ijk in np.argwhere(p == 0.0)}
        c = np.floor(centre).astype(int)
        want = {
            tuple(int(x) for x in o + c)
            for o in midpoint_sphere_offsets(r)
            if np.all(o + c >= 0) and np.all(o + c < np.asarray(box))
        }
        assert got == want


def test_midpoint_work_is_clipped_to_the_box():
    """A sphere of radius 10 km around a 1 m box takes the box's rows, not r^2 of them; radius 1e9 m is refused
    by name, not passed to an overflowing hash grid."""
    t0 = time.perf_counter()
    p = wl.porosity([[0.5, 0.5, 0.5]], [1e4], [0, 0, 0], [1, 1, 1], (1, 1, 1), method="midpoint", device="cpu")
    assert p[0, 0, 0] == 0.0
    assert time.perf_counter() - t0 < 2.0
    with pytest.raises(ValueError, match=r"radii: sphere 0 is 8e\+09 sub-cells in radius"):
        wl.porosity([[0.5, 0.5, 0.5]], [1e9], [0, 0, 0], [1, 1, 1], (1, 1, 1), method="midpoint", device="cpu")
    # A huge sphere that does not reach the box is dropped, whatever its size.
    with pytest.warns(RuntimeWarning, match="wholly outside"):
        far = wl.porosity([[0.5, 0.5, -3e9]], [1e9], [0, 0, 0], [1, 1, 1], (1, 1, 1), method="midpoint", device="cpu")
    assert far[0, 0, 0] == 1.0


def test_generator_lamps_and_other_one_shot_iterables_are_read_once(device):
    """A generator for lamps (or pressure, box corners, shape, subdivisions) gives the list's result, never an
    empty or half-read argument."""
    want = wl.lamp_forces(C3, R3, 1.0, lamps=["-x", "+y"], device=device)
    got = wl.lamp_forces(C3, R3, 1.0, lamps=(name for name in ["-x", "+y"]), device=device)
    assert np.abs(want).sum() > 0
    np.testing.assert_array_equal(got, want)
    lamp = wl.ShiningLamp(wl.LampGrid([-1] * 3, [2] * 3, 0.25), lamps=iter(["-x", "+y"]), device=device)
    assert lamp.lamp_mask == 0b1001
    np.testing.assert_array_equal(
        wl.lamp_forces(C3, R3, (p for p in (1.0, 2.0, 3.0)), device=device),
        wl.lamp_forces(C3, R3, (1.0, 2.0, 3.0), device=device),
    )
    args = (C3, R3, [-1, -1, -1], [2, 2, 2], (2, 2, 2))
    lazy = (C3, R3, iter([-1, -1, -1]), (x for x in [2, 2, 2]), iter((2, 2, 2)))
    np.testing.assert_array_equal(
        wl.porosity(*lazy, subdivisions=iter([4, 4, 4]), device=device),
        wl.porosity(*args, subdivisions=4, device=device),
    )


def test_voxel_counts_do_not_overflow_in_a_cell_of_more_than_2_31_sub_cells():
    """One full cell of 1291^3 > 2^31 sub-cells has porosity 0, not 1.955 from a wrapped int32 count."""
    p = wl.porosity([[0.5, 0.5, 0.5]], [1.0], [0, 0, 0], [1, 1, 1], (1, 1, 1), subdivisions=1291, device="cpu")
    assert p[0, 0, 0] == 0.0


def test_forces_that_would_leave_the_exact_range_are_refused():
    """A huge finite pressure (or P A) raises naming pressure instead of returning NaN forces; a float32 force
    array that cannot hold P A count is refused too."""
    with pytest.raises(ValueError, match=r"pressure: P times the cell area of grid 0 is .* N, over"):
        wl.lamp_forces(C3, R3, 1e307)
    with pytest.raises(ValueError, match=r"pressure: P times the cell area of grid 2 is .*below the smallest normal"):
        wl.lamp_forces(C3, R3, (1.0, 1.0, 1e-310))
    assert np.isfinite(wl.lamp_forces(C3, R3, 1e290)).all()
    lamp = wl.lamp_update(C3, R3, device="cpu")
    forces = wp.zeros(3, dtype=wp.vec3, device="cpu")
    with pytest.raises(ValueError, match=r"pressure: P A up to .* overflows the float32 force array"):
        lamp.add_forces(forces, 1e40)
    assert not forces.numpy().any()


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda: wl.LampGrid.enclosing(C3, R3, cells_per_diameter=1e300), r"cells_per_diameter: the grid's cell count"),
        (lambda: wl.LampGrid([0, 0, 0], [1, 1, 1], 1e-300), r"cell_size: the grid's cell count overflows"),
        (lambda: wl.LampGrid.from_grids(np.zeros((3, 2)), np.ones((3, 2)), np.full((3, 2), 1e300)), r"counts: "),
        (lambda: wl.lamp_forces(C3, R3, 1.0, cells_per_diameter=1e200), r"cells_per_diameter: "),
        (
            lambda: wl.LampGrid([0, 0, 0], [1, 1, 1], [1.0, 2**-14, 2**-14], max_bytes=math.inf),
            r"cell_size: grid 0 has 268,435,456 cells, over the 2\*\*27",
        ),
    ],
)
def test_cell_counts_that_overflow_are_refused_by_name(build, match):
    """Cell sizes, cells per diameter and memo-form counts whose cell count overflows give a ValueError naming
    the argument (not an OverflowError from the memory check); a grid past 2**27 cells is refused because its
    force sums would no longer be exact."""
    with pytest.raises(ValueError, match=match):
        build()


# --- memory -------------------------------------------------------------------------------------------------


def test_porosity_sum_methods_check_their_memory_first():
    """A 10^15-cell exact or centroid request names the shape, the bytes and max_bytes, before any allocation."""
    for method in ("exact", "centroid", "polyhedron"):
        with pytest.raises(
            ValueError,
            match=r"shape: \(100000, 100000, 100000\) cells and 3 spheres need 8,000,000,000,000,096 bytes .*"
            r"over the budget of max_bytes = 2,147,483,648 bytes",
        ):
            wl.porosity(C3, R3, [-1] * 3, [2] * 3, (100000,) * 3, method=method)


def test_union_budget_covers_the_per_cell_counts():
    """The union methods' budget counts the int64 per-cell counts as well as the bitmap."""
    from warp_lamp.porosity import porosity_nbytes

    shape = (100, 100, 100)
    bitmap = 4 * 4 * 100 * 100
    assert porosity_nbytes(shape, method="voxel", subdivisions=1, n_spheres=3) == bitmap + 8 * 10**6 + 96
    with pytest.raises(ValueError, match=r"subdivisions: \(1, 1, 1\) on shape \(100, 100, 100\) .* max_bytes = "):
        wl.porosity(C3, R3, [-1] * 3, [2] * 3, shape, subdivisions=1, max_bytes=10**6)
    assert wl.porosity(C3, R3, [-1] * 3, [2] * 3, shape, subdivisions=1, max_bytes=9 * 10**6).shape == shape


@pytest.mark.parametrize(
    ("max_bytes", "error", "match"),
    [
        (float("nan"), ValueError, r"max_bytes: expected a number of bytes >= 0"),
        (-1, ValueError, r"max_bytes: expected a number of bytes >= 0"),
        ("1e9", TypeError, r"max_bytes: expected a number of bytes, got str"),
        (True, TypeError, r"max_bytes: expected a number of bytes, got bool"),
    ],
)
def test_max_bytes_is_validated(max_bytes, error, match):
    """NaN, negative or non-numeric budgets raise, rather than meaning 'no budget'."""
    with pytest.raises(error, match=match):
        wl.porosity(C3, R3, [-1] * 3, [2] * 3, (2, 2, 2), max_bytes=max_bytes)
    with pytest.raises(error, match=match):
        wl.porosity(C3, R3, [-1] * 3, [2] * 3, (2, 2, 2), method="exact", max_bytes=max_bytes)
    with pytest.raises(error, match=match):
        wl.LampGrid([0, 0, 0], [1, 1, 1], 0.1, max_bytes=max_bytes)


def test_lamp_grid_arrays_are_read_only():
    """A LampGrid's arrays cannot be edited, so neither its memory check nor its kernels' view can be bypassed."""
    g = wl.LampGrid([0, 0, 0], [1, 1, 1], 0.25)
    for name in ("origin", "corner", "cell", "counts"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(g, name)[0] = 10**9
    assert g.n_cells == 48


# --- errors are messages --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (lambda: wl.lamp_forces(C3, R3, 1.0, cells_per_diameter="4"), TypeError, r"cells_per_diameter: expected a"),
        (lambda: wl.lamp_forces(C3, R3, 1.0, cells_per_diameter=None), TypeError, r"cells_per_diameter: expected a"),
        (lambda: wl.LampGrid.enclosing(C3, R3, cells_per_diameter="4"), TypeError, r"cells_per_diameter: expected"),
        (lambda: wl.porosity(C3, R3, [0] * 3, [1] * 3, (2, 2, 2), method=["voxel"]), ValueError, r"method: unknown"),
        (lambda: wl.lamp_forces(C3, R3, 1.0, active=["1", "0", "1"]), TypeError, r"active: expected booleans or"),
        (lambda: wl.lamp_forces(C3, R3, 1.0, active="101"), TypeError, r"active: expected booleans or numbers"),
        (lambda: wl.lamp_forces(C3, R3, "10e6"), TypeError, r"pressure: expected a number or 3 numbers"),
    ],
)
def test_arguments_of_the_wrong_type_are_named(call, error, match):
    """Strings, None and lists where a number or a name belongs raise an error naming the argument."""
    with pytest.raises(error, match=match):
        call()


def test_shining_lamp_misuse_is_named(device):
    """reserve of a non-integer, add_forces before any update, and diagnostics positions of the wrong length
    raise clear errors; add_forces before update writes nothing."""
    lamp = wl.ShiningLamp(wl.LampGrid([-1] * 3, [2] * 3, 0.25), device=device)
    with pytest.raises(TypeError, match=r"n: expected an integer >= 0, got str 'many'"):
        lamp.reserve("many")
    with pytest.raises(ValueError, match=r"n: expected an integer >= 0, got -1"):
        lamp.reserve(-1)
    forces = wp.zeros(3, dtype=wp.vec3, device=device)
    with pytest.raises(RuntimeError, match=r"add_forces: no counts yet; call ShiningLamp.update"):
        lamp.add_forces(forces, 1.0)
    pos, rad = device_arrays(C3, R3, device)
    lamp.update(pos, rad)
    lamp.add_forces(forces, 1.0)
    assert np.abs(forces.numpy()).sum() > 0
    for bad in (C3[:2], np.vstack([C3, C3])):
        with pytest.raises(ValueError, match=r"positions: expected shape \(3, 3\)"):
            lamp.diagnostics(bad, 1.0)
    assert lamp.diagnostics(pos, 1.0).moment is not None  # a warp array of the right length is fine


def test_options_are_checked_even_without_particles():
    """With N = 0, bad options still raise: nothing is skipped because there is no work."""
    empty = np.zeros((0, 3))
    grid = wl.LampGrid([0, 0, 0], [1, 1, 1], 0.5)
    for kwargs in ({"criterion": 5}, {"lamps": ["q"]}, {"cells_per_diameter": -1.0, "grid": grid}, {"active": [1]}):
        with pytest.raises((ValueError, TypeError)):
            wl.lamp_forces(empty, [], 1.0, **kwargs)
    for kwargs in ({"method": ["voxel"]}, {"max_bytes": float("nan")}, {"subdivisions": 0}, {"midpoint_algorithm": 3}):
        with pytest.raises((ValueError, TypeError)):
            wl.porosity(empty, [], [0] * 3, [1] * 3, (2, 2, 2), **kwargs)


def test_warp_arrays_are_accepted_and_the_work_follows_them(device, rng):
    """lamp_forces and porosity take warp arrays on the device they live on (read once, computed there), with
    the NumPy result; a device argument naming another device is refused."""
    centers, radii = polydisperse_scene(rng, n=40)
    pos = wp.array(centers, dtype=wp.vec3d, device=device)
    rad = wp.array(radii, dtype=wp.float64, device=device)
    np.testing.assert_array_equal(wl.lamp_forces(pos, rad, 2.0), wl.lamp_forces(centers, radii, 2.0, device=device))
    pos32, rad32 = device_arrays(centers, radii, device)
    np.testing.assert_array_equal(
        wl.lamp_forces(pos32, rad32, 2.0), wl.lamp_forces(pos32.numpy(), rad32.numpy(), 2.0, device=device)
    )
    box = ([0, 0, 0], [5.0] * 3, (3, 3, 3))
    np.testing.assert_array_equal(wl.porosity(pos, rad, *box), wl.porosity(centers, radii, *box, device=device))
    other = "cuda:0" if device == "cpu" else "cpu"
    if other == "cpu" or wp.get_cuda_device_count():
        with pytest.raises(ValueError, match=r"device: .* was asked for, but centers lives on"):
            wl.lamp_forces(pos, rad, 2.0, device=other)


def test_shining_lamp_float32_forces_round_the_exact_float64_forces(device, rng):
    """As documented: each float32 force is the exact float64 force, counts * pressure_area, rounded once; the
    float64 forces sum to exactly zero, the float32 ones only to rounding."""
    centers, radii = polydisperse_scene(rng, n=200)
    grid = wl.LampGrid.enclosing(centers, radii)
    lamp = wl.ShiningLamp(grid, device=device)
    pos, rad = device_arrays(centers - grid.origin, radii, device)
    lamp.update(pos, rad, in_frame=True)
    forces = wp.zeros(len(radii), dtype=wp.vec3, device=device)
    P = 1.2345e6
    lamp.add_forces(forces, P)
    exact = lamp.counts_numpy() * pressure_area(P, grid)
    assert np.all(exact.sum(axis=0) == 0.0)
    assert [math.fsum(exact[:, a]) for a in range(3)] == [0.0, 0.0, 0.0]
    np.testing.assert_array_equal(forces.numpy(), exact.astype(np.float32))


def test_porosity_warns_when_the_box_and_the_spheres_cannot_match():
    """Spheres in metres against a box in millimetres (none reaches the box, or they fill under 1e-9 of it) warn."""
    centers = np.random.default_rng(1).uniform(0, 0.1, (50, 3))
    with pytest.warns(RuntimeWarning, match=r"all 50 spheres lie wholly outside the box"):
        wl.porosity(centers, 0.0025, [100] * 3, [200] * 3, (2, 2, 2), method="exact")
    with pytest.warns(RuntimeWarning, match=r"share one unit"):
        wl.porosity(centers, 0.0025, [0] * 3, [100] * 3, (2, 2, 2), method="exact")
