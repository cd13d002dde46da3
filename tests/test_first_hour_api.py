"""The Python API's first-hour defects (issue "The first hour, again"): a midpoint porosity far off at tiny r/h,
one rule for tensor and per-axis pressures, Kozeny-Carman with per-particle radii, a unit mix-up behind a grid
over its budget, a CUDA device on a machine without one, and NumPy reprs in messages."""

import math
import warnings

import numpy as np
import pytest
import warp as wp

import warp_lamp as wl
from warp_lamp.frames import lamp_pressure
from warp_lamp.scenes import scene_lattice_ball
from warp_lamp.validate import check_box, check_positive, check_vec3


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
