"""Plain float64 NumPy references for the kernels, written for clarity rather than speed.

The lamp reference decides every cell in float64. The kernels decide in float32, so where a decision sits
within float32 rounding of a boundary (a cell centre on a sphere's silhouette, two depths within rounding of
each other) the two may legitimately differ: the reference flags those cells as ambiguous, with a bound
derived from float32's unit roundoff, and tests compare every other cell exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warp_lamp.grid import LampGrid
from warp_lamp.lamp import LAMPS, lamp_mask

__all__ = [
    "EPS32",
    "LampReference",
    "lamp_reference",
    "midpoint_sphere_offsets",
    "octant_volume",
    "porosity_reference",
    "sphere_box_volume",
]

#: Unit roundoff of float32.
EPS32 = 2.0**-24


@dataclass
class LampReference:
    """Reference answer. ``owners``, ``depths`` and ``ambiguous`` are per lamp name, indexed ``[i, j]``."""

    owners: dict
    depths: dict
    ambiguous: dict
    counts: np.ndarray


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


def lamp_reference(centers, radii, grid: LampGrid, *, criterion: int = 1, lamps="all", active=None) -> LampReference:
    """Owners, depths and signed counts of every lamp, in float64, by brute force over spheres and cells.

    Args:
        centers: Particle centres [m], shape (N, 3).
        radii: Particle radii [m], shape (N,).
        grid: The lamp grids.
        criterion: 1 (cell-centre ray) or 0 (cell rectangle meets the projected disk).
        lamps: "all" or names from :data:`warp_lamp.LAMPS`.
        active: Optional mask, shape (N,); inactive particles are left out.
    """
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    n = len(r)
    visible = np.ones(n, dtype=bool) if active is None else np.asarray(active) != 0
    local_c = c - grid.origin
    mask = lamp_mask(lamps)
    owners, depths, ambiguous = {}, {}, {}
    counts = np.zeros((n, 3), dtype=np.int64)
    for a in range(3):
        for side in range(2):
            name = LAMPS[2 * a + side]
            shape = tuple(int(x) for x in grid.counts[a])
            if not mask >> (2 * a + side) & 1:
                owners[name] = np.full(shape, -1)
                depths[name] = np.full(shape, np.nan)
                ambiguous[name] = np.zeros(shape, dtype=bool)
                continue
            own, dep, amb = _lamp_cells(local_c, r, visible, grid, a, criterion, side == 0)
            owners[name], depths[name], ambiguous[name] = own, dep, amb
            np.add.at(counts[:, a], own[own >= 0], 1 if side == 0 else -1)
    return LampReference(owners, depths, ambiguous, counts)


# --- porosity -----------------------------------------------------------------------------------------------


def _octant_f(y, a, c, r):
    r2 = r * r
    P, Q = r2 - a * a, r2 - c * c
    sP = np.sqrt(np.maximum(P - y * y, 0.0))
    sQ = np.sqrt(np.maximum(Q - y * y, 0.0))
    tP, tQ = np.arctan2(y, sP), np.arctan2(y, sQ)
    v = r2 * y - y**3 / 3.0
    acos_a = np.where(a > 0, np.arctan2(sP, a), np.pi / 2)
    asin_c = np.arctan2(c, sQ)
    kP = a / 3.0 * (0.5 * (P * tP - y * sP) - 2.0 * r2 * tP) + 2.0 / 3.0 * r2 * r * np.arctan2(a * y, r * sP)
    kQ = c / 3.0 * (0.5 * (Q * tQ - y * sQ) - 2.0 * r2 * tQ) + 2.0 / 3.0 * r2 * r * np.arctan2(c * y, r * sQ)
    i1, i2 = 0.5 * (y * sP + P * tP), 0.5 * (y * sQ + Q * tQ)
    return a * c * y - 0.5 * a * i1 - 0.5 * c * i2 + 0.5 * ((v * acos_a + kP) - (v * asin_c - kQ))


def octant_volume(a, b, c, r, dtype=np.float64):
    """Volume of {|p| <= r, x >= a, y >= b, z >= c}, a, b, c >= 0 (arrays broadcast).

    The integral over y of the area {x >= a, z >= c} of the disk at height y, done in closed form: inner
    integral over z, then integration by parts for the r^2 - y^2 weighted angle terms. Inverse trig as atan2.
    """
    a, b, c, r = np.broadcast_arrays(*(np.asarray(x, dtype=dtype) for x in (a, b, c, r)))
    top = np.sqrt(np.maximum(r * r - a * a - c * c, 0.0))
    inside = (a * a + b * b + c * c < r * r) & (b < top)
    return np.where(inside, _octant_f(top, a, c, r) - _octant_f(np.minimum(b, top), a, c, r), dtype(0.0))


def sphere_box_volume(lo, hi, r, dtype=np.float64):
    """Volume of the ball of radius r at the origin inside the box [lo, hi]; lo, hi shape (..., 3).

    Inclusion-exclusion over the box's 8 corners of the corner volumes {x >= a, y >= b, z >= c}; a negative
    bound is the whole axis (twice the half at 0, by symmetry) minus the mirrored positive bound.
    """
    r = np.asarray(r, dtype=dtype)
    lo = np.maximum(np.asarray(lo, dtype=dtype), -r[..., None])
    hi = np.minimum(np.asarray(hi, dtype=dtype), r[..., None])
    total = dtype(0.0)
    for corner in range(8):
        bounds = [hi[..., d] if corner >> d & 1 else lo[..., d] for d in range(3)]
        sign = -1.0 if bin(corner).count("1") % 2 else 1.0
        one, two, zero = dtype(1.0), dtype(2.0), dtype(0.0)
        terms = [
            [(np.where(x < 0, two, one), np.maximum(x, zero)), (np.where(x < 0, -one, zero), np.abs(x))] for x in bounds
        ]
        for fa, xa in terms[0]:
            for fb, xb in terms[1]:
                for fc, xc in terms[2]:
                    total = total + dtype(sign) * fa * fb * fc * octant_volume(xa, xb, xc, r, dtype)
    return np.where(np.all(hi > lo, axis=-1), total, dtype(0.0))


def midpoint_sphere_offsets(rad: int) -> np.ndarray:
    """Sub-cell offsets that the paper's Algorithm 1 (traversal sphere) marks for a sphere of radius ``rad``,
    as printed, with the fixes listed in :func:`warp_lamp.porosity`. Returns unique offsets, shape (M, 3)."""
    marked = set()

    def line(x, y, z):
        for i in range(x):  # as printed: the run stops one short of +-x, and x = 0 draws nothing
            marked.add((i, y, z))
            marked.add((-i, y, z))

    def disk(r, z):
        x, yr, p = 0, r, 1.25 - r
        while yr >= x:
            for zz in (z, -z):
                line(x, yr, zz)
                line(yr, x, zz)
                line(x, -yr, zz)
                line(yr, -x, zz)
            if p < 0:
                p += 2 * x + 3
            else:
                p += 2 * (x - yr) + 5
                yr -= 1
            x += 1

    z, yr, p = 0, rad, 1.25 - rad
    while yr >= z:
        disk(yr, z)
        disk(z, yr)
        if p < 0:
            p += 2 * z + 3
        else:
            p += 2 * (z - yr) + 5
            yr -= 1
        z += 1
    return np.array(sorted(marked), dtype=np.int64).reshape(-1, 3)


def porosity_reference(centers, radii, lower, upper, shape, *, method="voxel", subdivisions=8, midpoint_algorithm=None):
    """Porosity by brute force in float64, per method, as :func:`warp_lamp.porosity` defines it."""
    from warp_lamp.porosity import _midpoint_spheres, midpoint_choice

    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    lo = np.asarray(lower, dtype=np.float64)
    shape = tuple(int(x) for x in shape)
    h = (np.asarray(upper, dtype=np.float64) - lo) / np.asarray(shape)
    local = c - lo
    solid = np.zeros(shape)
    if method in ("centroid", "polyhedron", "exact"):
        for k in range(len(r)):
            if method == "centroid":
                idx = np.floor(local[k] / h).astype(int)
                if np.all((idx >= 0) & (idx < shape)):
                    solid[tuple(idx)] += 4.0 / 3.0 * np.pi * r[k] ** 3
                continue
            first = np.clip(np.floor((local[k] - r[k]) / h), 0, np.asarray(shape) - 1).astype(int)
            last = np.clip(np.floor((local[k] + r[k]) / h), 0, np.asarray(shape) - 1).astype(int)
            if np.any(local[k] + r[k] < 0) or np.any(local[k] - r[k] >= h * shape):
                continue
            grids = np.meshgrid(*(np.arange(first[d], last[d] + 1) for d in range(3)), indexing="ij")
            ijk = np.stack(grids, axis=-1)
            cell_lo = ijk * h - local[k]
            if method == "exact":
                v = sphere_box_volume(cell_lo, cell_lo + h, np.full(ijk.shape[:-1], r[k]))
            else:
                v = np.prod(np.maximum(np.minimum(cell_lo + h, r[k]) - np.maximum(cell_lo, -r[k]), 0.0), axis=-1)
            solid[first[0] : last[0] + 1, first[1] : last[1] + 1, first[2] : last[2] + 1] += v
        return 1.0 - solid / np.prod(h)
    s = int(subdivisions)
    sub = tuple(x * s for x in shape)
    hs = h / s
    occupied = np.zeros(sub, dtype=bool)
    if method == "voxel":
        axes = [(np.arange(sub[d]) + 0.5) * hs[d] for d in range(3)]
        for k in range(len(r)):
            sl = []
            for d in range(3):
                a = max(int(np.floor((local[k, d] - r[k]) / hs[d])) - 1, 0)
                b = min(int(np.floor((local[k, d] + r[k]) / hs[d])) + 1, sub[d] - 1)
                sl.append(slice(a, b + 1))
            if any(x.start > x.stop - 1 for x in sl):
                continue
            dx, dy, dz = (axes[d][sl[d]] - local[k, d] for d in range(3))
            d2 = dx[:, None, None] ** 2 + dy[None, :, None] ** 2 + dz[None, None, :] ** 2
            occupied[tuple(sl)] |= d2 <= r[k] ** 2
    else:
        mc, mr = _midpoint_spheres(local, r, hs)
        algorithm = midpoint_algorithm or midpoint_choice(mr, sub[0] * sub[1] * sub[2])
        if algorithm == 1:
            for k in range(len(mr)):
                pts = midpoint_sphere_offsets(int(mr[k])) + mc[k]
                ok = np.all((pts >= 0) & (pts < np.asarray(sub)), axis=1)
                occupied[tuple(pts[ok].T)] = True
        else:
            grid = np.stack(np.meshgrid(*(np.arange(n) for n in sub), indexing="ij"), axis=-1)
            for k in range(len(mr)):
                d = grid - mc[k]
                occupied |= np.einsum("...i,...i->...", d, d) - int(mr[k]) ** 2 < 0
    counts = occupied.reshape(shape[0], s, shape[1], s, shape[2], s).sum(axis=(1, 3, 5))
    return 1.0 - counts / float(s**3)
