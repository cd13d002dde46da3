"""Float64 NumPy references for the lamp's visible-area criterion (issue 15), written for clarity and robustness.

Two layers:

- :func:`visible_disk_areas`, the planar core: the area of each of a list of disks, ordered front to back, that
  is visible inside an axis-aligned rectangle (not covered by an earlier disk). Exact: Green's theorem,
  ``A = 1/2 \\oint (x dy - y dx)``, over circle arcs and rectangle edges in closed form.
- :func:`visible_area_reference`: the exact visible projected area of every sphere from each of the six lamps,
  by tiling each lamp's plane and running the planar core per tile on the spheres that reach it.

How the planar core stays robust to tangent, coincident and nearly tangent circles: it never intersects two
circles to find a vertex. Every boundary point is attributed, not clipped: a point of circle j (inside the
rectangle) belongs to the boundary of disk j's visible region when no disk before j covers it, and then also,
reversed, to the region of the *first* disk after j that covers it. A point of a rectangle edge belongs to the
first disk that covers it. Which disks cover a point of circle j is an angular interval per other disk,
``|angle - phi_i| <= alpha_i`` with ``cos(alpha_i) = (d^2 + (r_j - r_i)(r_j + r_i)) / (2 d r_j)`` clamped to
[-1, 1]: as two circles approach tangency (external or internal) alpha goes continuously to 0 or pi, so no
decision jumps. The circle is cut at every interval end, and each elementary arc is classified by its midpoint
against the same intervals (the same numbers that made the cuts), so a rounding error can only misclassify an
arc whose length is of the order of that error. The one discontinuity, two identical circles (d = 0, equal
radii), is decided by rule: the earlier disk covers the later one's circle and not the reverse, which is also the
limit of two circles a vanishing distance apart. The per-disk areas therefore sum to the area of the union of the
disks inside the rectangle (the same boundary pieces, added), which the tests check independently.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from warp_lamp.validate import LAMPS, lamp_mask

__all__ = [
    "COVERED_TOL",
    "EXACT_UNIT",
    "MAX_SEEDS",
    "AreaEstimate",
    "area_depth_slots",
    "area_estimate_reference",
    "ordered_key",
    "visible_area_reference",
    "visible_disk_areas",
]

#: A tile whose visible areas add up to within this fraction of its area counts as covered: the disks behind it
#: are not visited, so each is off by at most this fraction of a tile.
COVERED_TOL = 1e-12

_TWO_PI = 2.0 * np.pi


def _first_true(mask: np.ndarray, none: int) -> np.ndarray:
    """Index of the first True along the last axis, or ``none`` where there is none."""
    return np.where(mask.any(axis=-1), mask.argmax(axis=-1), none)


def _arc_pieces(xc, yc, r, j, hw, hh):
    """Circle j of every batch row cut into elementary arcs, each with its integral and classification.

    Returns (integral, first, outside): shapes (B, M); ``first`` is the first disk (lowest list index, j
    excluded) whose disk covers the arc, K where none does; ``outside`` marks arcs outside the rectangle.
    """
    B, K = r.shape
    rj = r[:, j]
    ok_j = rj > 0
    rj_s = np.where(ok_j, rj, 1.0)
    xj, yj = xc[:, j], yc[:, j]
    dx = xc - xj[:, None]
    dy = yc - yj[:, None]
    d = np.hypot(dx, dy)
    with np.errstate(divide="ignore", invalid="ignore"):
        # (r_j - r_i)(r_j + r_i) instead of r_j^2 - r_i^2: exact cancellation for equal radii.
        cos_a = (d * d + (rj_s[:, None] - r) * (rj_s[:, None] + r)) / (2.0 * d * rj_s[:, None])
    alpha = np.arccos(np.clip(np.nan_to_num(cos_a, nan=1.0), -1.0, 1.0))
    phi = np.arctan2(dy, dx)
    idx = np.arange(K)[None, :]
    same_centre = d == 0.0
    full = same_centre & ((r > rj_s[:, None]) | ((r == rj_s[:, None]) & (idx < j)))
    alpha = np.where(same_centre, np.where(full, np.pi, -1.0), alpha)
    alpha = np.where((r > 0) & (idx != j), alpha, -1.0)  # padding and the circle itself cover nothing
    # Outside the rectangle: left of x = -hw is |angle - pi| < acos((x_j + hw) / r_j), and so on.
    ex_phi = np.broadcast_to(np.array([np.pi, 0.0, -0.5 * np.pi, 0.5 * np.pi]), (B, 4))
    ex_alpha = np.arccos(np.clip(np.stack([xj + hw, hw - xj, yj + hh, hh - yj], axis=1) / rj_s[:, None], -1.0, 1.0))
    c_phi = np.concatenate([phi, ex_phi], axis=1)
    c_alpha = np.concatenate([alpha, ex_alpha], axis=1)
    partial = (c_alpha > 0.0) & (c_alpha < np.pi)
    ends = np.concatenate([c_phi - c_alpha, c_phi + c_alpha], axis=1) % _TWO_PI
    ends = np.where(np.concatenate([partial, partial], axis=1), ends, _TWO_PI)
    cuts = np.sort(np.concatenate([np.zeros((B, 1)), ends, np.full((B, 1), _TWO_PI)], axis=1), axis=1)
    t1, t2 = cuts[:, :-1], cuts[:, 1:]
    mid = 0.5 * (t1 + t2)
    off = (mid[:, :, None] - c_phi[:, None, :] + np.pi) % _TWO_PI - np.pi
    # alpha <= 0 covers nothing and alpha >= pi everything, whatever the midpoint's rounding.
    a3 = c_alpha[:, None, :]
    inside = (a3 >= np.pi) | ((a3 > 0.0) & (np.abs(off) <= a3))
    outside = inside[:, :, K:].any(axis=2) | ~ok_j[:, None]
    first = _first_true(inside[:, :, :K], K)
    r1 = rj_s[:, None]
    integral = 0.5 * (
        r1 * r1 * (t2 - t1)
        + xj[:, None] * r1 * (np.sin(t2) - np.sin(t1))
        - yj[:, None] * r1 * (np.cos(t2) - np.cos(t1))
    )
    return integral, first, outside


def _edge_pieces(par, perp, r, line, half_len):
    """One rectangle edge (the line ``perp = line``, ``|par| <= half_len``) cut at every chord end.

    Returns (length, first): shapes (B, M); ``first`` is the first disk whose chord holds the piece, K if none.
    """
    K = r.shape[1]
    s2 = r * r - (perp - line[:, None]) ** 2
    has = (s2 > 0.0) & (r > 0)
    s = np.sqrt(np.where(has, s2, 0.0))
    lo = np.where(has, par - s, np.inf)
    hi = np.where(has, par + s, -np.inf)
    h = half_len[:, None]
    cuts = np.concatenate([-h, np.clip(lo, -h, h), np.clip(hi, -h, h), h], axis=1)
    cuts = np.sort(np.where(np.isfinite(cuts), cuts, np.broadcast_to(h, cuts.shape)), axis=1)
    t1, t2 = cuts[:, :-1], cuts[:, 1:]
    mid = 0.5 * (t1 + t2)
    inside = (mid[:, :, None] >= lo[:, None, :]) & (mid[:, :, None] <= hi[:, None, :])
    return t2 - t1, _first_true(inside, K)


def _visible_batch(x, y, r, w, h) -> np.ndarray:
    """Visible areas of B independent problems: disks (B, K) front to back in rectangles [0, w_b] x [0, h_b].

    Args:
        x, y: Disk centres relative to each rectangle's lower-left corner [m], shape (B, K), float64.
        r: Radii [m], shape (B, K); r <= 0 marks padding (no disk).
        w, h: Rectangle sizes [m], shape (B,).

    Returns:
        Visible area of each disk [m^2], shape (B, K), float64.
    """
    x, y, r = (np.asarray(a, dtype=np.float64) for a in (x, y, r))
    B, K = r.shape
    hw = 0.5 * np.broadcast_to(np.asarray(w, dtype=np.float64), (B,))
    hh = 0.5 * np.broadcast_to(np.asarray(h, dtype=np.float64), (B,))
    # Green's theorem about the rectangle's centre keeps every term of the order of the rectangle.
    xc = x - hw[:, None]
    yc = y - hh[:, None]
    r = np.where(r > 0, r, 0.0)
    area = np.zeros((B, K))
    rows = np.arange(B)[:, None]
    for j in range(K):
        if not (r[:, j] > 0).any():
            continue
        integral, first, outside = _arc_pieces(xc, yc, r, j, hw, hh)
        keep = ~outside & (first > j)
        area[:, j] += np.where(keep, integral, 0.0).sum(axis=1)
        later = keep & (first < K)
        np.add.at(area, (np.broadcast_to(rows, first.shape)[later], first[later]), -integral[later])
    # Counter-clockwise, every edge piece contributes 1/2 (distance of its line from the centre) x length.
    for par, perp, line, half_len, weight in (
        (yc, xc, -hw, hh, hw),  # left edge, downward
        (yc, xc, hw, hh, hw),  # right edge, upward
        (xc, yc, -hh, hw, hh),  # bottom edge, rightward
        (xc, yc, hh, hw, hh),  # top edge, leftward
    ):
        length, first = _edge_pieces(par, perp, r, line, half_len)
        hit = first < K
        contrib = 0.5 * weight[:, None] * length
        np.add.at(area, (np.broadcast_to(rows, first.shape)[hit], first[hit]), contrib[hit])
    return area


def visible_disk_areas(centers, radii, rect) -> np.ndarray:
    """Area of each disk, ordered front to back, that is visible inside an axis-aligned rectangle.

    A point of the rectangle belongs to the first disk (in list order) whose closed disk holds it. Exact up to
    float64 rounding, including for tangent, coincident and nearly tangent circles (module docstring); two
    identical disks: the earlier one takes the area. The areas sum to the area of the union of the disks
    inside the rectangle.

    Args:
        centers: Disk centres [m], shape (K, 2), front disk first.
        radii: Disk radii [m], shape (K,), > 0.
        rect: The rectangle (x0, y0, x1, y1) [m], x0 < x1, y0 < y1.

    Returns:
        Visible area of each disk inside the rectangle [m^2], shape (K,), float64.
    """
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    if r.shape[0] != c.shape[0]:
        raise ValueError(f"radii: expected shape ({c.shape[0]},) to match centers, got {r.shape}")
    bad = ~(np.isfinite(r) & (r > 0)) | ~np.isfinite(c).all(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"centers/radii: disk {k} is not finite with radius > 0: {c[k].tolist()}, {r[k]!r}")
    x0, y0, x1, y1 = (float(v) for v in rect)
    if not (np.isfinite([x0, y0, x1, y1]).all() and x1 > x0 and y1 > y0):
        raise ValueError(f"rect: expected finite (x0, y0, x1, y1) with x0 < x1 and y0 < y1, got {tuple(rect)!r}")
    if r.shape[0] == 0:
        return np.zeros(0)
    out = _visible_batch(c[None, :, 0] - x0, c[None, :, 1] - y0, r[None, :], np.array([x1 - x0]), np.array([y1 - y0]))
    return out[0]


def _check_scene(centers, radii, active):
    c = np.asarray(centers, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 3:
        raise ValueError(f"centers: expected shape (N, 3), got {c.shape}")
    r = np.asarray(radii, dtype=np.float64)
    if r.ndim == 0:
        r = np.full(c.shape[0], float(r))
    if r.shape != (c.shape[0],):
        raise ValueError(f"radii: expected shape ({c.shape[0]},) to match centers, got {r.shape}")
    if c.shape[0] and not np.isfinite(c).all():
        k = int(np.flatnonzero(~np.isfinite(c).all(axis=1))[0])
        raise ValueError(f"centers: non-finite value at index {k}: {c[k].tolist()}")
    if r.shape[0] and not (np.isfinite(r) & (r > 0)).all():
        k = int(np.flatnonzero(~(np.isfinite(r) & (r > 0)))[0])
        raise ValueError(f"radii: must be finite and > 0; index {k} is {r[k]!r}")
    on = np.ones(c.shape[0], dtype=bool)
    if active is not None:
        act = np.asarray(active)
        if act.shape != (c.shape[0],):
            raise ValueError(f"active: expected shape ({c.shape[0]},), got {act.shape}")
        on = act != 0
    return c, r, on


def _grouped(tile, order_keys):
    """Sort (tile, candidate) pairs by tile then by the order keys; return the order and each pair's rank."""
    order = np.lexsort((*order_keys[::-1], tile))
    t = tile[order]
    start = np.flatnonzero(np.r_[True, t[1:] != t[:-1]])
    size = np.diff(np.r_[start, len(t)])
    rank = np.arange(len(t)) - np.repeat(start, size)
    return order, t, rank, start, size


def _tile_areas(pu, pv, r, ids, tile_ids, tile_x0, tile_y0, t, order_keys, n_out):
    """Exact visible area per sphere, summed over tiles; candidates per tile ordered by ``order_keys``."""
    out = np.zeros(n_out)
    order, tsorted, rank, start, size = _grouped(tile_ids, order_keys)
    tiles = tsorted[start]
    todo = np.ones(len(start), dtype=bool)
    k_max = 8
    while todo.any():
        g = np.flatnonzero(todo)
        k = min(k_max, int(size[g].max()))
        B = len(g)
        # Gather the first k candidates of each tile to be done.
        take = np.minimum(size[g], k)
        pos = np.repeat(start[g], take) + (np.arange(take.sum()) - np.repeat(np.cumsum(take) - take, take))
        row = np.repeat(np.arange(B), take)
        col = rank[pos]
        src = order[pos]
        x = np.zeros((B, k))
        y = np.zeros((B, k))
        rr = np.zeros((B, k))
        who = np.full((B, k), -1)
        tt = tiles[g]
        x[row, col] = pu[src] - tile_x0[tt[row]]
        y[row, col] = pv[src] - tile_y0[tt[row]]
        rr[row, col] = r[src]
        who[row, col] = ids[src]
        areas = _visible_batch(x, y, rr, np.full(B, t), np.full(B, t))
        covered = areas.sum(axis=1) >= (1.0 - COVERED_TOL) * t * t
        done = covered | (size[g] <= k)
        m = done[:, None] & (who >= 0)
        np.add.at(out, who[m], areas[m])
        todo[g[done]] = False
        k_max *= 2
    return out


def visible_area_reference(centers, radii, *, lamps="all", active=None) -> np.ndarray:
    """Exact visible projected area of every sphere from each of the six lamps, in float64.

    Lamp ``"-x"`` sits at minus infinity on x and looks toward +x (:data:`warp_lamp.LAMPS` order). The area
    a lamp sees of a sphere is the part of its projected disk not covered by the disk of a sphere in front.
    No lamp grid is involved: each lamp's plane is cut into square tiles of the smallest radius internally,
    and each tile runs :func:`visible_disk_areas` on the disks that reach it, front to back, until the tile is
    covered to within :data:`COVERED_TOL` of its area.

    Front to back means by centre depth (ties to the lower index). For disjoint spheres that is the true
    visibility order: along any ray through two disjoint spheres their chords are disjoint, and each chord's
    midpoint is the sphere's centre depth, so the earlier chord has the smaller centre depth. The result is
    then exact (to float64 rounding and the coverage tolerance). For overlapping spheres (DEM contacts) it is
    the convention, not the geometry: inside the lens where two projected disks overlap, the whole lens goes
    to the sphere whose centre is nearer the lamp, although near the lens edge the other sphere's surface may
    be the first one a ray meets. The error is of the order of the overlap area, tiny at DEM overlaps.

    Args:
        centers: Particle centres [m], shape (N, 3).
        radii: Particle radii [m], shape (N,), or one number for all.
        lamps: "all" or names from :data:`warp_lamp.LAMPS`; the columns of lamps that are off are zero.
        active: Optional mask, shape (N,): inactive spheres are absent (no shadow, zero area).

    Returns:
        Visible area [m^2], shape (N, 6), float64, columns in :data:`warp_lamp.LAMPS` order.
    """
    c, r, on = _check_scene(centers, radii, active)
    mask = lamp_mask(lamps)
    n = c.shape[0]
    out = np.zeros((n, 6))
    ids = np.flatnonzero(on)
    if len(ids) == 0 or mask == 0:
        return out
    t = float(r[ids].min())
    for a in range(3):
        sides = [s for s in range(2) if mask >> (2 * a + s) & 1]
        if not sides:
            continue
        u, v = (a + 1) % 3, (a + 2) % 3
        pu, pv, pd, rr = c[ids, u], c[ids, v], c[ids, a], r[ids]
        u0, v0 = float((pu - rr).min()), float((pv - rr).min())
        i0 = np.floor((pu - rr - u0) / t).astype(np.int64)
        i1 = np.floor((pu + rr - u0) / t).astype(np.int64)
        j0 = np.floor((pv - rr - v0) / t).astype(np.int64)
        j1 = np.floor((pv + rr - v0) / t).astype(np.int64)
        nu = int(i1.max()) + 1
        ni, nj = i1 - i0 + 1, j1 - j0 + 1
        cnt = ni * nj
        sph = np.repeat(np.arange(len(ids)), cnt)
        local = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        ti = i0[sph] + local % ni[sph]
        tj = j0[sph] + local // ni[sph]
        # Keep the pairs whose disk meets the tile's interior.
        gx = np.maximum(np.maximum(u0 + ti * t - pu[sph], pu[sph] - (u0 + (ti + 1) * t)), 0.0)
        gy = np.maximum(np.maximum(v0 + tj * t - pv[sph], pv[sph] - (v0 + (tj + 1) * t)), 0.0)
        meet = gx * gx + gy * gy < rr[sph] ** 2
        sph, ti, tj = sph[meet], ti[meet], tj[meet]
        tile = tj * nu + ti
        n_tiles = int(tile.max()) + 1
        tile_x0 = u0 + (np.arange(n_tiles) % nu) * t
        tile_y0 = v0 + (np.arange(n_tiles) // nu) * t
        for s in sides:
            depth = pd[sph] if s == 0 else -pd[sph]
            res = _tile_areas(pu[sph], pv[sph], rr[sph], ids[sph], tile, tile_x0, tile_y0, t, (depth, ids[sph]), n)
            out[:, 2 * a + s] = res
    return out


# --- the estimator (issue 15): D-slot depth pass, per-cell gather, resolve, balance -----------------------------

#: Fixed-point units per cell of the exact resolver. 2^12 keeps the rounding (at most one unit per cell and lamp)
#: below 2.5e-4 of a cell, far under the estimator's own error, while a particle needs 32,768 cells per axis
#: before its units reach 2^27, where P A / UNIT times units stops being exact in float64.
EXACT_UNIT = 4096

#: Most seeds a cell keeps per lamp (the frontmost by centre depth); more is counted as overflow.
MAX_SEEDS = 16

_EMPTY = np.uint64(0xFFFFFFFFFFFFFFFF)
_LOW32 = np.uint64(0xFFFFFFFF)


def ordered_key(depth, ids) -> np.ndarray:
    """Pack float32 depths and particle ids as the kernels' ``pack_key`` does: uint64, ordered by depth, then id.

    Args:
        depth: Depths, shape (M,), converted to float32 first.
        ids: Particle indices, shape (M,), 0 <= id < 2^32.
    """
    b = np.asarray(depth, dtype=np.float32).view(np.uint32).copy()
    b[b == np.uint32(0x80000000)] = 0  # -0 and +0 alike
    neg = (b & np.uint32(0x80000000)) != 0
    b = np.where(neg, ~b, b | np.uint32(0x80000000)).astype(np.uint64)
    return (b << np.uint64(32)) | np.asarray(ids, dtype=np.int64).astype(np.uint64)


def _f32(x):
    return np.asarray(x, dtype=np.float32)


def _frame(centers, radii, grid, on):
    """Float32 frame positions and radii as :func:`warp_lamp.lamp_forces` hands them to the kernels, and the
    float32 grid parameters: (q (N, 3), r (N,), per-axis (corner_u, corner_v, h_u, h_v, n_u, n_v))."""
    q = (centers - np.asarray(grid.origin, dtype=np.float64)).astype(np.float32)
    r = radii.astype(np.float32)
    axes = []
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        cu = np.float32(grid.corner[a, 0] - grid.origin[u])
        cv = np.float32(grid.corner[a, 1] - grid.origin[v])
        axes.append((cu, cv, np.float32(grid.cell[a, 0]), np.float32(grid.cell[a, 1]), *map(int, grid.counts[a])))
    return q, r, axes


def _sample_hits(pu, pv, r, hu, hv, nu, nv):
    """Every (particle, sample) pair whose sample ray meets the sphere, with the reach ``s`` along the ray.

    Float32 arithmetic exactly as the depth pass: ``du = f32(i) * h_u - p_u``, ``dv = f32(j) * h_v - p_v``,
    ``rem = r * r - dv * dv``, hit when ``rem >= 0`` and ``du * du <= rem``, ``s = sqrt(rem - du * du)``.
    """
    # Index ranges padded by one sample on each side; the float32 test decides.
    i0 = np.clip(np.floor((pu - r) / hu) - 1, 0, nu).astype(np.int64)
    i1 = np.clip(np.floor((pu + r) / hu) + 1, -1, nu).astype(np.int64)
    j0 = np.clip(np.floor((pv - r) / hv) - 1, 0, nv).astype(np.int64)
    j1 = np.clip(np.floor((pv + r) / hv) + 1, -1, nv).astype(np.int64)
    ni = np.maximum(i1 - i0 + 1, 0)
    nj = np.maximum(j1 - j0 + 1, 0)
    cnt = ni * nj
    pid = np.repeat(np.arange(len(r)), cnt)
    local = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    i = i0[pid] + local % np.maximum(ni[pid], 1)
    j = j0[pid] + local // np.maximum(ni[pid], 1)
    du = i.astype(np.float32) * hu - pu[pid]
    dv = j.astype(np.float32) * hv - pv[pid]
    rem = r[pid] * r[pid] - dv * dv
    hit = (rem >= 0) & (du * du <= rem)
    s = np.sqrt(np.where(hit, rem - du * du, np.float32(0)))
    return pid[hit], (j * (nu + 1) + i)[hit], s[hit]


def area_depth_slots(centers, radii, grid, *, depth_slots=3, lamps="all", active=None):
    """The D-slot depth pass in NumPy: per sample ray (cell corner) and lamp, the D smallest (depth, id) keys.

    Sample (i, j), 0 <= i <= n_u, 0 <= j <= n_v, of grid a sits at ``(f32(i) h_u, f32(j) h_v)`` from the grid
    corner; its low lamp keys ``pack(p_a - s, id)`` (entry depth), its high lamp ``pack(-(p_a + s), id)``
    (negated exit depth), in float32 as :func:`_sample_hits` says, positions being ``f32(centers - origin)``
    (float64 subtraction first, as :func:`warp_lamp.lamp_forces` does). Ties go to the lowest id (the packing).

    Returns:
        (keys, offsets): uint64 keys in the kernel layout, sample s of grid a holding
        ``keys[(2 * (offsets[a] + s) + side) * D + k]``, k ascending, EMPTY (2^64 - 1) where fewer than D
        spheres meet the ray, s = j (n_u + 1) + i; and the first sample of each grid, shape (3,).
    """
    c, r64, on = _check_scene(centers, radii, active)
    mask = lamp_mask(lamps)
    d = int(depth_slots)
    if d < 1:
        raise ValueError(f"depth_slots: must be >= 1, got {depth_slots!r}")
    q, r, axes = _frame(c, r64, grid, on)
    sizes = [(ax[4] + 1) * (ax[5] + 1) for ax in axes]
    offsets = np.concatenate([[0], np.cumsum(sizes)[:2]]).astype(np.int64)
    keys = np.full(2 * d * int(sum(sizes)), _EMPTY, dtype=np.uint64)
    ids = np.flatnonzero(on)
    for a, (cu, cv, hu, hv, nu, nv) in enumerate(axes):
        u, v = (a + 1) % 3, (a + 2) % 3
        pu = q[ids, u] - cu
        pv = q[ids, v] - cv
        pd = q[ids, a]
        pid, sample, s = _sample_hits(pu, pv, r[ids], hu, hv, nu, nv)
        for side in range(2):
            if not mask >> (2 * a + side) & 1:
                continue
            depth = pd[pid] - s if side == 0 else -(pd[pid] + s)
            k = ordered_key(depth, ids[pid])
            order = np.lexsort((k, sample))
            ss, kk = sample[order], k[order]
            start = np.flatnonzero(np.r_[True, ss[1:] != ss[:-1]])
            rank = np.arange(len(ss)) - np.repeat(start, np.diff(np.r_[start, len(ss)]))
            keep = rank < d
            slot = (2 * (offsets[a] + ss[keep]) + side) * d + rank[keep]
            keys[slot] = kk[keep]
    return keys, offsets


#: The 8 ring samples of cell (i, j), as offsets from (i, j): across each edge, the two samples facing its ends.
RING = ((-1, 0), (-1, 1), (2, 0), (2, 1), (0, -1), (1, -1), (0, 2), (1, 2))
#: The 4 corner samples of cell (i, j).
CORNERS = ((0, 0), (1, 0), (0, 1), (1, 1))


@dataclass
class AreaEstimate:
    """What :func:`area_estimate_reference` computed.

    Attributes:
        units: Signed fixed-point units per particle and axis, shape (N, 3), int64: + from the low lamp, - from
            the high lamp; a particle's force on axis a is ``P_a A_a units / unit``.
        unit: Units per whole cell (S^2 for the sub-point resolver, :data:`EXACT_UNIT` for the exact one).
        cells: Per lamp name, per-cell details when asked for (``details=True``), else empty: a dict with
            ``cell`` (flat cell index within the grid, j n_u + i, shape (M,)), ``seeds`` (particle ids front to
            back, -1 padded, (M, K)), ``share`` (each seed's visible share in units, float64, (M, K)),
            ``units`` (the units it receives, int64, (M, K)), ``total`` (the lamp's rounded total, (M,)).
        stats: Counters for the cost model and diagnostics: ``sample_hits`` (sphere-sample pairs), ``cells``
            (cells with at least one seed, per lamp), ``seeds`` (seeds resolved, summed over those cells),
            ``seeds_gathered`` (before the cull), ``max_seeds`` (most gathered in one cell), ``overflow``
            (cells that had more than ``max_seeds`` seeds), ``one_sided`` (cells dropped because one lamp had
            units to give and the other no seed to give them to), ``candidates`` (keys read).
    """

    units: np.ndarray
    unit: int
    cells: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)


def _gather(keys, offsets, a, d, nu, nv, side, ring_slots):
    """Candidate keys of every cell of grid a: the D slots of its 4 corners, the first ``ring_slots`` slots of
    its 8 ring samples (EMPTY off the grid). Shape (nu * nv, 4 D + 8 ring_slots)."""
    ii, jj = np.meshgrid(np.arange(nu), np.arange(nv), indexing="xy")
    ii, jj = ii.ravel(), jj.ravel()
    cols = []
    for (di, dj), depth in [(c, d) for c in CORNERS] + [(c, ring_slots) for c in RING]:
        si, sj = ii + di, jj + dj
        inside = (si >= 0) & (si <= nu) & (sj >= 0) & (sj <= nv)
        sample = offsets[a] + np.where(inside, sj * (nu + 1) + si, 0)
        for k in range(depth):
            cols.append(np.where(inside, keys[(2 * sample + side) * d + k], _EMPTY))
    return np.stack(cols, axis=1)


def _seeds(cand, q, r, a, cu, cv, hu, hv, nu, side, max_seeds):
    """Dedupe, drop disks that miss the cell, order front to back by centre depth (ties to the lowest id),
    keep the first ``max_seeds``. Returns (seed ids (C, K) -1 padded, count before truncation (C,))."""
    u, v = (a + 1) % 3, (a + 2) % 3
    C = cand.shape[0]
    owner = np.where(cand == _EMPTY, -1, (cand & _LOW32).astype(np.int64))
    owner = np.sort(owner, axis=1)
    owner[:, 1:] = np.where(owner[:, 1:] == owner[:, :-1], -1, owner[:, 1:])
    valid = owner >= 0
    o = np.where(valid, owner, 0)
    cell = np.arange(C)
    i = (cell % nu).astype(np.float32)
    j = (cell // nu).astype(np.float32)
    ox = (q[o, u] - cu) - (i * hu)[:, None]
    oy = (q[o, v] - cv) - (j * hv)[:, None]
    zero = np.float32(0)
    gx = np.maximum(np.maximum(-ox, ox - hu), zero)
    gy = np.maximum(np.maximum(-oy, oy - hv), zero)
    ro = r[o]
    valid &= gx * gx + gy * gy < ro * ro
    depth = q[o, a] if side == 0 else -q[o, a]
    okey = np.where(valid, ordered_key(depth.ravel(), o.ravel()).reshape(o.shape), _EMPTY)
    okey = np.sort(okey, axis=1)
    count = (okey != _EMPTY).sum(axis=1)
    k = max(1, min(int(count.max()) if C else 1, max_seeds))
    okey = okey[:, :k]
    seeds = np.where(okey == _EMPTY, -1, (okey & _LOW32).astype(np.int64))
    return _cull(seeds, q, r, a, cu, cv, hu, hv, nu), count


def _cull(seeds, q, r, a, cu, cv, hu, hv, nu):
    """Drop seeds that can win nothing, keeping the order: a seed concentric with an earlier one (the same
    float32 cell-relative centre) and not larger, and every seed after the first that holds all four cell
    corners (that disk holds the whole cell). Both resolvers would give them nothing (the sub-point test of
    a concentric smaller disk fails wherever the earlier one's passes, in float32 too), so this only saves work.
    """
    u, v = (a + 1) % 3, (a + 2) % 3
    C, K = seeds.shape
    ok = seeds >= 0
    o = np.where(ok, seeds, 0)
    cell = np.arange(C)
    ox = (q[o, u] - cu) - ((cell % nu).astype(np.float32) * hu)[:, None]
    oy = (q[o, v] - cv) - ((cell // nu).astype(np.float32) * hv)[:, None]
    rr = r[o]
    same = (ox[:, :, None] == ox[:, None, :]) & (oy[:, :, None] == oy[:, None, :])
    smaller = rr[:, :, None] <= rr[:, None, :]
    earlier = np.tril(np.ones((K, K), dtype=bool), -1)[None]
    keep = ok & ~(same & smaller & earlier & ok[:, None, :]).any(axis=2)
    holds = ok.copy()
    for x, y in ((0, 0), (hu, 0), (0, hv), (hu, hv)):
        dx = np.float32(x) - ox
        dy = np.float32(y) - oy
        holds &= dx * dx + dy * dy <= rr * rr
    first = np.where(holds.any(axis=1), holds.argmax(axis=1), K)
    keep &= np.arange(K)[None, :] <= first[:, None]
    # Stable compaction to the left.
    order = np.argsort(~keep, axis=1, kind="stable")
    out = np.where(np.take_along_axis(keep, order, axis=1), np.take_along_axis(seeds, order, axis=1), -1)
    width = max(1, int(keep.sum(axis=1).max()) if C else 1)
    return out[:, :width]


def _resolve(seeds, cells, q, r, a, cu, cv, hu, hv, nu, resolver, subpoints, unit):
    """Each seed's share of its cell in units, float64 (exact) or integer-valued (sub-points), shape (M, K)."""
    u, v = (a + 1) % 3, (a + 2) % 3
    o = np.where(seeds >= 0, seeds, 0)
    i = (cells % nu).astype(np.float32)
    j = (cells // nu).astype(np.float32)
    ox = (q[o, u] - cu) - (i * hu)[:, None]
    oy = (q[o, v] - cv) - (j * hv)[:, None]
    rs = np.where(seeds >= 0, r[o], np.float32(0))
    out = np.zeros(seeds.shape)
    k = seeds.shape[1]
    chunk = max(64, int(2e6 // (k * (2 * k + 10) if resolver == "exact" else k * subpoints * subpoints)))
    for b0 in range(0, len(cells), chunk):
        sl = slice(b0, b0 + chunk)
        if resolver == "exact":
            m = len(cells[sl])
            area = _visible_batch(ox[sl], oy[sl], rs[sl], np.full(m, float(hu)), np.full(m, float(hv)))
            out[sl] = area / (float(hu) * float(hv)) * unit
        else:
            sub = np.float32(subpoints)
            t = np.arange(subpoints, dtype=np.float32) + np.float32(0.5)
            tx = np.repeat(t * (hu / sub), subpoints)  # sub-point k * S + l at (t_k h_u / S, t_l h_v / S)
            ty = np.tile(t * (hv / sub), subpoints)
            dx = tx[None, :, None] - ox[sl][:, None, :]
            dy = ty[None, :, None] - oy[sl][:, None, :]
            rr = rs[sl][:, None, :]
            held = (dx * dx + dy * dy <= rr * rr) & (rr > 0)
            # After the cull, a last seed holding all four corners takes every point left, untested.
            last = np.maximum((seeds[sl] >= 0).sum(axis=1) - 1, 0)
            rows = np.arange(held.shape[0])
            lx, ly, lr = ox[sl][rows, last], oy[sl][rows, last], rs[sl][rows, last]
            corners = lr > 0
            for x, y in ((0, 0), (hu, 0), (0, hv), (hu, hv)):
                cx = np.float32(x) - lx
                cy = np.float32(y) - ly
                corners &= cx * cx + cy * cy <= lr * lr
            held[rows[corners], :, last[corners]] = True
            first = _first_true(held, seeds.shape[1])
            k = seeds.shape[1]
            counts = np.zeros((held.shape[0], k + 1))
            np.add.at(counts, (np.repeat(np.arange(held.shape[0]), held.shape[1]), first.ravel()), 1.0)
            out[sl] = counts[:, :k]
    return out


def _split(share, total_units):
    """Share ``total_units`` (M,) among seeds by floor of the proportional part, remainder to the largest share
    (the first, front to back, among equal ones). ``share`` (M, K) >= 0 with a positive row sum."""
    s = share.sum(axis=1)
    units = np.floor(total_units[:, None] * share / s[:, None]).astype(np.int64)
    rest = total_units - units.sum(axis=1)
    units[np.arange(len(s)), share.argmax(axis=1)] += rest
    return units


def area_estimate_reference(
    centers,
    radii,
    grid,
    *,
    depth_slots=3,
    resolver="exact",
    subpoints=8,
    lamps="all",
    active=None,
    max_seeds=MAX_SEEDS,
    details=False,
    _ring_slots=1,
    _cell_seeds="side",
    _extra=None,
) -> AreaEstimate:
    """The lamp's visible-area estimator (issue 15), as the reference its Warp kernel is tested against.

    Every choice, in the order the estimator makes them (float32 where the kernels compute, so that the kernel
    can match unit for unit):

    1. **Depth pass**, :func:`area_depth_slots`: each sample ray (cell corner) keeps the D smallest
       (depth, id) keys per lamp.
    2. **Gather**, per cell (i, j) and lamp: the D slots of the 4 corner samples (i, j), (i+1, j), (i, j+1),
       (i+1, j+1), and slot 0 (the front sphere) of the 8 ring samples :data:`RING`, (i-1, j), (i-1, j+1),
       (i+2, j), (i+2, j+1), (i, j-1), (i+1, j-1), (i, j+2), (i+1, j+2): across each cell edge, the two samples
       facing its ends. Ring samples off the grid (index -1 or n+1) are skipped; corner samples always exist.
       Duplicates collapse. A disk is kept when it meets the cell's interior, in float32 with the cell-relative
       centre ``o = (p_u - f32(i) h_u, p_v - f32(j) h_v)``: ``g_x = max(-o_x, o_x - h_u, 0)``, likewise
       ``g_y``, kept when ``g_x g_x + g_y g_y < r r``. Seeds are ordered by ``pack(p_a, id)`` (low lamp) or
       ``pack(-p_a, id)`` (high lamp): centre depth, ties to the lowest id. At most ``max_seeds`` frontmost
       seeds are kept; cells with more count as ``overflow``. Then, in order, seeds that can win nothing are
       dropped (:func:`_cull`): one concentric with an earlier seed (bitwise the same float32 ``o``) and not
       larger (``r <= r_earlier``), and every seed after the first one whose disk holds all four cell corners,
       each tested as ``dx dx + dy dy <= r r`` in float32 with ``dx = f32(corner_x) - o_x``.
    3. **Resolve**: each point of the cell goes to the first seed whose closed disk holds it.
       ``"exact"``: :func:`visible_disk_areas` on the seeds in float64 (inputs the float32 values above), share
       = area / (h_u h_v) * :data:`EXACT_UNIT`. ``"subpoints"``: S x S points at
       ``t_k = (f32(k) + 0.5) * (h_u / f32(S))``, ``t_l`` likewise with h_v, k, l = 0 .. S-1; a point is held
       when ``(t_k - o_x)^2 + (t_l - o_y)^2 <= r^2`` in float32 (each product and sum rounded, no FMA), except
       that a last seed holding all four corners holds every point untested; share = points won; unit = S^2,
       so nothing is rounded.
    4. **Balance**: each lamp's total is its shares' sum rounded half up (exact sub-point counts are already
       integers); both lamps of the cell distribute T = the larger of the two totals. A lamp with seeds shares
       T by ``floor(T share_k / sum(share))`` and gives the remainder to its largest share (the first, front to
       back, among equal ones). If T > 0 but one lamp has no seed with a positive share (possible only when
       the other lamp's seeds come from rays this lamp saw empty in front), the cell gives nothing on either
       side and counts as ``one_sided``. With one lamp of an axis off, the other distributes its own total.
    5. **Scatter**: low-lamp units add to the seed particle's axis-a entry, high-lamp units subtract; every cell
       therefore adds exactly zero per axis.

    Grid borders: the grid's cells are the estimator's cells; a disk is only resolved inside the grid, and rays
    off the grid do not exist (ring samples there are skipped). Particles reaching out of the grid lose the
    part outside, on both lamps alike.

    Args:
        centers: Particle centres [m], shape (N, 3).
        radii: Particle radii [m], shape (N,), or one number for all.
        grid: A :class:`warp_lamp.LampGrid` (attributes ``origin``, ``corner``, ``cell``, ``counts``).
        depth_slots: D, spheres kept per sample ray and lamp.
        resolver: ``"exact"`` or ``"subpoints"``.
        subpoints: S, sub-points per cell edge of the sub-point resolver.
        lamps: "all" or names from :data:`warp_lamp.LAMPS`.
        active: Optional mask, shape (N,): inactive spheres are absent.
        max_seeds: Most seeds a cell keeps per lamp.
        details: Also return per-cell seeds, shares and units (``AreaEstimate.cells``).

    Returns:
        An :class:`AreaEstimate`.
    """
    c, r64, on = _check_scene(centers, radii, active)
    if resolver not in ("exact", "subpoints"):
        raise ValueError(f"resolver: expected 'exact' or 'subpoints', got {resolver!r}")
    if not (isinstance(subpoints, int | np.integer) and 1 <= subpoints <= 64):
        raise ValueError(f"subpoints: expected an int in 1 .. 64, got {subpoints!r}")
    if not (isinstance(max_seeds, int | np.integer) and max_seeds >= 1):
        raise ValueError(f"max_seeds: expected an int >= 1, got {max_seeds!r}")
    mask = lamp_mask(lamps)
    d = int(depth_slots)
    keys, offsets = area_depth_slots(c, r64, grid, depth_slots=d, lamps=lamps, active=active)
    q, r, axes = _frame(c, r64, grid, on)
    unit = EXACT_UNIT if resolver == "exact" else int(subpoints) ** 2
    n = c.shape[0]
    units = np.zeros((n, 3), dtype=np.int64)
    stats = dict(sample_hits=0, cells=0, seeds_gathered=0, seeds=0, max_seeds=0, overflow=0, one_sided=0, candidates=0)
    cells_out = {}
    ids = np.flatnonzero(on)
    for a, (cu, cv, hu, hv, nu, nv) in enumerate(axes):
        u, v = (a + 1) % 3, (a + 2) % 3
        stats["sample_hits"] += len(_sample_hits(q[ids, u] - cu, q[ids, v] - cv, r[ids], hu, hv, nu, nv)[0])
        sides = [s for s in range(2) if mask >> (2 * a + s) & 1]
        if not sides:
            continue
        cand = {s: _gather(keys, offsets, a, d, nu, nv, s, _ring_slots) for s in sides}
        # Study hooks (bench/experiments/area_study.py): seeds from both lamps, extra candidates per cell.
        if _cell_seeds == "both" and len(sides) == 2:
            both = np.concatenate([cand[0], cand[1]], axis=1)
            cand = {0: both, 1: both}
        if _extra is not None:
            more = _extra(a, nu, nv)
            cand = {s: np.concatenate([cand[s], more], axis=1) for s in sides}
        per = {}
        for s in sides:
            stats["candidates"] += int((cand[s] != _EMPTY).sum())
            seeds, count = _seeds(cand[s], q, r, a, cu, cv, hu, hv, nu, s, max_seeds)
            per[s] = (seeds, count)
        any_seed = np.zeros(nu * nv, dtype=bool)
        for s in sides:
            any_seed |= per[s][1] > 0
        cells = np.flatnonzero(any_seed)
        share, total = {}, {}
        for s in sides:
            seeds, count = per[s]
            stats["cells"] += int((count > 0).sum())
            stats["seeds_gathered"] += int(np.minimum(count, max_seeds).sum())
            stats["seeds"] += int((seeds >= 0).sum())
            stats["max_seeds"] = max(stats["max_seeds"], int(count.max()) if len(count) else 0)
            stats["overflow"] += int((count > max_seeds).sum())
            sh = _resolve(seeds[cells], cells, q, r, a, cu, cv, hu, hv, nu, resolver, subpoints, unit)
            share[s] = sh
            total[s] = np.floor(sh.sum(axis=1) + 0.5).astype(np.int64)
        big = np.max(np.stack([total[s] for s in sides]), axis=0)
        empty = np.zeros(len(cells), dtype=bool)
        for s in sides:
            empty |= share[s].sum(axis=1) <= 0
        dropped = empty & (big > 0)
        stats["one_sided"] += int(dropped.sum())
        big = np.where(empty, 0, big)
        for s in sides:
            seeds = per[s][0][cells]
            ok = share[s].sum(axis=1) > 0
            got = np.zeros(share[s].shape, dtype=np.int64)
            got[ok] = _split(share[s][ok], big[ok])
            sign = 1 if s == 0 else -1
            m = seeds >= 0
            np.add.at(units[:, a], seeds[m], sign * got[m])
            if details:
                cells_out[LAMPS[2 * a + s]] = dict(cell=cells, seeds=seeds, share=share[s], units=got, total=total[s])
    return AreaEstimate(units, unit, cells_out, stats)
