"""Float64 NumPy/scipy reference of the wetted-surface mode (:mod:`warp_lamp.wetted`), voxel for voxel.

Written for clarity, with scipy's independent algorithms where they exist: ``ndimage.label`` for the
connectivity to the outside, ``ndimage.distance_transform_edt`` for the dilation by the probe, a k-d tree for
the nearest sphere. Each decision the kernels make is the same float64 expression here, so on inputs that
float32 holds exactly (frame coordinates and radii) the two agree bitwise. Where the kernels' float32 inputs
could tip a decision (a voxel centre within float32 rounding of a probe shell ``r + rho``, two spheres within
rounding of the same distance from a crossing), the reference flags it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warp_lamp.grid import LampGrid
from warp_lamp.validate import lamp_mask
from warp_lamp.wetted import attribution_bound, check_probe_radius, dilation_table, voxel_box

__all__ = ["WettedReference", "wetted_reference"]

#: Unit roundoff of float32.
EPS32 = 2.0**-24


@dataclass
class WettedReference:
    """Reference answer; voxel maps are indexed [x, y, z], per-axis items by lamp grid a = 0, 1, 2.

    Attributes:
        shape: Voxels per axis.
        h: Voxel edge per axis [m], shape (3,).
        allowed: Probe centre may stand at the voxel centre, bool (nx, ny, nz).
        allowed_ambiguous: Voxel centre within float32 input rounding of some sphere's shell r + rho.
        reachable: Allowed and 6-connected to the outside, bool (nx, ny, nz).
        fluid: Wetted voxels, bool (nx, ny, nz).
        dilation_near: Voxels whose distance to the reachable set is within 1e-9 of rho (decided by the offset
            table, which the kernels share; a float32 distance test could differ here).
        crossings: Per axis a, a dict of equal-length arrays: ``u``, ``v`` (the ray's lamp cell), ``face`` (index
            along a, 0..n_a, between voxels face-1 and face), ``enters`` (fluid to dry going +a), ``owner``
            (nearest sphere, -1 if none), ``distance`` (its |p - c| - r [m]), ``near_tie`` (a runner-up within
            float32 input rounding).
        ray_crossings: Per axis a, fluid-to-dry crossings per ray, shape (n_u, n_v).
        counts: Signed per-particle per-axis counts, (N, 3) int64 (lamps that are off left out).
        hits: Crossings attributed per particle, (N,) int64 (lamps that are off left out).
        bound: :func:`warp_lamp.wetted.attribution_bound` per axis [m].
        invalid: Active particles with a non-finite position or radius, or radius <= 0.
        outside: Valid active particles whose sphere pokes out of the box.
        tight: Valid active particles whose sphere inflated by rho reaches past the first layer of virtual voxel
            centres outside the box.
    """

    shape: tuple
    h: np.ndarray
    allowed: np.ndarray
    allowed_ambiguous: np.ndarray
    reachable: np.ndarray
    fluid: np.ndarray
    dilation_near: np.ndarray
    crossings: dict
    ray_crossings: dict
    counts: np.ndarray
    hits: np.ndarray
    bound: np.ndarray
    invalid: int
    outside: int
    tight: int


def _allowed(local, r, rho, n, h):
    """Blocked where ``(dx dx + dy dy) + dz dz < (r + rho)^2``, dx = (i + 1/2) hx - cx: the kernel's expression."""
    blocked = np.zeros(tuple(n), dtype=bool)
    near = np.zeros(tuple(n), dtype=bool)
    for k in range(len(r)):
        c = local[k]
        big = r[k] + rho
        big2 = big * big
        # Moving a float32-rounded input by its rounding moves |x - c| by at most this much.
        tol = 2.0 * EPS32 * (np.sqrt(3.0) * np.abs(c).max() + r[k]) + 1e-12 * big
        sl, d = [], []
        for a in range(3):
            lo = max(int(np.floor((c[a] - big - tol) / h[a] - 0.5)) - 1, 0)
            hi = min(int(np.ceil((c[a] + big + tol) / h[a] - 0.5)) + 1, int(n[a]) - 1)
            if lo > hi:
                break
            sl.append(slice(lo, hi + 1))
            d.append((np.arange(lo, hi + 1, dtype=np.float64) + 0.5) * h[a] - c[a])
        if len(sl) < 3:
            continue
        dx, dy, dz = d
        d2 = (dx[:, None, None] * dx[:, None, None] + dy[None, :, None] * dy[None, :, None]) + (
            dz[None, None, :] * dz[None, None, :]
        )
        blocked[tuple(sl)] |= d2 < big2
        near[tuple(sl)] |= np.abs(np.sqrt(d2) - big) <= tol
    return ~blocked, near


def _reachable(allowed):
    from scipy import ndimage

    padded = np.pad(allowed, 1, constant_values=True)  # the outside: allowed and connected all round
    labels, _ = ndimage.label(padded)  # default structure: 6-connectivity
    return (labels == labels[0, 0, 0])[1:-1, 1:-1, 1:-1]


def _offset_inside(off, h, rho):
    """The offset set's membership test of :func:`warp_lamp.wetted.dilation_table`, vectorised."""
    t = [off[..., a].astype(np.float64) * h[a] for a in range(3)]
    return ((t[0] * t[0] + t[1] * t[1]) + t[2] * t[2]) <= rho * rho


def _fluid(reachable, h, rho, table):
    """Voxels within rho of a reachable voxel or of the outside, by scipy's exact Euclidean distance transform.

    The EDT's nearest reachable voxel decides wherever its distance is clearly off rho; within 1e-9 of rho the
    offset set itself decides, by brute force over its offsets, so the answer is the table's, exactly.
    """
    from scipy import ndimage

    padded = np.pad(reachable, 1, constant_values=True)
    dist, idx = ndimage.distance_transform_edt(~padded, sampling=h, return_indices=True)
    dist = dist[1:-1, 1:-1, 1:-1]
    own = np.indices(padded.shape)[:, 1:-1, 1:-1, 1:-1]
    off = np.moveaxis(idx[:, 1:-1, 1:-1, 1:-1] - own, 0, -1)
    fluid = _offset_inside(off, h, rho)
    near = np.abs(dist - rho) <= 1e-9 * (rho + float(np.max(h)))
    if near.any():
        wy, wz = table.shape[0] - 1, table.shape[1] - 1
        wx = int(table.max())
        offs = np.stack(np.meshgrid(*(np.arange(-w, w + 1) for w in (wx, wy, wz)), indexing="ij"), axis=-1)
        offs = offs.reshape(-1, 3)
        offs = offs[_offset_inside(offs, h, rho)]
        big = np.pad(reachable, ((wx, wx), (wy, wy), (wz, wz)), constant_values=True)
        pts = np.argwhere(near)
        hit = np.zeros(len(pts), dtype=bool)
        for o in offs:
            q = pts + o + np.array([wx, wy, wz])
            hit |= big[q[:, 0], q[:, 1], q[:, 2]]
        fluid[near] = hit
    return fluid, near


def _nearest(points, cen, rad, ids, tol, chunk=100_000):
    """Per point: the sphere with the smallest |p - c| - r (ties to the lowest id), its distance, and whether a
    runner-up lies within tol. A k-d tree on centres gives candidates that provably include the winner."""
    from scipy.spatial import cKDTree

    m = len(points)
    owner = np.full(m, -1, dtype=np.int64)
    best = np.full(m, np.inf)
    tie = np.zeros(m, dtype=bool)
    if m == 0 or len(rad) == 0:
        return owner, best, tie
    tree = cKDTree(cen)
    for s in range(0, m, chunk):
        p = points[s : s + chunk]
        dc, ic = tree.query(p)
        # A sphere that can beat or tie the nearest centre's sphere has |p - c| <= dc - r_ic + r_max.
        radius = dc - rad[ic] + rad.max() + tol + 1e-12 * (1.0 + dc)
        lists = tree.query_ball_point(p, radius)
        sizes = np.array([len(x) for x in lists])
        cand = np.concatenate([np.asarray(x, dtype=np.int64) for x in lists])
        pt = np.repeat(np.arange(len(p)), sizes)
        dx = p[pt, 0] - cen[cand, 0]
        dy = p[pt, 1] - cen[cand, 1]
        dz = p[pt, 2] - cen[cand, 2]
        d = np.sqrt((dx * dx + dy * dy) + dz * dz) - rad[cand]
        order = np.lexsort((ids[cand], d, pt))
        first = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        win = order[first]
        owner[s : s + chunk] = ids[cand[win]]
        best[s : s + chunk] = d[win]
        second = np.full(len(p), np.inf)
        two = sizes > 1
        second[two] = d[order[first[two] + 1]]
        tie[s : s + chunk] = second - d[win] <= tol
    return owner, best, tie


def wetted_reference(
    centers, radii, grid: LampGrid, *, probe_radius: float, lamps="all", active=None, allowed=None
) -> WettedReference:
    """The wetted-surface mode in float64, by brute force over spheres and scipy over voxels.

    Args:
        centers: Particle centres [m], shape (N, 3) (global coordinates; ``grid.origin`` is subtracted).
            Non-finite rows are skipped and counted, like the kernels do.
        radii: Particle radii [m], shape (N,); radii <= 0 or non-finite are skipped and counted.
        grid: Box-form lamp grid.
        probe_radius: rho [m], >= 0.
        lamps: "all" or names from :data:`warp_lamp.LAMPS`.
        active: Optional mask, shape (N,); inactive particles are absent.
        allowed: Optional allowed map, bool (nx, ny, nz), to replace the reference's own (to check the
            kernels' later stages on the kernels' own allowed map).
    """
    n, h = voxel_box(grid)
    rho = check_probe_radius(probe_radius)
    mask = lamp_mask(lamps)
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    count = len(r)
    on = np.ones(count, dtype=bool) if active is None else np.asarray(active) != 0
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(c).all(axis=1) & np.isfinite(r) & (r > 0)
    visible = on & valid
    invalid = int((on & ~valid).sum())
    local = c[visible] - grid.origin
    rv = r[visible]
    ids = np.flatnonzero(visible)
    size = n * h
    outside = int(np.any((local - rv[:, None] < 0) | (local + rv[:, None] > size), axis=1).sum())
    big = rv[:, None] + rho
    tight = int(np.any((local - big < -0.5 * h) | (local + big > size + 0.5 * h), axis=1).sum())

    own_allowed, allowed_near = _allowed(local, rv, rho, n, h)
    if allowed is None:
        allowed = own_allowed
    else:
        allowed = np.asarray(allowed, dtype=bool)
        if allowed.shape != tuple(n):
            raise ValueError(f"allowed: expected shape {tuple(n)}, got {allowed.shape}")
    reachable = _reachable(allowed)
    table = dilation_table(h, rho)
    fluid, dilation_near = _fluid(reachable, h, rho, table)

    tol = 4.0 * EPS32 * ((float(np.abs(local).max()) if len(local) else 0.0) + (float(rv.max()) if len(rv) else 0.0))
    crossings, ray_crossings = {}, {}
    counts = np.zeros((count, 3), dtype=np.int64)
    hits = np.zeros(count, dtype=np.int64)
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        f = np.pad(np.transpose(fluid, (u, v, a)), ((0, 0), (0, 0), (1, 1)), constant_values=True)
        before, after = f[..., :-1], f[..., 1:]
        iu, iv, face = np.nonzero(before != after)
        enters = ~after[iu, iv, face]
        pts = np.empty((len(face), 3))
        pts[:, a] = face * h[a]
        pts[:, u] = (iu + 0.5) * h[u]
        pts[:, v] = (iv + 0.5) * h[v]
        owner, dist, tie = _nearest(pts, local, rv, ids, tol)
        crossings[a] = dict(u=iu, v=iv, face=face, enters=enters, owner=owner, distance=dist, near_tie=tie)
        rc = np.zeros((int(n[u]), int(n[v])), dtype=np.int64)
        np.add.at(rc, (iu[enters], iv[enters]), 1)
        ray_crossings[a] = rc
        for side, sel, sign in ((0, enters, 1), (1, ~enters, -1)):
            if not (mask >> (2 * a + side)) & 1:
                continue
            got = sel & (owner >= 0)
            np.add.at(counts[:, a], owner[got], sign)
            np.add.at(hits, owner[got], 1)
    bound = np.array([attribution_bound(h[a], rho) for a in range(3)])
    return WettedReference(
        shape=tuple(int(x) for x in n),
        h=h,
        allowed=allowed,
        allowed_ambiguous=allowed_near,
        reachable=reachable,
        fluid=fluid,
        dilation_near=dilation_near,
        crossings=crossings,
        ray_crossings=ray_crossings,
        counts=counts,
        hits=hits,
        bound=bound,
        invalid=invalid,
        outside=outside,
        tight=tight,
    )
