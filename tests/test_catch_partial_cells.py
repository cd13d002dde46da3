"""Boxes that are not a whole number of cells: ``LampGrid(lower, upper, h)`` must still cover the whole box.

The docstring promises ``ceil((upper - lower) / h)`` cells per axis, so the grid may end past ``upper`` but never
before it, and a sphere anywhere inside the box is lit by every lamp and never counted as outside.
"""

import math
from fractions import Fraction

import numpy as np
import pytest

import warp_lamp as wl
from warp_lamp.lamp import lamp_update

# (lower, upper, cell): whole-cell boxes are what every other test uses; these leave a part cell on some axis.
BOXES = [
    ("0", "1", ("0.3", "0.3", "0.3")),  # 3.33 cells
    ("-0.35", "0.65", ("0.3", "0.3", "0.3")),
    ("0", "2", ("0.3", "0.25", "0.45")),  # 6.67, 8 (whole) and 4.44 cells
    ("2", "5.3", ("0.5", "0.6", "0.7")),
]


def hand_counts(lower, upper, cells):
    """ceil((upper - lower) / h) per axis, in exact decimal arithmetic."""
    return [math.ceil((Fraction(upper) - Fraction(lower)) / Fraction(h)) for h in cells]


@pytest.mark.parametrize(("lower", "upper", "cells"), BOXES)
def test_grid_covers_a_box_that_is_not_whole_cells(lower, upper, cells):
    """Cells per axis are ceil(L / h), counted by hand in exact decimals; the grid ends at or past ``upper``."""
    h = np.array([float(x) for x in cells])
    grid = wl.LampGrid([float(lower)] * 3, [float(upper)] * 3, h)
    n = hand_counts(lower, upper, cells)
    np.testing.assert_array_equal(grid.box_counts, n)
    for a in range(3):
        for k, d in enumerate(((a + 1) % 3, (a + 2) % 3)):
            assert grid.counts[a, k] == n[d]
            assert grid.corner[a, k] + grid.counts[a, k] * grid.cell[a, k] >= float(upper) - 1e-12


@pytest.mark.parametrize("criterion", [1, 0])
@pytest.mark.parametrize(("lower", "upper", "cells"), BOXES)
def test_spheres_in_every_corner_of_the_box_are_lit(device, lower, upper, cells, criterion):
    """A sphere inside each of the box's eight corners (radius 3/4 of the largest cell, so that some centre ray
    meets it, a twentieth of a cell from the faces) is lit by the three lamps that face its corner, is not counted
    outside, and the forces balance."""
    lo, up = float(lower), float(upper)
    h = np.array([float(x) for x in cells])
    grid = wl.LampGrid([lo] * 3, [up] * 3, h)
    r = 0.75 * h.max()
    gap = r + 0.05 * h.min()
    centers = np.array([[(lo + gap, up - gap)[(k >> d) & 1] for d in range(3)] for k in range(8)])
    lamp = lamp_update(centers, np.full(8, r), grid=grid, criterion=criterion, device=device)
    d = lamp.diagnostics()
    assert d.outside == 0
    assert d.surface.all()
    for a in range(3):
        for side in range(2):  # the low lamp of axis a sees the four spheres at the low end of a; the high, the rest
            name = wl.LAMPS[2 * a + side]
            assert set(np.unique(d.owners[name])) >= {k for k in range(8) if (k >> a) & 1 == side}, name
    np.testing.assert_array_equal(lamp.forces_numpy(1.0e6).sum(axis=0), 0.0)


def test_lamp_forces_on_a_partial_cell_grid_load_the_far_side(device):
    """Spheres inside [0, 1]^3 near its upper corner, on 0.03 m cells (33.3 per axis): the forces equal those on a
    grid of the same lattice that reaches past the box by whole cells, and the spheres are inside both."""
    rng = np.random.default_rng(4)
    centers = rng.uniform(0.9, 0.97, (20, 3))
    radii = rng.uniform(0.01, 0.025, 20)
    partial = wl.LampGrid([0.0] * 3, [1.0] * 3, 0.03)
    whole = wl.LampGrid([0.0] * 3, [1.2] * 3, 0.03)
    f = wl.lamp_forces(centers, radii, 1.0e6, grid=partial, device=device)
    g = wl.lamp_forces(centers, radii, 1.0e6, grid=whole, device=device)
    assert np.count_nonzero(g) > 20
    np.testing.assert_array_equal(f, g)
    assert lamp_update(centers, radii, grid=partial, device=device).diagnostics().outside == 0
