"""Cells that float32 cannot represent exactly (h = 0.1, 0.3, 1/3) on lattice-aligned scenes, where cell centres and
cell edges fall exactly on sphere silhouettes.

Off the silhouette, every cell is decided as exact rational arithmetic decides it. On it, float32 rounding decides
(the exact answer is a tie), but it must decide the same way whichever path asks: the depth pass (which walks a
footprint of cells), a per-cell ray caster (which walks none), and the seed that re-tests last update's owners. A
footprint that leaves out a cell its own hit test accepts makes these disagree.
"""

from fractions import Fraction

import numpy as np
import pytest
import warp as wp
from helpers import bvh_owners

import warp_lamp as wl
from warp_lamp.lamp import lamp_update

CELLS = [Fraction(1, 10), Fraction(3, 10), Fraction(1, 3)]
RADIUS_CELLS = 5  # 3-4-5 and 5-0-5: twelve lattice points on each silhouette
#: Cells exactly on one silhouette: criterion 1, the twelve cell centres; criterion 0, the cells whose nearest point
#: is one of the twelve lattice points: one cell for each of the eight (3, 4)-type points, two for each of the four
#: (5, 0)-type points (the cells on both sides of the line the point lies on): 8 + 8.
ON_SILHOUETTE = {1: 12, 0: 16}
N_CELLS = 24


def lattice_scene(h: Fraction, criterion: int):
    """Eight spheres of radius 5 h, 12 cells apart, centred on cell centres (criterion 1: centre rays meet the
    silhouette at the 3-4-5 points) or on cell corners (criterion 0: cell edges touch it there), exactly in
    rationals; and the box grid of 24^3 cells from the origin."""
    offset = Fraction(11, 2) if criterion == 1 else Fraction(6)
    centres = [
        [(offset + 12 * a) * h, (offset + 12 * b) * h, (offset + 12 * c) * h]
        for a in range(2)
        for b in range(2)
        for c in range(2)
    ]
    radii = [RADIUS_CELLS * h] * len(centres)
    return centres, radii


def exact_decision(centres, radii, h: Fraction, counts, criterion: int):
    """Per lamp: the owner of each cell in exact arithmetic (-1 unlit), and the cells exactly on a silhouette.

    Criterion 1: the centre ray meets the sphere, (u - pu)^2 + (v - pv)^2 <= r^2 at the cell centre; criterion 0:
    the cell rectangle meets the projected disk (its nearest point). The nearest sphere along the ray wins; the
    spheres here are 12 cells apart along every axis, so depths never tie.
    """
    owners, boundary = {}, {}
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        nu, nv = (int(x) for x in counts[a])
        for side in range(2):
            name = wl.LAMPS[2 * a + side]
            own = np.full((nu, nv), -1)
            on = np.zeros((nu, nv), dtype=bool)
            best = np.full((nu, nv), np.inf)
            for k, (c, r) in enumerate(zip(centres, radii, strict=True)):
                for i in range(nu):
                    for j in range(nv):
                        if criterion == 1:
                            du = (i + Fraction(1, 2)) * h - c[u]
                            dv = (j + Fraction(1, 2)) * h - c[v]
                        else:
                            du = max(i * h - c[u], c[u] - (i + 1) * h, Fraction(0))
                            dv = max(j * h - c[v], c[v] - (j + 1) * h, Fraction(0))
                        d2 = du * du + dv * dv
                        if d2 > r * r:
                            continue
                        on[i, j] |= d2 == r * r
                        depth = float(c[a]) if side == 0 else -float(c[a])
                        if depth < best[i, j]:
                            best[i, j], own[i, j] = depth, k
            owners[name], boundary[name] = own, on
    return owners, boundary


def as_float(centres, radii):
    return np.array([[float(x) for x in c] for c in centres]), np.array([float(r) for r in radii])


@pytest.mark.parametrize("criterion", [1, 0])
@pytest.mark.parametrize("h", CELLS, ids=["h=0.1", "h=0.3", "h=1/3"])
def test_off_silhouette_cells_follow_exact_arithmetic(device, h, criterion):
    """Every cell not exactly on a silhouette has the owner exact rational arithmetic gives it; the twelve cells per
    disk (16 for criterion 0) exactly on it are either unlit or lit by one of the spheres."""
    centres, radii = lattice_scene(h, criterion)
    c, r = as_float(centres, radii)
    grid = wl.LampGrid([0.0] * 3, [float(N_CELLS * h)] * 3, float(h))
    d = lamp_update(c, r, grid=grid, criterion=criterion, device=device).diagnostics()
    owners, boundary = exact_decision(centres, radii, h, grid.counts, criterion)
    for name in wl.LAMPS:
        on = boundary[name]
        assert on.sum() == 4 * ON_SILHOUETTE[criterion], (name, on.sum())  # four disks per lamp
        np.testing.assert_array_equal(d.owners[name][~on], owners[name][~on], err_msg=name)
        assert np.isin(d.owners[name][on], [-1, *range(len(radii))]).all()


@pytest.mark.parametrize("h", CELLS, ids=["h=0.1", "h=0.3", "h=1/3"])
def test_silhouette_cells_decided_alike_by_depth_pass_and_per_cell_rays(device, h):
    """Criterion 1: the lamp's depth pass and the BVH caster (one ray per cell, no footprint) give every cell,
    those exactly on a silhouette included, the same owner."""
    centres, radii = lattice_scene(h, 1)
    c, r = as_float(centres, radii)
    grid = wl.LampGrid([0.0] * 3, [float(N_CELLS * h)] * 3, float(h))
    lamp = lamp_update(c, r, grid=grid, criterion=1, device=device)
    owners, _ = bvh_owners(grid, c, r, device)
    d = lamp.diagnostics()
    _, boundary = exact_decision(centres, radii, h, grid.counts, 1)
    for name in wl.LAMPS:
        assert boundary[name].any()
        np.testing.assert_array_equal(d.owners[name], owners[name], err_msg=name)


@pytest.mark.parametrize("criterion", [1, 0])
@pytest.mark.parametrize("h", CELLS, ids=["h=0.1", "h=0.3", "h=1/3"])
def test_silhouette_cells_do_not_depend_on_the_last_update(device, h, criterion):
    """A lamp whose last update saw the spheres 2% larger (so that it held every silhouette cell) gives bitwise the
    keys of a fresh lamp: the seed's re-test and the depth pass agree on every silhouette cell."""
    centres, radii = lattice_scene(h, criterion)
    c, r = as_float(centres, radii)
    grid = wl.LampGrid([0.0] * 3, [float(N_CELLS * h)] * 3, float(h))
    pos = wp.array(grid.to_frame(c).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(r.astype(np.float32), dtype=wp.float32, device=device)
    fresh = wl.ShiningLamp(grid, criterion=criterion, device=device)
    fresh.update(pos, rad, in_frame=True)
    warm = wl.ShiningLamp(grid, criterion=criterion, device=device)
    warm.update(pos, wp.array((1.02 * r).astype(np.float32), dtype=wp.float32, device=device), in_frame=True)
    warm.update(pos, rad, in_frame=True)
    np.testing.assert_array_equal(warm.keys.numpy(), fresh.keys.numpy())
    np.testing.assert_array_equal(warm.counts_numpy(), fresh.counts_numpy())
