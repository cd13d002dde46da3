"""Bad input: a clear error naming the argument (and the first bad index), and nothing written."""

import numpy as np
import pytest
import warp as wp
from helpers import DEVICES

import warp_lamp as wl

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
