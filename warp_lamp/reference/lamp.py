"""Float64 reference of the shining lamp (criteria 0 and 1), written for clarity rather than speed.

It decides every cell in float64. The kernels decide in float32, so where a decision sits
within float32 rounding of a boundary (a cell centre on a sphere's silhouette, two depths within rounding of
each other) the two may legitimately differ: the reference flags those cells as ambiguous, with a bound
derived from float32's unit roundoff, and tests compare every other cell exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warp_lamp.grid import LampGrid
from warp_lamp.validate import LAMPS, lamp_mask

__all__ = ["EPS32", "LampReference", "lamp_reference", "wall_gaps"]

#: Unit roundoff of float32.
EPS32 = 2.0**-24


@dataclass
class LampReference:
    """Reference answer. ``owners``, ``depths``, ``ambiguous`` and ``wall_owners`` are per lamp name, indexed
    ``[i, j]``; ``wall_owners`` holds the wall that took the cell (-1: none), ``wall_counts`` (W, 3) the walls'
    signed counts."""

    owners: dict
    depths: dict
    ambiguous: dict
    counts: np.ndarray
    wall_owners: dict | None = None
    wall_counts: np.ndarray | None = None


def _ray_fluid(walls: np.ndarray, grid: LampGrid, a: int):
    """For every cell-centre ray of grid a, the part in the fluid, in float64 by definition: whether any (wet),
    its ends lo < hi along a (local: minus the grid origin; -inf / inf where open) and the walls that bound them
    (-1: open). lo is the largest crossing of a wall whose normal has a positive a-component (ties to the lowest
    wall), hi the smallest of one with a negative component; a wall parallel to the ray with the ray behind it
    (g < 0) leaves it dry."""
    u, v = (a + 1) % 3, (a + 2) % 3
    (cu, cv), (hu, hv), (nu, nv) = grid.corner[a], grid.cell[a], grid.counts[a]
    pu = (cu + (np.arange(nu) + 0.5) * hu)[:, None]
    pv = (cv + (np.arange(nv) + 0.5) * hv)[None, :]
    wet = np.ones((nu, nv), dtype=bool)
    lo, hi = np.full((nu, nv), -np.inf), np.full((nu, nv), np.inf)
    lo_wall, hi_wall = np.full((nu, nv), -1), np.full((nu, nv), -1)
    for w, (nx, ny, nz, d) in enumerate(walls):
        n = (nx, ny, nz)
        # n . x - d along the ray x = (pu, pv) + t e_a, in global frame coordinates.
        g = np.broadcast_to(n[u] * pu + n[v] * pv - d, (nu, nv))
        if n[a] == 0.0:
            wet &= g >= 0.0
            continue
        t = -g / n[a] - grid.origin[a]
        if n[a] > 0.0:
            better = t > lo
            lo, lo_wall = np.where(better, t, lo), np.where(better, w, lo_wall)
        else:
            better = t < hi
            hi, hi_wall = np.where(better, t, hi), np.where(better, w, hi_wall)
    wet &= lo < hi
    return wet, lo, hi, lo_wall, hi_wall


def wall_gaps(centers, radii, walls) -> np.ndarray:
    """Per wall, the smallest (n . c - d - r) / r over the particles (inf without particles), in float64."""
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    walls = np.asarray(walls, dtype=np.float64).reshape(-1, 4)
    if not len(r):
        return np.full(len(walls), np.inf)
    return ((c @ walls[:, :3].T - walls[:, 3] - r[:, None]) / r[:, None]).min(axis=0)


def _lamp_cells(local_c, r, visible, grid: LampGrid, a: int, criterion: int, lo_side: bool):
    """Per-cell winner of one lamp, plus the ambiguity band. Spheres are visited in index order."""
    u, v = (a + 1) % 3, (a + 2) % 3
    (cu, cv), (hu, hv), (nu, nv) = grid.corner[a], grid.cell[a], grid.counts[a]
    cu -= grid.origin[u]
    cv -= grid.origin[v]
    best = np.full((nu, nv), np.inf)
    best_id = np.full((nu, nv), -1)
    best_tol = np.zeros((nu, nv))
    best_near = np.zeros((nu, nv), dtype=bool)
    others_lo = np.full((nu, nv), np.inf)
    for k in np.flatnonzero(visible):
        pu, pv, pd, rk = local_c[k, u] - cu, local_c[k, v] - cv, local_c[k, a], r[k]
        i0 = max(int(np.floor((pu - rk) / hu)) - 1, 0)
        i1 = min(int(np.floor((pu + rk) / hu)) + 1, nu - 1)
        j0 = max(int(np.floor((pv - rk) / hv)) - 1, 0)
        j1 = min(int(np.floor((pv + rk) / hv)) + 1, nv - 1)
        if i0 > i1 or j0 > j1:
            continue
        ii, jj = np.meshgrid(np.arange(i0, i1 + 1), np.arange(j0, j1 + 1), indexing="ij")
        if criterion == 1:
            du = (ii + 0.5) * hu - pu
            dv = (jj + 0.5) * hv - pv
        else:
            du = np.maximum(np.maximum(ii * hu - pu, pu - (ii + 1) * hu), 0.0)
            dv = np.maximum(np.maximum(jj * hv - pv, pv - (jj + 1) * hv), 0.0)
        d2 = du * du + dv * dv
        # The kernels test du^2 <= r^2 - dv^2 in float32: the same criterion, rounded differently.
        # Rounding of the float32 inputs and of each float32 operation on the way to d2 and r2.
        scale_u = np.abs(ii + 1) * hu + abs(pu) + abs(local_c[k, u]) + abs(cu)
        scale_v = np.abs(jj + 1) * hv + abs(pv) + abs(local_c[k, v]) + abs(cv)
        err2 = 16 * EPS32 * (rk * rk + d2 + 2 * np.abs(du) * scale_u + 2 * np.abs(dv) * scale_v)
        hit = d2 <= rk * rk
        near = np.abs(d2 - rk * rk) <= err2
        if criterion == 1:
            s2 = np.maximum(rk * rk - d2, 0.0)
            s = np.sqrt(s2)
            depth = pd - s if lo_side else -(pd + s)
            ds = np.where(s2 > err2, err2 / (2 * np.sqrt(np.maximum(s2, err2))), np.sqrt(err2))
            tol = 8 * EPS32 * (abs(pd) + s) + 2 * ds
        else:
            depth = np.full(d2.shape, pd if lo_side else -pd)
            tol = np.full(d2.shape, 8 * EPS32 * abs(pd))
        sl = (slice(i0, i1 + 1), slice(j0, j1 + 1))
        wins = hit & (depth < best[sl])
        # A displaced winner, and every losing candidate or near miss, can still win under rounding if it
        # comes within tolerance of the final winner: keep the lowest (depth - tol) of them.
        displaced = wins & (best_id[sl] >= 0)
        others_lo[sl] = np.where(displaced, np.minimum(others_lo[sl], best[sl] - best_tol[sl]), others_lo[sl])
        loser = (hit | near) & ~wins
        others_lo[sl] = np.where(loser, np.minimum(others_lo[sl], depth - tol), others_lo[sl])
        best[sl] = np.where(wins, depth, best[sl])
        best_id[sl] = np.where(wins, k, best_id[sl])
        best_tol[sl] = np.where(wins, tol, best_tol[sl])
        best_near[sl] = np.where(wins, near, best_near[sl])
    lit = best_id >= 0
    ambiguous = np.where(lit, best_near | (others_lo <= best + best_tol), np.isfinite(others_lo))
    depth_global = (best if lo_side else -best) + grid.origin[a]
    return best_id, np.where(lit, depth_global, np.nan), ambiguous


def lamp_reference(
    centers, radii, grid: LampGrid, *, criterion: int = 1, lamps="all", active=None, walls=None, rest: float = 0.1
) -> LampReference:
    """Owners, depths and signed counts of every lamp, in float64, by brute force over spheres and cells.

    Args:
        centers: Particle centres [m], shape (N, 3), in the grid's frame (``R^T x``; no rotation is applied).
        radii: Particle radii [m], shape (N,).
        grid: The lamp grids.
        criterion: 1 (cell-centre ray) or 0 (cell rectangle meets the projected disk).
        lamps: "all" or names from :data:`warp_lamp.LAMPS`.
        active: Optional mask, shape (N,); inactive particles are left out.
        walls: Optional planes (W, 4) in the same coordinates as ``centers``: unit normal n into the fluid and
            offset d, the fluid being n . x > d. Along each cell-centre ray the fluid is (lo, hi) and the body the
            span [E, X] of its first entry and last exit (centres for criterion 0). Where the span meets the
            fluid, the low lamp loads the first sphere (+1) and the wall at lo (-1) unless E <= lo or the body
            rests on that wall; the high lamp likewise at hi. A wet ray with no body in its fluid: the low lamp's
            +1 goes to the wall at hi, the high lamp's -1 to the wall at lo. Within float32 rounding of a
            comparison a cell is ambiguous.
        rest: The body rests on a wall when its smallest (n . c - d - r) / r lies within [-rest, rest]
            (``warp_lamp.validate.WALL_REST``).
    """
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    n = len(r)
    visible = np.ones(n, dtype=bool) if active is None else np.asarray(active) != 0
    local_c = c - grid.origin
    mask = lamp_mask(lamps)
    owners, depths, ambiguous, wall_owners = {}, {}, {}, {}
    counts = np.zeros((n, 3), dtype=np.int64)
    walls = np.zeros((0, 4)) if walls is None else np.asarray(walls, dtype=np.float64).reshape(-1, 4)
    wall_counts = np.zeros((len(walls), 3), dtype=np.int64)
    gaps = wall_gaps(c[visible], r[visible], walls)
    rests = np.abs(gaps) <= rest
    for a in range(3):
        shape = tuple(int(x) for x in grid.counts[a])
        both = [_lamp_cells(local_c, r, visible, grid, a, criterion, side == 0) for side in range(2)]
        if len(walls):
            both = _walled(both, walls, rests, grid, a, wall_counts, mask)
        for side in range(2):
            name = LAMPS[2 * a + side]
            own, dep, amb, took = both[side] if len(both[side]) == 4 else (*both[side], np.full(shape, -1))
            wall_owners[name] = took
            if not mask >> (2 * a + side) & 1:
                own, dep, amb = np.full(shape, -1), np.full(shape, np.nan), np.zeros(shape, dtype=bool)
                wall_owners[name] = np.full(shape, -1)
            owners[name], depths[name], ambiguous[name] = own, dep, amb
            np.add.at(counts[:, a], own[own >= 0], 1 if side == 0 else -1)
    return LampReference(owners, depths, ambiguous, counts, wall_owners, wall_counts)


def _walled(both, walls, rests, grid: LampGrid, a: int, wall_counts, mask: int):
    """Both lamps of axis a with the walls: (owner, depth, ambiguous, target wall) per side; adds the walls' counts
    of the lamps that are on (targets and recoils) to ``wall_counts``."""
    (own0, dep0, amb0), (own1, dep1, amb1) = both
    wet, lo, hi, lo_wall, hi_wall = _ray_fluid(walls, grid, a)
    e = dep0 - grid.origin[a]
    x = dep1 - grid.origin[a]
    lit = (own0 >= 0) & (own1 >= 0)
    has_lo, has_hi = lo_wall >= 0, hi_wall >= 0
    with np.errstate(invalid="ignore"):
        body = wet & lit & ~(has_lo & (x <= lo)) & ~(has_hi & (e >= hi))
        seal0 = has_lo & ((e <= lo) | rests[np.maximum(lo_wall, 0)])
        seal1 = has_hi & ((x >= hi) | rests[np.maximum(hi_wall, 0)])

    def tol(p, q):
        return 8 * EPS32 * (np.abs(np.nan_to_num(p)) + np.abs(np.where(np.isfinite(q), q, 0.0)) + 1e-30)

    # The kernels compare float32 depths with float64 crossings: within rounding, a comparison may go either way.
    near = np.zeros(e.shape, dtype=bool)
    for p, q in ((e, lo), (x, lo), (e, hi), (x, hi)):
        with np.errstate(invalid="ignore"):
            near |= lit & np.isfinite(q) & (np.abs(p - q) <= tol(p, q))
    out = []
    for side, (own, dep, _amb) in enumerate(both):
        sign = 1 if side == 0 else -1
        seal = seal0 if side == 0 else seal1
        recoil = lo_wall if side == 0 else hi_wall
        empty_target = hi_wall if side == 0 else lo_wall
        loads = body & ~seal
        target_wall = np.where(wet & ~body & (empty_target >= 0), empty_target, -1)
        new_own = np.where(loads, own, -1)
        if mask >> (2 * a + side) & 1:
            took = target_wall[target_wall >= 0]
            np.add.at(wall_counts[:, a], took, sign)
            rec = recoil[loads & (recoil >= 0)]
            np.add.at(wall_counts[:, a], rec, -sign)
        out.append((new_own, np.where(new_own >= 0, dep, np.nan), amb0 | amb1 | near, target_wall))
    return out
