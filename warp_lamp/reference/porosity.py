"""Float64 references of the porosity methods, written for clarity rather than speed."""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "PAPER_TABLE_1",
    "midpoint_sphere_offsets",
    "midpoint_spheres",
    "octant_volume",
    "porosity_reference",
    "sphere_box_volume",
]

#: Table 1 of Zhang et al. (2024): sub-cells their Algorithm 1 marks for radius 1 ... 25.
PAPER_TABLE_1 = [
    1, 35, 93, 223, 529, 819, 1405, 1987, 2845, 4175, 5425, 7111, 8985,
    11267, 13793, 16595, 20165, 24115, 28461, 32943, 37969, 43823, 50537, 57115, 64025,
]  # fmt: skip


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


def midpoint_sphere_offsets(rad: int, *, line_ends: bool = False) -> np.ndarray:
    """Sub-cell offsets that the paper's Algorithm 1 (traversal sphere) marks for a sphere of radius ``rad``,
    as printed, with the fixes listed in :func:`warp_lamp.porosity`. Returns unique offsets, shape (M, 3).

    ``line_ends=True`` draws each run -x ... x inclusive: the counterfactual the README quotes (what the paper's
    ``range(x)`` would mark with its ends included); the library never uses it."""
    marked = set()
    stop = 1 if line_ends else 0

    def line(x, y, z):
        for i in range(x + stop):  # as printed (stop 0): the run stops one short of +-x, and x = 0 draws nothing
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


def midpoint_spheres(local, radii, hs):
    """The midpoint method's inputs, written independently of ``warp_lamp.porosity``: each centre goes to the
    sub-cell that holds it (floor), each radius to the nearest whole number of sub-cells of the smallest sub-cell
    edge (ties to even, as Python's ``round``), at least 1."""
    h = min(float(x) for x in hs)
    centers = np.array([[math.floor(float(x) / float(s)) for x, s in zip(p, hs, strict=True)] for p in local])
    rad = np.array([max(round(float(r) / h), 1) for r in radii])
    return centers.reshape(-1, 3).astype(np.int64), rad.astype(np.int64)


def _midpoint_algorithm(rad, n_subcells: int) -> int:
    """The paper's section 2.3 choice: Algorithm 2 when the spheres' total sub-cell volume, sum 4/3 pi r^3,
    exceeds K (2R)^3, the work of searching a cube of side 2R around each of the K sub-cells; else Algorithm 1."""
    if len(rad) == 0:
        return 1
    work_1 = sum(4.0 / 3.0 * math.pi * float(r) ** 3 for r in rad)
    work_2 = n_subcells * (2.0 * float(max(rad))) ** 3
    return 2 if work_1 > work_2 else 1


def _reference_subdivisions(h, subdivisions, method) -> tuple[int, int, int]:
    """Sub-cells per cell edge along x, y, z. Midpoint with one integer s: s along the shortest cell edge and
    sub-cells of that edge on the others (they must fit whole, as :func:`warp_lamp.porosity` requires)."""
    if np.ndim(subdivisions):
        return tuple(int(x) for x in subdivisions)
    s = int(subdivisions)
    if method != "midpoint":
        return (s, s, s)
    edge = min(float(x) for x in h) / s
    return tuple(round(float(x) / edge) for x in h)


def porosity_reference(centers, radii, lower, upper, shape, *, method="voxel", subdivisions=8, midpoint_algorithm=None):
    """Porosity by brute force in float64, per method, as :func:`warp_lamp.porosity` defines it."""
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
    s = _reference_subdivisions(h, subdivisions, method)
    sub = tuple(x * k for x, k in zip(shape, s, strict=True))
    hs = h / np.asarray(s)
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
        mc, mr = midpoint_spheres(local, r, hs)
        algorithm = midpoint_algorithm or _midpoint_algorithm(mr, sub[0] * sub[1] * sub[2])
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
    counts = occupied.reshape(shape[0], s[0], shape[1], s[1], shape[2], s[2]).sum(axis=(1, 3, 5))
    return 1.0 - counts / float(s[0] * s[1] * s[2])
