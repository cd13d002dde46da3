"""Float64 NumPy references for the lamp's visible-area criterion, written for clarity and robustness.

Two layers:

- :func:`visible_disk_areas`, the planar core: the area of each of a list of disks, ordered front to back, that
  is visible inside an axis-aligned rectangle (not covered by an earlier disk). Exact: Green's theorem,
  ``A = 1/2 \\oint (x dy - y dx)``, over circle arcs and rectangle edges in closed form.
- :func:`visible_sphere_areas` and :func:`visible_area_reference`: the visible projected area of spheres, each
  point to the sphere whose *surface* the ray meets first (where spheres overlap, that is not the
  nearest centre): the planar core on the spheres ordered pair by pair for the rectangle, exact wherever the
  order holds on the whole rectangle, refined and rastered only where a projected intersection circle passes;
  :func:`visible_area_reference` tiles each lamp's plane and runs that per tile on the spheres that reach it.

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
    "hidden_spheres",
    "ordered_key",
    "visible_area_reference",
    "visible_disk_areas",
    "visible_sphere_areas",
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


def _checked(centers, radii, rect, dims: int, what: str):
    """Centres (K, dims) and radii (K,) as float64, and the rectangle's four floats, or ValueError naming the
    argument (and the first bad disk or sphere)."""
    c = np.asarray(centers, dtype=np.float64).reshape(-1, dims)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    if r.shape[0] != c.shape[0]:
        raise ValueError(f"radii: expected shape ({c.shape[0]},) to match centers, got {r.shape}")
    bad = ~(np.isfinite(r) & (r > 0)) | ~np.isfinite(c).all(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"centers/radii: {what} {k} is not finite with radius > 0: {c[k].tolist()}, {r[k]!r}")
    x0, y0, x1, y1 = (float(v) for v in rect)
    if not (np.isfinite([x0, y0, x1, y1]).all() and x1 > x0 and y1 > y0):
        raise ValueError(f"rect: expected finite (x0, y0, x1, y1) with x0 < x1 and y0 < y1, got {tuple(rect)!r}")
    return c, r, (x0, y0, x1, y1)


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
    c, r, (x0, y0, x1, y1) = _checked(centers, radii, rect, 2, "disk")
    if r.shape[0] == 0:
        return np.zeros(0)
    out = _visible_batch(c[None, :, 0] - x0, c[None, :, 1] - y0, r[None, :], np.array([x1 - x0]), np.array([y1 - y0]))
    return out[0]


# --- visibility by surface depth: spheres that overlap ------------------------------------------------------

#: Where the surface order changes inside a rectangle, :func:`_visible_surface_batch` cuts it in four until its
#: sides are at most the smallest radius over 2^SURFACE_LEVELS, then resolves it on a SURFACE_RASTER square raster.
SURFACE_LEVELS = 4
SURFACE_RASTER = 16


def _ellipse_meets(dx, dy, dz, mu, mv, rho2, w, h):
    """Whether the projection of a sphere pair's intersection circle (centre (mu, mv) in the rectangle's
    frame, radius^2 rho2, normal along (dx, dy, dz)) meets the closed rectangle [0, w] x [0, h], float64.

    The ellipse is Q(q) = 0 with ``Q = dz^2 |q - m|^2 + ((dx, dy) . (q - m))^2 - dz^2 rho2`` (the point of the
    plane above q lies on the circle), a convex quadratic: the curve meets the rectangle iff Q's minimum over it
    is <= 0 <= its maximum (at a corner). The minimum is at m when m lies inside, else on an edge (a clamped
    parabola vertex). A tolerance of 1e-12 of Q's scale keeps a pair at equal depths (dz = 0, the ellipse a
    segment of the radical line, Q >= 0 with zero on it) undecided where the line crosses the rectangle.
    """
    w = np.broadcast_to(w, mu.shape)
    h = np.broadcast_to(h, mu.shape)
    a_uu = dz * dz + dx * dx
    a_vv = dz * dz + dy * dy
    a_uv = dx * dy
    c0 = dz * dz * rho2

    def q(du, dv):
        return a_uu * du * du + 2.0 * a_uv * du * dv + a_vv * dv * dv - c0

    hi = np.full(mu.shape, -np.inf)
    lo = np.full(mu.shape, np.inf)
    for x, y in ((0.0, 0.0), (w, 0.0), (0.0, h), (w, h)):
        hi = np.maximum(hi, q(x - mu, y - mv))
    inside = (mu >= 0) & (mu <= w) & (mv >= 0) & (mv <= h)
    lo = np.where(inside, -c0, lo)
    with np.errstate(divide="ignore", invalid="ignore"):
        for x in (0.0, w):  # edges u = x: Q is a_vv dv^2 + 2 a_uv du dv + ...
            du = x - mu
            dv = np.where(a_vv > 0, -a_uv * du / a_vv, 0.0)
            dv = np.clip(dv + mv, 0.0, h) - mv
            lo = np.minimum(lo, q(du, dv))
        for y in (0.0, h):
            dv = y - mv
            du = np.where(a_uu > 0, -a_uv * dv / a_uu, 0.0)
            du = np.clip(du + mu, 0.0, w) - mu
            lo = np.minimum(lo, q(du, dv))
    tol = 1e-12 * (dx * dx + dy * dy + dz * dz) * (w * w + h * h + rho2)
    return (lo <= tol) & (hi >= -tol)


def _pair_relations64(x, y, z, r, ok, w, h):
    """:func:`_pair_relations` in float64 for the exact reference, with the ellipse tested exactly
    (:func:`_ellipse_meets`) instead of by its bounding box. Shape (B, K, K)."""
    xe, ye, ze, re = (a[:, :, None] for a in (x, y, z, r))
    xl, yl, zl, rl = (a[:, None, :] for a in (x, y, z, r))
    ww, hh = w[:, None, None], h[:, None, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        dx, dy, dz = xl - xe, yl - ye, zl - ze
        dp = dx * dx + dy * dy
        d2 = dp + dz * dz
        rs = re + rl
        rd = re - rl
        t = (d2 + re * re - rl * rl) / (2.0 * d2)
        rho2 = np.maximum(re * re - t * t * d2, 0.0)
        ma, ba = ze + t * dz, np.sqrt(rho2 * dp / d2)
        meets = ((ma - ba < ze) | (ma + ba > zl)) & _ellipse_meets(dx, dy, dz, xe + t * dx, ye + t * dy, rho2, ww, hh)
        qx = np.clip(xe, 0.0, ww)
        qy = np.clip(ye, 0.0, hh)
        dl = (qx - xl) ** 2 + (qy - yl) ** 2
        se = np.sqrt(np.maximum(re * re - (qx - xe) ** 2 - (qy - ye) ** 2, 0.0))
        sl = np.sqrt(np.maximum(rl * rl - dl, 0.0))
        swap_q0 = (dl <= rl * rl) & (zl - sl <= ze - se) & (ze + se <= zl + sl)
    rel = np.where(swap_q0, REL_SWAP, REL_KEEP)
    rel = np.where(meets, REL_UNDECIDED, rel)
    rel = np.where(d2 <= rd * rd, np.where(re < rl, REL_SWAP, REL_KEEP), rel)
    rel = np.where(d2 >= rs * rs, REL_KEEP, rel)
    rel = np.where(dp >= rs * rs, REL_APART, rel)
    upper = np.triu(np.ones(rel.shape[1:], dtype=bool), 1)[None] & ok[:, :, None] & ok[:, None, :]
    return np.where(upper, rel, REL_APART).astype(np.int8)


def _surface_raster(x, y, z, r, w, h, n):
    """Per row, the points of an n x n raster of [0, w] x [0, h] won by each sphere (first surface, ties to the
    earlier) minus those the first disk holding them takes, times the point's area: shape (B, K), float64."""
    B, K = r.shape
    t = (np.arange(n) + 0.5) / n
    out = np.zeros(B * (K + 1))
    for b0 in range(0, B, 512):
        sl = slice(b0, b0 + 512)
        m = len(r[sl])
        tx = (w[sl, None] * np.repeat(t, n)[None])[:, :, None]
        ty = (h[sl, None] * np.tile(t, n)[None])[:, :, None]
        d2 = (tx - x[sl, None, :]) ** 2 + (ty - y[sl, None, :]) ** 2
        r2 = (r[sl] * r[sl])[:, None, :]
        held = (d2 <= r2) & (r[sl] > 0)[:, None, :]
        depth = np.where(held, z[sl, None, :] - np.sqrt(np.maximum(r2 - d2, 0.0)), np.inf)
        any_held = held.any(axis=2)
        won = np.where(any_held, depth.argmin(axis=2), K)
        holder = np.where(any_held, held.argmax(axis=2), K)
        base = (np.arange(b0, b0 + m) * (K + 1))[:, None]
        size = B * (K + 1)
        out += np.bincount((base + won).ravel(), minlength=size) - np.bincount((base + holder).ravel(), minlength=size)
    return out.reshape(B, K + 1)[:, :K] * (w * h / (n * n))[:, None]


def _behind_full(x, y, z, r, w, h):
    """Spheres (B, K, by centre depth; r <= 0 padding) that cannot be first anywhere in their rectangle: after the
    first one whose disk holds the four corners, those whose ball does not reach into it (their chords lie wholly
    behind its chord on every ray of the rectangle). Shape (B, K) bool."""
    B, K = r.shape
    holds = r > 0
    for cx, cy in ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)):
        holds &= (cx * w[:, None] - x) ** 2 + (cy * h[:, None] - y) ** 2 <= r * r
    f = np.where(holds.any(axis=1), holds.argmax(axis=1), K)
    rows = np.arange(B)
    g = np.minimum(f, K - 1)
    d2 = (x - x[rows, g][:, None]) ** 2 + (y - y[rows, g][:, None]) ** 2 + (z - z[rows, g][:, None]) ** 2
    apart = d2 >= (r + r[rows, g][:, None]) ** 2
    return (np.arange(K)[None, :] > f[:, None]) & apart


def _compact(*arrays, keep):
    """The kept entries of each (B, K) array moved left in order, padded with zeros, trimmed to the widest row."""
    order = np.argsort(~keep, axis=1, kind="stable")
    width = max(1, int(keep.sum(axis=1).max()) if keep.size else 1)
    kept = np.take_along_axis(keep, order, axis=1)[:, :width]
    return [np.where(kept, np.take_along_axis(a, order, axis=1)[:, :width], 0.0) for a in arrays], order[:, :width]


def _visible_surface_batch(x, y, z, r, w, h, leaf) -> np.ndarray:
    """Visible areas of B problems, each point of the rectangle [0, w_b] x [0, h_b] to the sphere whose surface a
    ray from depth -infinity meets first there: spheres (B, K) with disk centres (x, y), depths z, radii r
    (r <= 0: padding), ordered by centre depth z (ties: the earlier wins). Shape (B, K), float64.

    Per row, each pair of spheres whose disks overlap gets its order from :func:`_pair_relations64`; where every
    pair's order holds on the whole rectangle and the orders admit one sequence, the disks are clipped front to
    back in it (:func:`_visible_batch`: exact). Elsewhere the rectangle is cut in four until its sides are at
    most ``leaf``; the pieces still undecided then are clipped in centre-depth order and corrected on a
    :data:`SURFACE_RASTER` square raster of surface depths (:func:`_surface_raster`): the error sits only where
    the visible boundary is the projection of an intersection circle (an ellipse arc).
    """
    B, K = r.shape
    out = np.zeros((B, K))
    if B == 0:
        return out
    # Only the spheres that can be first somewhere in the rectangle, moved left (keeps the centre-depth order).
    (x, y, z, r), where = _compact(x, y, z, r, keep=(r > 0) & ~_behind_full(x, y, z, r, w, h))
    rows = np.arange(B)[:, None]
    ok = r > 0
    order, undecided = _surface_order(_pair_relations64(x, y, z, r, ok, w, h), ok)
    res = np.zeros(r.shape)
    done = np.flatnonzero(~undecided)
    if len(done):
        o = order[done]
        xs, ys, rs = (np.take_along_axis(a[done], o, axis=1) for a in (x, y, r))
        area = _visible_batch(xs, ys, rs, w[done], h[done])
        back = np.zeros_like(area)
        np.put_along_axis(back, o, area, axis=1)
        res[done] = back
    rest = np.flatnonzero(undecided)
    if len(rest) and max(float(w[rest].max()), float(h[rest].max())) <= leaf:
        # Centre-depth order, then the raster moves what that order gets wrong.
        xs, ys, zs, rs = (a[rest] for a in (x, y, z, r))
        res[rest] = _visible_batch(xs, ys, rs, w[rest], h[rest]) + _surface_raster(
            xs, ys, zs, rs, w[rest], h[rest], SURFACE_RASTER
        )
    elif len(rest):
        # Four quadrants per undecided row; disks missing a quadrant become padding there.
        hw, hh = 0.5 * w[rest], 0.5 * h[rest]
        xs, ys, zs, rs = (np.repeat(a[rest], 4, axis=0) for a in (x, y, z, r))
        qw, qh = np.repeat(hw, 4), np.repeat(hh, 4)
        xs = xs - (np.tile([0.0, 1.0, 0.0, 1.0], len(rest)) * qw)[:, None]
        ys = ys - (np.tile([0.0, 0.0, 1.0, 1.0], len(rest)) * qh)[:, None]
        gx = np.maximum(np.maximum(-xs, xs - qw[:, None]), 0.0)
        gy = np.maximum(np.maximum(-ys, ys - qh[:, None]), 0.0)
        rs = np.where(gx * gx + gy * gy < rs * rs, rs, 0.0)
        sub = _visible_surface_batch(xs, ys, zs, rs, qw, qh, leaf)
        res[rest] = sub.reshape(len(rest), 4, -1).sum(axis=1)
    np.add.at(out, (np.broadcast_to(rows, where.shape), where), np.where(ok, res, 0.0))
    return out


def visible_sphere_areas(centers, radii, rect) -> np.ndarray:
    """Area of each sphere that is visible inside an axis-aligned rectangle, seen from depth -infinity.

    A point of the rectangle belongs to the sphere whose surface the ray through it (along the third
    coordinate, increasing) meets first; ties to the lower index. Exact (to float64 rounding) wherever the
    visible boundary is made of the spheres' outlines; where it is the projection of two spheres' intersection
    circle, it is resolved on a raster as fine as the smallest radius over 2^SURFACE_LEVELS x SURFACE_RASTER
    (:func:`_visible_surface_batch`).

    Args:
        centers: Sphere centres [m], shape (K, 3): two coordinates in the rectangle's plane, then the depth.
        radii: Radii [m], shape (K,), > 0.
        rect: The rectangle (x0, y0, x1, y1) [m], x0 < x1, y0 < y1.

    Returns:
        Visible area of each sphere inside the rectangle [m^2], shape (K,), float64.
    """
    c, r, (x0, y0, x1, y1) = _checked(centers, radii, rect, 3, "sphere")
    if r.shape[0] == 0:
        return np.zeros(0)
    leaf = float(r.min()) / 2**SURFACE_LEVELS
    w, h = np.array([x1 - x0]), np.array([y1 - y0])
    o = np.lexsort((np.arange(len(r)), c[:, 2]))
    x, y, z, rr = c[o, 0][None] - x0, c[o, 1][None] - y0, c[o, 2][None], r[o][None]
    out = np.zeros(len(r))
    out[o] = _visible_surface_batch(x, y, z, rr, w, h, leaf)[0]
    return out


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


def _tile_areas(pu, pv, pd, r, ids, tile_ids, tile_x0, tile_y0, t, n_out):
    """Visible area per sphere by surface depth (:func:`_visible_surface_batch`), summed over tiles of side t.

    Candidates per tile are taken front to back by centre depth ``pd`` (ties to the lower id), the first k of
    them, k doubling until the tile is covered (to :data:`COVERED_TOL`) and no candidate left out reaches into a
    sphere visible in the tile: one that does not cannot show in front of it (its chord would have to hold the
    visible one's), and every point of a covered tile belongs to a visible sphere.
    """
    out = np.zeros(n_out)
    order, tsorted, rank, start, size = _grouped(tile_ids, (pd, ids))
    tiles = tsorted[start]
    todo = np.ones(len(start), dtype=bool)
    leaf = t / 2**SURFACE_LEVELS
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
        z = np.zeros((B, k))
        rr = np.zeros((B, k))
        who = np.full((B, k), -1)
        tt = tiles[g]
        x[row, col] = pu[src] - tile_x0[tt[row]]
        y[row, col] = pv[src] - tile_y0[tt[row]]
        z[row, col] = pd[src]
        rr[row, col] = r[src]
        who[row, col] = ids[src]
        areas = _visible_surface_batch(x, y, z, rr, np.full(B, t), np.full(B, t), leaf)
        covered = areas.sum(axis=1) >= (1.0 - COVERED_TOL) * t * t
        # Candidates left out of covered tiles: does any reach into a visible sphere?
        more = np.flatnonzero(covered & (size[g] > k))
        reach = np.zeros(B, dtype=bool)
        if len(more):
            extra = size[g][more] - k
            mrow = np.repeat(more, extra)
            mpos = np.repeat(start[g][more] + k, extra) + (
                np.arange(extra.sum()) - np.repeat(np.cumsum(extra) - extra, extra)
            )
            msrc = order[mpos]
            dx = (pu[msrc] - tile_x0[tt[mrow]])[:, None] - x[mrow]
            dy = (pv[msrc] - tile_y0[tt[mrow]])[:, None] - y[mrow]
            dz = pd[msrc][:, None] - z[mrow]
            hit = (dx * dx + dy * dy + dz * dz < (r[msrc][:, None] + rr[mrow]) ** 2) & (areas[mrow] > 0)
            np.logical_or.at(reach, mrow, hit.any(axis=1))
        done = (covered & ~reach) | (size[g] <= k)
        m = done[:, None] & (who >= 0)
        np.add.at(out, who[m], areas[m])
        todo[g[done]] = False
        k_max *= 2
    return out


def visible_area_reference(centers, radii, *, lamps="all", active=None) -> np.ndarray:
    """Exact visible projected area of every sphere from each of the six lamps, in float64.

    Lamp ``"-x"`` sits at minus infinity on x and looks toward +x (:data:`warp_lamp.LAMPS` order). The area
    a lamp sees of a sphere is where the sphere's surface is the first one the lamp's rays meet: the entry point
    of each ray for a low lamp, the exit point (the entry seen from +infinity) for a high lamp. No lamp grid is
    involved: each lamp's plane is cut into square tiles of the smallest radius internally, and each tile runs
    :func:`_visible_surface_batch` on the spheres that reach it, front to back by centre depth, until the tile
    is covered to within :data:`COVERED_TOL` of its area and no sphere left out reaches into a visible one.

    For disjoint spheres the centre depth orders the surfaces: along any ray through two disjoint spheres their
    chords are disjoint, and each chord's midpoint is the sphere's centre depth. The result is then exact (to
    float64 rounding and the coverage tolerance). Where spheres overlap (DEM contacts, bonded packings) the
    visible boundary between two of them is the projection of their intersection circle, an ellipse arc; a
    sphere nested in another is hidden. Tiles where that boundary may pass are cut in four down to the smallest
    radius over 2^:data:`SURFACE_LEVELS` and corrected there on a :data:`SURFACE_RASTER` square raster of surface
    depths; the error, confined to those arcs, is at most 2e-5 of a mean sphere's disk per sphere and lamp on a
    packing overlapping up to 30% with radius ratio 3 (against two more levels), and
    ``tests/test_area.py`` checks it against brute-force rasters.

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
            res = _tile_areas(pu[sph], pv[sph], depth, rr[sph], ids[sph], tile, tile_x0, tile_y0, t, n)
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


def area_depth_slots(centers, radii, grid, *, depth_slots=3, lamps="all", active=None, hidden=None):
    """The D-slot depth pass in NumPy: per sample ray (cell corner) and lamp, the D smallest (depth, id) keys.

    Sample (i, j), 0 <= i <= n_u, 0 <= j <= n_v, of grid a sits at ``(f32(i) h_u, f32(j) h_v)`` from the grid
    corner; its low lamp keys ``pack(p_a - s, id)`` (entry depth), its high lamp ``pack(-(p_a + s), id)``
    (negated exit depth), in float32 as :func:`_sample_hits` says, positions being ``f32(centers - origin)``
    (float64 subtraction first, as :func:`warp_lamp.lamp_forces` does). Ties go to the lowest id (the packing).
    ``hidden`` (bool, shape (N, 6), columns in ``LAMPS`` order) leaves out the spheres a lamp can never see
    (:func:`hidden_spheres`): their slots go to the next spheres along the ray.

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
        pid_all, sample_all, s_all = _sample_hits(pu, pv, r[ids], hu, hv, nu, nv)
        for side in range(2):
            if not mask >> (2 * a + side) & 1:
                continue
            pid, sample, s = pid_all, sample_all, s_all
            if hidden is not None:
                show = ~hidden[ids[pid], 2 * a + side]
                pid, sample, s = pid[show], sample[show], s[show]
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


def hidden_spheres(centers, radii, grid, *, depth_slots=3, rounds=1, lamps="all", active=None) -> np.ndarray:
    """Spheres a lamp can never see because one other sphere hides them, found from the depth pass's own slots.

    Sphere B is hidden from the low lamp of axis a by sphere A when B's projected disk lies inside A's and B's
    entry surface is behind A's on the whole of B's disk. In float32, with ``o`` the centres' offset across the
    lamp, ``e = sqrt(o_u o_u + o_v o_v) + r_B`` (the farthest point of B's disk from A's axis) and z the depth along
    the lamp (``p_a``; ``-p_a`` for the high lamp): ``e < r_A`` and ``z_B - r_B > z_A - sqrt(r_A r_A - e e)``
    (B's nearest point against A's surface at its deepest over B's disk). The candidates A for B are the D keys
    of the sample nearest B's centre (``floor(p / h + 1/2)``, clamped to the grid): a hider holds B's whole disk,
    so it meets that ray in front of B. Each round runs the depth pass without the spheres found so far, so
    that the next D spheres along each ray offer themselves as hiders.

    Returns:
        Bool array (N, 6), columns in ``LAMPS`` order: True where the lamp can never see the sphere.
    """
    c, r64, on = _check_scene(centers, radii, active)
    mask = lamp_mask(lamps)
    d = int(depth_slots)
    q, r, axes = _frame(c, r64, grid, on)
    n = len(r)
    hidden = np.zeros((n, 6), dtype=bool)
    for _ in range(int(rounds)):
        keys, offsets = area_depth_slots(c, r64, grid, depth_slots=d, lamps=lamps, active=active, hidden=hidden)
        new = hidden.copy()
        for a, (cu, cv, hu, hv, nu, nv) in enumerate(axes):
            u, v = (a + 1) % 3, (a + 2) % 3
            pu = q[:, u] - cu
            pv = q[:, v] - cv
            i = np.clip(np.floor(pu / hu + np.float32(0.5)), 0, nu).astype(np.int64)
            j = np.clip(np.floor(pv / hv + np.float32(0.5)), 0, nv).astype(np.int64)
            sample = offsets[a] + j * (nu + 1) + i
            for side in range(2):
                if not mask >> (2 * a + side) & 1:
                    continue
                z = q[:, a] if side == 0 else -q[:, a]
                for k in range(d):
                    key = keys[(2 * sample + side) * d + k]
                    ok = (key != _EMPTY) & on
                    h = np.where(ok, (key & _LOW32).astype(np.int64), 0)
                    du = pu - pu[h]
                    dv = pv - pv[h]
                    e = np.sqrt(du * du + dv * dv) + r
                    rh = r[h]
                    bound = z[h] - np.sqrt(np.maximum(rh * rh - e * e, np.float32(0)))
                    new[:, 2 * a + side] |= ok & (h != np.arange(n)) & (e < rh) & (z - r > bound)
        hidden = new
    return hidden


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
    seeds, full = _cull(seeds, q, r, a, cu, cv, hu, hv, nu, side)
    return seeds, full, count


def _geometry(seeds, cells, q, r, a, cu, cv, hu, hv, nu, side):
    """Float32 cell-relative centres, depths along the lamp and radii of seeds (C, K) of ``cells`` (C,), as the
    kernel holds them: (ox, oy, oz, rr, ok), padding with rr = 0 and ok False."""
    u, v = (a + 1) % 3, (a + 2) % 3
    ok = seeds >= 0
    o = np.where(ok, seeds, 0)
    ox = (q[o, u] - cu) - ((cells % nu).astype(np.float32) * hu)[:, None]
    oy = (q[o, v] - cv) - ((cells // nu).astype(np.float32) * hv)[:, None]
    oz = q[o, a] if side == 0 else -q[o, a]
    rr = np.where(ok, r[o], np.float32(0))
    return ox, oy, oz, rr, ok


def _holds_corners(ox, oy, rr, hu, hv):
    """Whether each disk holds the four cell corners, float32 ``dx dx + dy dy <= r r`` per corner."""
    holds = rr > 0
    for x, y in ((0, 0), (hu, 0), (0, hv), (hu, hv)):
        dx = np.float32(x) - ox
        dy = np.float32(y) - oy
        holds &= dx * dx + dy * dy <= rr * rr
    return holds


def _cull(seeds, q, r, a, cu, cv, hu, hv, nu, side):
    """Drop seeds that can win nothing, keeping the order, one seed at a time as the kernel does: a seed concentric
    with a kept earlier one (the same float32 cell-relative centre) and not larger; and, once a kept seed's disk
    holds all four cell corners (the first such seed, ``full``), every later seed whose surface is behind full's
    on the whole cell (:func:`_pair_relations` of the two: REL_KEEP, or REL_APART): full holds every point of
    the cell, so such a seed is first nowhere. Returns (seeds (C, K') -1 padded, the full seed's position in
    them (C,), -1 where none)."""
    C, K = seeds.shape
    ox, oy, oz, rr, ok = _geometry(seeds, np.arange(C), q, r, a, cu, cv, hu, hv, nu, side)
    holds = _holds_corners(ox, oy, rr, hu, hv)
    rows = np.arange(C)
    out = np.full((C, K), -1, dtype=np.int64)
    kx, ky, kz, kr = (np.zeros((C, K), dtype=np.float32) for _ in range(4))
    kept = np.zeros(C, dtype=np.int64)
    full = np.full(C, -1, dtype=np.int64)
    for k in range(K):
        x, y, z, rad = ox[:, k], oy[:, k], oz[:, k], rr[:, k]
        slot = np.arange(K)[None, :] < kept[:, None]
        drop = (slot & (kx == x[:, None]) & (ky == y[:, None]) & (rad[:, None] <= kr)).any(axis=1)
        f = np.maximum(full, 0)
        pair = [np.stack([kept_f[rows, f], now], axis=1) for kept_f, now in ((kx, x), (ky, y), (kz, z), (kr, rad))]
        rel = _pair_relations(*pair, np.ones((C, 2), dtype=bool), hu, hv)[:, 0, 1]
        drop |= (full >= 0) & ((rel == REL_KEEP) | (rel == REL_APART))
        keep = ok[:, k] & ~drop
        w = rows[keep]
        out[w, kept[w]] = seeds[w, k]
        kx[w, kept[w]], ky[w, kept[w]], kz[w, kept[w]], kr[w, kept[w]] = x[w], y[w], z[w], rad[w]
        first = keep & (full < 0) & holds[:, k]
        full[first] = kept[first]
        kept += keep
    width = max(1, int(kept.max()) if C else 1)
    return out[:, :width], full


#: Pair relations (the kernel's ``pair_relation``): disks apart, earlier seed first, later seed first, undecided.
REL_APART, REL_KEEP, REL_SWAP, REL_UNDECIDED = 0, 1, 2, 3


def _pair_relations(ox, oy, oz, rr, ok, hu, hv):
    """How every pair of seeds (k0 < k1, by centre depth) must be ordered for the clip in its cell, float32 as
    the kernel's ``pair_relation``: REL_APART (disks apart), REL_KEEP (k0's surface first wherever both disks
    hold a point of the cell), REL_SWAP (k1's), REL_UNDECIDED (the projected intersection circle may cross the
    cell). Shape (C, K, K), meaningful above the diagonal where both seeds exist.

    Why one answer holds where the ellipse misses the cell: k1's surface comes first at a point only where k0's
    chord along the ray lies inside k1's (otherwise k0 enters first, its chord's midpoint, the centre depth,
    coming first); that region of k0's disk is bounded by k0's outline and the projection of the intersection
    circle's points in front of both centres or behind both (where both chords begin, or both end, together).
    """
    f32 = np.float32
    xe, ye, ze, re = (x[:, :, None] for x in (ox, oy, oz, rr))
    xl, yl, zl, rl = (x[:, None, :] for x in (ox, oy, oz, rr))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        dx = xl - xe
        dy = yl - ye
        dz = zl - ze
        rs = re + rl
        dp = dx * dx + dy * dy
        d2 = dp + dz * dz
        rd = re - rl
        re2 = re * re
        rl2 = rl * rl
        t = (d2 + re2 - rl2) / (f32(2.0) * d2)
        rho2 = np.maximum(re2 - t * t * d2, f32(0))
        mu = xe + t * dx
        mv = ye + t * dy
        ma = ze + t * dz
        bu = np.sqrt(rho2 * (dy * dy + dz * dz) / d2)
        bv = np.sqrt(rho2 * (dx * dx + dz * dz) / d2)
        ba = np.sqrt(rho2 * (dx * dx + dy * dy) / d2)
        box = ((ma - ba < ze) | (ma + ba > zl)) & (mu - bu <= hu) & (mu + bu >= f32(0))
        box &= (mv - bv <= hv) & (mv + bv >= f32(0))
        inside = np.ones(box.shape, dtype=bool)
        for x, y in ((0, 0), (hu, 0), (0, hv), (hu, hv)):
            du = f32(x) - mu
            dv = f32(y) - mv
            w = dx * du + dy * dv
            qv = dz * dz * (du * du + dv * dv) + w * w - dz * dz * rho2
            inside &= qv < f32(0)
        qx = np.clip(xe, f32(0), hu)
        qy = np.clip(ye, f32(0), hv)
        lx = qx - xl
        ly = qy - yl
        dl = lx * lx + ly * ly
        ex = qx - xe
        ey = qy - ye
        se = np.sqrt(np.maximum(re2 - (ex * ex + ey * ey), f32(0)))
        sl = np.sqrt(np.maximum(rl2 - dl, f32(0)))
        swap_q0 = (dl <= rl2) & (zl - sl <= ze - se) & (ze + se <= zl + sl)
    rel = np.where(swap_q0, REL_SWAP, REL_KEEP)
    rel = np.where(box & ~inside, REL_UNDECIDED, rel)
    nested = d2 <= rd * rd
    rel = np.where(nested, np.where(re < rl, REL_SWAP, REL_KEEP), rel)
    rel = np.where(d2 >= rs * rs, REL_KEEP, rel)
    rel = np.where(dp >= rs * rs, REL_APART, rel)
    upper = np.triu(np.ones(rel.shape[1:], dtype=bool), 1)[None] & ok[:, :, None] & ok[:, None, :]
    return np.where(upper, rel, REL_APART).astype(np.int8)


def _surface_order(rel, ok):
    """The clip's order per cell (the kernel's ``topo_order``): each seed after those the relations put before it,
    the lowest free index first, padding last. Returns (order (C, K); undecided (C,): an undecided pair or a
    cycle, where the order is the given one)."""
    C, K = ok.shape
    before = np.zeros((C, K, K), dtype=bool)  # before[c, k, m]: m must come before k
    before |= np.transpose(rel == REL_KEEP, (0, 2, 1))
    before |= rel == REL_SWAP
    undecided = (rel == REL_UNDECIDED).any(axis=(1, 2))
    placed = ~ok.copy()
    pos = K + np.tile(np.arange(K), (C, 1))  # the step each seed is placed at; padding after all
    cycle = np.zeros(C, dtype=bool)
    count = ok.sum(axis=1)
    rows = np.arange(C)
    for step in range(K):
        free = ~placed & ~(before & ~placed[:, None, :]).any(axis=2)
        todo = step < count
        cycle |= todo & ~free.any(axis=1)
        go = rows[todo & free.any(axis=1)]
        pick = free[go].argmax(axis=1)
        pos[go, pick] = step
        placed[go, pick] = True
    order = np.argsort(pos, axis=1, kind="stable")
    order[cycle] = np.arange(K)
    return order, undecided | cycle


def _first_surface(ox, oy, oz, rr, full, tx, ty):
    """For points (tx, ty) (P,) of each cell: the seed whose surface the ray meets first (ties to the earlier
    seed) and the first seed whose disk holds the point, each K where none does; float32 as the kernel's
    ``surface_depth``. Seeds (B, K) with rr = 0 as padding; ``full`` (B,) a seed holding every point, or -1."""
    K = rr.shape[1]
    dx = tx[None, :, None] - ox[:, None, :]
    dy = ty[None, :, None] - oy[:, None, :]
    d2 = dx * dx + dy * dy
    r2 = (rr * rr)[:, None, :]
    is_full = (np.arange(K)[None, :] == full[:, None])[:, None, :]
    held = ((d2 <= r2) | is_full) & (rr > 0)[:, None, :]
    depth = oz[:, None, :] - np.sqrt(np.maximum(r2 - d2, np.float32(0)))
    depth = np.where(held, depth, np.float32(np.inf))
    won = np.where(held.any(axis=2), depth.argmin(axis=2), K)
    return won, _first_true(held, K)


def _points(n, h):
    """Sub-point coordinates along one cell edge, float32 as the kernels: ``(f32(k) + 0.5) * (h / f32(n))``."""
    return (np.arange(n, dtype=np.float32) + np.float32(0.5)) * (h / np.float32(n))


def _resolve(seeds, full, cells, q, r, a, cu, cv, hu, hv, nu, side, resolver, subpoints, unit):
    """Each seed's share of its cell in units, float64 (exact) or integer-valued (sub-points), shape (M, K), and
    the seeds in the order the shares are given (the sequence of :func:`_surface_order`)."""
    ox, oy, oz, rr, ok = _geometry(seeds, cells, q, r, a, cu, cv, hu, hv, nu, side)
    out = np.zeros(seeds.shape)
    seeds = seeds.copy()
    k = seeds.shape[1]
    chunk = max(16, int(2e6 // (k * (2 * k + 10) if resolver == "exact" else k * subpoints * subpoints)))
    for b0 in range(0, len(cells), chunk):
        sl = slice(b0, b0 + chunk)
        x, y, z, rad, good, f = ox[sl], oy[sl], oz[sl], rr[sl], ok[sl], full[sl]
        m = len(x)
        rows = np.arange(m)
        order, undecided = _surface_order(_pair_relations(x, y, z, rad, good, hu, hv), good)
        x, y, z, rad = (np.take_along_axis(v, order, axis=1) for v in (x, y, z, rad))
        seeds[sl] = np.take_along_axis(seeds[sl], order, axis=1)
        moved = np.argsort(order, axis=1)  # new position of each old one
        f = np.where(f >= 0, moved[rows, np.maximum(f, 0)], -1)
        if resolver == "exact":
            area = _visible_batch(x, y, rad, np.full(m, float(hu)), np.full(m, float(hv)))
            share = area / (float(hu) * float(hv)) * unit
            fix = np.flatnonzero(undecided)
            if len(fix):
                share[fix] += _raster_correction(x[fix], y[fix], z[fix], rad[fix], f[fix], hu, hv, unit)
                share[fix] = np.maximum(share[fix], 0.0)
            out[sl] = share
        else:
            t_u, t_v = _points(subpoints, hu), _points(subpoints, hv)
            won, holder = _first_surface(x, y, z, rad, f, np.repeat(t_u, subpoints), np.tile(t_v, subpoints))
            won = np.where(undecided[:, None], won, holder)
            counts = np.zeros((m, k + 1))
            np.add.at(counts, (np.repeat(rows, won.shape[1]), won.ravel()), 1.0)
            out[sl] = counts[:, :k]
    return out, seeds


#: Points per cell edge of the exact resolver's raster correction (one exact unit each).
RASTER = 64


def _raster_correction(ox, oy, oz, rr, full, hu, hv, unit):
    """The kernel's ``raster_correction``: on RASTER x RASTER points, unit / RASTER^2 per point moves from the first
    seed whose disk holds it (whom the clip gave it) to the one whose surface comes first. Shape (B, K)."""
    B, K = rr.shape
    t_u, t_v = _points(RASTER, hu), _points(RASTER, hv)
    tx, ty = np.repeat(t_u, RASTER), np.tile(t_v, RASTER)
    weight = unit / RASTER**2
    corr = np.zeros((B, K + 1))
    for b0 in range(0, B, 64):
        sl = slice(b0, b0 + 64)
        won, holder = _first_surface(ox[sl], oy[sl], oz[sl], rr[sl], full[sl], tx, ty)
        rows = np.repeat(np.arange(b0, b0 + won.shape[0]), won.shape[1])
        np.add.at(corr, (rows, won.ravel()), weight)
        np.add.at(corr, (rows, holder.ravel()), -weight)
    return corr[:, :K]


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
    _hidden_rounds=0,
) -> AreaEstimate:
    """The lamp's visible-area estimator, as the reference its Warp kernel is tested against.

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
       dropped (:func:`_cull`): one concentric with a kept earlier seed (bitwise the same float32 ``o``) and
       not larger (``r <= r_earlier``); and, after the first kept seed whose disk holds all four cell corners
       (``full``; each corner tested as ``dx dx + dy dy <= r r`` in float32 with ``dx = f32(corner_x) - o_x``),
       every seed that full comes before on the whole cell (the pair relation of step 3, with z the depth along
       the lamp: ``p_a``, or ``-p_a`` for the high lamp).
    3. **Resolve**: each point of the cell goes to the seed whose surface its ray meets first, at depth
       ``z - sqrt(max(r r - d d, 0))`` (the entry point; for the high lamp, with z = -p_a, the exit point), the
       earlier seed on ties; ``full`` holds every point.
       First every pair of seeds whose disks overlap gets an order for the cell (:func:`_pair_relations`,
       float32): the earlier first, the later first, or undecided where the order may change inside the cell
       (the projection of the two spheres' intersection circle may cross it); the seeds are put in the first
       sequence (lowest index first) that keeps every decided pair (:func:`_surface_order`), and listed in it
       from then on; a cell with an undecided pair or no such sequence is *undecided*.
       ``"subpoints"``: S x S points at ``t_k = (f32(k) + 0.5) * (h_u / f32(S))``, ``t_l`` likewise with h_v,
       k, l = 0 .. S-1; a point is held when ``(t_k - o_x)^2 + (t_l - o_y)^2 <= r^2`` in float32 (each product
       and sum rounded, no FMA); it goes to the first seed in the sequence that holds it, or, in an undecided
       cell, to the holder of least surface depth (:func:`_first_surface`); share = points won; unit = S^2, so
       nothing is rounded.
       ``"exact"``: :func:`visible_disk_areas` on the seeds in sequence, in float64 (inputs the float32 values
       above), gives share = area / (h_u h_v) * :data:`EXACT_UNIT`. In an undecided cell a :data:`RASTER` x
       :data:`RASTER` raster (the sub-point rule with S = RASTER) moves one unit per point from the first seed
       whose disk holds it to the seed whose surface comes first there, where they differ, and shares below zero
       become zero (:func:`_raster_correction`).
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
    # Study hook: the depth pass without the spheres one other sphere hides (hidden_spheres).
    hidden = None
    if _hidden_rounds:
        hidden = hidden_spheres(c, r64, grid, depth_slots=d, rounds=_hidden_rounds, lamps=lamps, active=active)
    keys, offsets = area_depth_slots(c, r64, grid, depth_slots=d, lamps=lamps, active=active, hidden=hidden)
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
            per[s] = _seeds(cand[s], q, r, a, cu, cv, hu, hv, nu, s, max_seeds)
        any_seed = np.zeros(nu * nv, dtype=bool)
        for s in sides:
            any_seed |= per[s][2] > 0
        cells = np.flatnonzero(any_seed)
        share, total, order = {}, {}, {}
        for s in sides:
            seeds, full, count = per[s]
            stats["cells"] += int((count > 0).sum())
            stats["seeds_gathered"] += int(np.minimum(count, max_seeds).sum())
            stats["seeds"] += int((seeds >= 0).sum())
            stats["max_seeds"] = max(stats["max_seeds"], int(count.max()) if len(count) else 0)
            stats["overflow"] += int((count > max_seeds).sum())
            sh, order[s] = _resolve(
                seeds[cells], full[cells], cells, q, r, a, cu, cv, hu, hv, nu, s, resolver, subpoints, unit
            )
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
            seeds = order[s]
            ok = share[s].sum(axis=1) > 0
            got = np.zeros(share[s].shape, dtype=np.int64)
            got[ok] = _split(share[s][ok], big[ok])
            sign = 1 if s == 0 else -1
            m = seeds >= 0
            np.add.at(units[:, a], seeds[m], sign * got[m])
            if details:
                cells_out[LAMPS[2 * a + s]] = dict(cell=cells, seeds=seeds, share=share[s], units=got, total=total[s])
    return AreaEstimate(units, unit, cells_out, stats)
