"""The midpoint method's inputs: which sub-cell a centre goes to, and how a radius rounds to whole sub-cells.

The paper's algorithms take integer centres and radii. ``warp_lamp.porosity`` rounds them (centre: the sub-cell
that holds it, floor; radius: nearest whole number of sub-cell edges, ties to even, at least 1). Here the rounding
is done by hand on dyadic sub-cells (so that the ties are exact), and the reference is checked not to borrow the
library's rounding.
"""

import ast
import importlib
import inspect

import numpy as np
import pytest

from warp_lamp.porosity import porosity
from warp_lamp.reference import midpoint_sphere_offsets, porosity_reference

# By module name: the package re-exports a function called porosity, which shadows the submodule as an attribute.
porosity_module = importlib.import_module("warp_lamp.porosity")
reference_module = importlib.import_module("warp_lamp.reference.porosity")

# Cubic sub-cells of 0.25 m (the midpoint method needs cubes), one per cell, so that porosity shows the bitmap;
# the anisotropic box (24 x 16 x 20 cells) keeps the three axes apart.
HS = np.array([0.25, 0.25, 0.25])
SHAPE = (24, 16, 20)

# (centre [m], radius [m], centre sub-cell by hand, radius in sub-cells by hand)
CASES = [
    ((3.0, 2.0, 2.5), 0.625, (12, 8, 10), 2),  # r/h = 2.5: ties to even, 2
    ((3.0, 2.0, 2.5), 0.875, (12, 8, 10), 4),  # 3.5: to even, 4
    ((3.0, 2.0, 2.5), 0.7, (12, 8, 10), 3),  # 2.8
    ((2.99, 1.99, 2.49), 0.6, (11, 7, 9), 2),  # just below a sub-cell corner: floor, not nearest
    ((0.249, 0.249, 0.249), 0.25, (0, 0, 0), 1),
    ((3.2, 2.3, 2.6), 0.05, (12, 9, 10), 1),  # r/h = 0.2 rounds to 0: at least 1
    ((-0.1, 2.0, 2.5), 1.0, (-1, 8, 10), 4),  # centre outside the box: floor, -1, not 0
]


def marked(centre, radius, algorithm, device):
    """Solid sub-cells of one sphere on the grid (one sub-cell per cell), by the library."""
    upper = HS * SHAPE
    eps = porosity(
        [centre],
        [radius],
        [0, 0, 0],
        upper,
        SHAPE,
        method="midpoint",
        subdivisions=1,
        midpoint_algorithm=algorithm,
        device=device,
    )
    return {tuple(int(x) for x in p) for p in np.argwhere(eps == 0.0)}


def expected(cell, rad, algorithm):
    """Algorithm 1: the paper's traversal pattern of radius rad around cell; Algorithm 2: the sub-cells with
    |p - c|^2 - r^2 < 0. Clipped to the grid."""
    if algorithm == 1:
        pts = midpoint_sphere_offsets(rad) + np.asarray(cell)
    else:
        r = range(-rad, rad + 1)
        pts = np.array([(i, j, k) for i in r for j in r for k in r if i * i + j * j + k * k < rad * rad]) + cell
    inside = np.all((pts >= 0) & (pts < np.asarray(SHAPE)), axis=1)
    return {tuple(int(x) for x in p) for p in pts[inside]}


@pytest.mark.filterwarnings("ignore:subdivisions. with")  # radii of 1 sub-cell on purpose: the rounding warns
@pytest.mark.parametrize("algorithm", [1, 2])
@pytest.mark.parametrize(("centre", "radius", "cell", "rad"), CASES)
def test_midpoint_rounds_centres_down_and_radii_to_nearest_even(device, centre, radius, cell, rad, algorithm):
    """The sub-cells the midpoint method marks for one sphere are the pattern of the hand-rounded centre and
    radius, for both of the paper's algorithms; the float64 reference marks the same."""
    got = marked(centre, radius, algorithm, device)
    want = expected(cell, rad, algorithm)
    assert got == want
    ref = porosity_reference(
        [centre],
        [radius],
        [0, 0, 0],
        HS * SHAPE,
        SHAPE,
        method="midpoint",
        subdivisions=1,
        midpoint_algorithm=algorithm,
    )
    assert {tuple(int(x) for x in p) for p in np.argwhere(ref == 0.0)} == want


def test_reference_does_not_borrow_the_library_rounding(monkeypatch):
    """The reference's midpoint inputs are its own: it imports nothing from ``warp_lamp.porosity``, and breaking
    the library's rounding does not change the reference's answer."""
    tree = ast.parse(inspect.getsource(reference_module))
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            assert node.module != "warp_lamp.porosity", ast.dump(node)
        if isinstance(node, ast.Import):
            assert all(a.name != "warp_lamp.porosity" for a in node.names)
    args = ([[3.0, 2.0, 2.5], [1.3, 2.2, 4.4]], [0.875, 0.6], [0, 0, 0], HS * SHAPE, SHAPE)
    before = porosity_reference(*args, method="midpoint", subdivisions=1)
    monkeypatch.setattr(porosity_module, "_midpoint_spheres", lambda local, radii, hs: (None, None))
    np.testing.assert_array_equal(porosity_reference(*args, method="midpoint", subdivisions=1), before)
