"""Float64 NumPy/scipy reference of the wetted-surface mode (:mod:`warp_lamp.wetted`), voxel for voxel.

Written for clarity, with scipy's independent algorithms where they exist: ``ndimage.label`` for the
connectivity to the outside, ``ndimage.distance_transform_edt`` for the dilations, k-d trees for the spheres near a
point. It restates the mode's definition and imports nothing from the modules it checks:

- **Allowed** probe centres: voxel centres x with ``|x - c_i|^2 >= (r_i + rho)^2`` for every sphere; **solid**:
  ``|x - c_i|^2 < r_i^2`` for some sphere.
- **Reached**: allowed voxels 6-connected to the outside of the box (everything beyond the box is).
- **Fluid**: a voxel centre within rho of a reached voxel centre (the probe's offset table), or, when it is not
  solid and lies within rho + one voxel diagonal of one (the *band*), when some *candidate* probe centre z is
  valid: within rho of x, outside every other inflated ball, and reachable, i.e. a reached corner of the
  voxel-centre cube holding z joins z by a segment that enters no inflated ball. Candidates are the critical points
  of the union of inflated balls: radial projections of x (faces), the points of the pairwise intersection circles
  nearest to x (edges), the triple points (vertices); for a point off the lattice also x itself.
- **Crossings**: fluid/dry changes along every voxel row (virtual fluid beyond the box), each to its nearest sphere;
  and **thin chords**: sphere chords that hold no voxel centre, between two fluid samples of a row, merged where
  they overlap or where the gap between them is dry (the exact test at the gap's midpoint), each merged interval an
  entry (to the sphere that starts it) and an exit (to the one that reaches furthest).
- **Walls** (planes ``g(x) = n . x - d``, the fluid where g > 0, as the kernels read them: float32 frame planes
  evaluated in float64 as ``((n0 x0 + n1 x1) + n2 x2) - d``): the probe centre keeps ``g >= rho`` (blocked where
  ``g < rho``), a voxel centre with ``g < 0`` is solid; beyond the box the lattice points with ``g >= rho`` for every
  wall are allowed and reached (all of them, whatever their connection), and the virtual samples within rho of
  those points (spheres aside: the walls' own fluid; ``g >= 0`` for one wall) are fluid. The offset plane g = rho
  is one more surface of the union whose critical points are the candidates: its faces, its circles with inflated
  spheres, the lines of two walls, and the points of a wall with two spheres, of two walls with a sphere, of three
  walls. A sphere wholly inside a wall (``g(c) + r < 0``) is part of the wall: never an owner. A crossing goes to the
  wall with the smallest ``g(p)`` among those cutting its axis when that is below the nearest sphere's
  ``|p - c| - r`` or no sphere lies within the attribution bound; only walls whose normal has a component along the
  row's axis take crossings.

Each decision is the same float64 expression the kernels evaluate, so on inputs that float32 holds exactly (frame
coordinates and radii) the two agree bitwise. Where the kernels' float32 inputs could tip a decision (a voxel
centre within float32 rounding of a probe shell ``r + rho``, two spheres within rounding of the same distance from a
crossing), the reference flags it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warp_lamp.grid import LampGrid
from warp_lamp.validate import check_positive, lamp_mask

__all__ = [
    "WettedReference",
    "attribution_bound",
    "band_radius",
    "dilation_table",
    "dry_certificate",
    "frame_walls",
    "voxel_diagonal",
    "wetted_reference",
    "witness_clearance",
]

#: Unit roundoff of float32.
EPS32 = 2.0**-24
#: Relative slack of the pruning tests (the kernels' ``SLACK``): they drop only what exact arithmetic rules out.
SLACK = 1e-9


@dataclass
class WettedReference:
    """Reference answer; voxel maps are indexed [x, y, z], per-axis items by lamp grid a = 0, 1, 2.

    Attributes:
        shape: Voxels per axis.
        h: Voxel edge per axis [m], shape (3,).
        allowed: Probe centre may stand at the voxel centre, bool (nx, ny, nz).
        allowed_ambiguous: Voxel centre within float32 input rounding of some sphere's shell r + rho.
        solid: Voxel centre strictly inside a sphere, bool (nx, ny, nz).
        reachable: Allowed and 6-connected to the outside, bool (nx, ny, nz).
        band: Within :func:`band_radius` of a reached voxel centre (or the outside), bool (nx, ny, nz).
        fluid: Wetted voxels, bool (nx, ny, nz).
        dilation_near: Voxels whose distance to the reachable set is within 1e-9 of rho or of the band radius
            (decided by the offset tables; a float32 distance test could differ here).
        crossings: Per axis a, a dict of equal-length arrays: ``u``, ``v`` (the ray's lamp cell), ``face`` (index
            along a, 0..n_a, between voxels face-1 and face), ``enters`` (fluid to dry going +a), ``owner``
            (nearest sphere, -1 if none or if a wall took it), ``wall`` (the wall that took it, -1 if none),
            ``distance`` (the nearest sphere's |p - c| - r [m]), ``near_tie`` (a runner-up within float32 input
            rounding).
        thin: Per axis a, a dict of equal-length arrays, one entry per merged thin dry interval: ``u``, ``v``,
            ``face`` (between the samples face-1 and face), ``entry`` and ``exit`` (their spheres).
        thin_faces: Per axis a, thin intervals per ray and face, shape (n_u, n_v, n_a + 1).
        ray_crossings: Per axis a, fluid-to-dry crossings per ray (thin ones included), shape (n_u, n_v).
        virtual: Per axis a, whether each ray's virtual samples just before and after the box are fluid, shape
            (n_u, n_v, 2): the particles' and walls' counts on axis a sum to ``virtual[a][..., 0].sum() -
            virtual[a][..., 1].sum()`` with both lamps on.
        counts: Signed per-particle per-axis counts, (N, 3) int64 (lamps that are off left out).
        hits: Crossings attributed per particle, (N,) int64 (lamps that are off left out).
        wall_counts: Signed counts per wall and axis, (W, 3) int64 (lamps that are off left out).
        walls: The walls' planes in the frame as the kernels read them (float32 values), (W, 4).
        bound: :func:`attribution_bound` per axis [m].
        uncertain: Band voxels that the dilation by rho left dry and that are not solid (given the exact test).
        rescued: Of those, the ones found fluid.
        invalid: Active particles with a non-finite position or radius, or radius <= 0.
        outside: Valid active particles whose sphere pokes out of the box.
        tight: Valid active particles whose sphere inflated by rho reaches past the first layer of virtual voxel
            centres outside the box.
    """

    shape: tuple
    h: np.ndarray
    allowed: np.ndarray
    allowed_ambiguous: np.ndarray
    solid: np.ndarray
    reachable: np.ndarray
    band: np.ndarray
    fluid: np.ndarray
    dilation_near: np.ndarray
    crossings: dict
    thin: dict
    thin_faces: dict
    ray_crossings: dict
    virtual: dict
    counts: np.ndarray
    hits: np.ndarray
    wall_counts: np.ndarray
    walls: np.ndarray
    bound: np.ndarray
    uncertain: int
    rescued: int
    invalid: int
    outside: int
    tight: int


# --- the voxel grid and the probe's offsets ----------------------------------------------------------------------


def _voxel_box(grid: LampGrid) -> tuple[np.ndarray, np.ndarray]:
    """Voxels and edge per axis: axis b is grid (b + 2) % 3's u axis. The three grids must be one voxel grid."""
    n = np.array([grid.counts[(b + 2) % 3, 0] for b in range(3)], dtype=np.int64)
    h = np.array([grid.cell[(b + 2) % 3, 0] for b in range(3)], dtype=np.float64)
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        if tuple(grid.counts[a]) != (n[u], n[v]) or tuple(grid.cell[a]) != (h[u], h[v]):
            raise ValueError("grid: the reference needs one voxel grid (LampGrid(lower, upper, cell_size))")
    return n, h


def voxel_diagonal(h) -> float:
    """``sqrt((hx^2 + hy^2) + hz^2)`` [m]."""
    hx, hy, hz = (float(x) for x in h)
    return float(np.sqrt((hx * hx + hy * hy) + hz * hz))


def band_radius(h, rho) -> float:
    """Every fluid voxel lies within rho + one diagonal of a reached one; ``(rho + diagonal)(1 + 1e-9)`` [m]."""
    return (float(rho) + voxel_diagonal(h)) * (1.0 + 1e-9)


def attribution_bound(h, rho) -> np.ndarray:
    """Per axis, the largest ``|p - c| - r`` of a crossing's nearest sphere: ``rho + sqrt((rho + h_a/2 + g)^2 +
    (h_a/2)^2)``, g the voxel diagonal (fluid is within rho + g of a reached point) [m], shape (3,)."""
    g = voxel_diagonal(h)
    half = 0.5 * np.asarray(h, dtype=np.float64)
    return float(rho) + np.hypot(float(rho) + half + g, half)


def _offset_inside(off, h, rho):
    """Offset (i, j, k) is within rho: ``((i hx)^2 + (j hy)^2) + (k hz)^2 <= rho^2 (1 + 1e-9)``, each square as
    t * t; the slack keeps an offset exactly rho away in, whatever the unit of length rounds h and rho to."""
    t = [off[..., a].astype(np.float64) * h[a] for a in range(3)]
    return ((t[0] * t[0] + t[1] * t[1]) + t[2] * t[2]) <= rho * rho * (1.0 + 1e-9)


def dilation_table(h, rho) -> np.ndarray:
    """``table[|dy|, |dz|]`` = the largest |dx| of an offset within rho, or -1, shape (wy + 1, wz + 1)."""
    h = np.asarray(h, dtype=np.float64)
    w = [int(np.floor(rho / h[a])) + 2 for a in range(3)]
    grid = np.stack(np.meshgrid(*(np.arange(x + 1) for x in w), indexing="ij"), axis=-1)
    inside = _offset_inside(grid, h, float(rho))
    wy = int(np.flatnonzero(inside[0, :, 0]).max())
    wz = int(np.flatnonzero(inside[0, 0, :]).max())
    table = np.full((wy + 1, wz + 1), -1, dtype=np.int64)
    for j in range(wy + 1):
        for k in range(wz + 1):
            xs = np.flatnonzero(inside[:, j, k])
            if len(xs):
                table[j, k] = xs.max()
    return table


# --- voxel maps --------------------------------------------------------------------------------------------------


def _rasterize(local, r, rho, n, h, planes):
    """Allowed (no ``(dx dx + dy dy) + dz dz < (r + rho)^2``, dx = (i + 1/2) hx - cx, and ``g >= rho`` for every
    wall), its rounding flags, and solid (``... < r^2``, or ``g < 0`` for a wall)."""
    blocked = np.zeros(tuple(n), dtype=bool)
    solid = np.zeros(tuple(n), dtype=bool)
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
        solid[tuple(sl)] |= d2 < r[k] * r[k]
        near[tuple(sl)] |= np.abs(np.sqrt(d2) - big) <= tol
    if len(planes):
        g = _plane(planes, _centres(np.indices(tuple(n)).transpose(1, 2, 3, 0), h))
        blocked |= np.any(g < rho, axis=-1)
        solid |= np.any(g < 0.0, axis=-1)
    return ~blocked, near, solid


def _reachable(allowed, planes, h, rho):
    """Allowed voxels 6-connected to an allowed lattice point beyond the box (each of those is reached: the
    outside is, where it keeps rho from every wall)."""
    from scipy import ndimage

    padded = _padded(allowed, planes, h, (1, 1, 1), rho)
    labels, _ = ndimage.label(padded)  # default structure: 6-connectivity
    ring = padded.copy()
    ring[1:-1, 1:-1, 1:-1] = False
    seeds = np.unique(labels[ring])
    return np.isin(labels, seeds[seeds > 0])[1:-1, 1:-1, 1:-1]


def _dilate(reachable, h, radius, table, planes, rho):
    """Voxels within ``radius`` of a reached voxel or of a reached point beyond the box (``g >= rho`` for every
    wall), by scipy's exact Euclidean distance transform on the box padded by the table's widths.

    The EDT's nearest reached voxel decides wherever its distance is clearly off the radius; within 1e-9 of it the
    offset set decides, by brute force over its offsets, so the answer is the table's, exactly.
    """
    from scipy import ndimage

    wy, wz = table.shape[0] - 1, table.shape[1] - 1
    wx = int(table.max())
    # Without walls the nearest reached point beyond the box is on its first layer; with walls it may lie deeper.
    pad = (1, 1, 1) if len(planes) == 0 else (wx + 1, wy + 1, wz + 1)
    padded = _padded(reachable, planes, h, pad, rho)
    inner = tuple(slice(p, -p) for p in pad)
    dist, idx = ndimage.distance_transform_edt(~padded, sampling=h, return_indices=True)
    dist = dist[inner]
    own = np.indices(padded.shape)[(slice(None), *inner)]
    off = np.moveaxis(idx[(slice(None), *inner)] - own, 0, -1)
    out = _offset_inside(off, h, radius)
    near = np.abs(dist - radius) <= 1e-9 * (radius + float(np.max(h)))
    if near.any():
        offs = np.stack(np.meshgrid(*(np.arange(-w, w + 1) for w in (wx, wy, wz)), indexing="ij"), axis=-1)
        offs = offs.reshape(-1, 3)
        offs = offs[_offset_inside(offs, h, radius)]
        big = _padded(reachable, planes, h, (wx, wy, wz), rho)
        pts = np.argwhere(near)
        hit = np.zeros(len(pts), dtype=bool)
        for o in offs:
            q = pts + o + np.array([wx, wy, wz])
            hit |= big[q[:, 0], q[:, 1], q[:, 2]]
        out[near] = hit
    return out, near, dist


# --- the exact test ----------------------------------------------------------------------------------------------


def _dot(a, b):
    """Row-wise ``(a0 b0 + a1 b1) + a2 b2``, the kernels' order."""
    return (a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]) + a[..., 2] * b[..., 2]


def _cross(a, b):
    return np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


def _plane(planes, x):
    """``g = ((n0 x0 + n1 x1) + n2 x2) - d`` for every wall (rows of planes (W, 4)) at every point x (..., 3):
    shape (..., W)."""
    n = planes[:, :3]
    x = np.asarray(x, dtype=np.float64)[..., None, :]
    return ((n[:, 0] * x[..., 0] + n[:, 1] * x[..., 1]) + n[:, 2] * x[..., 2]) - planes[:, 3]


def _centres(idx, h):
    """Voxel centres (i + 1/2) h of integer indices (..., 3), also beyond the box."""
    return (np.asarray(idx, dtype=np.float64) + 0.5) * h


def _outside_ok(planes, idx, h, thr):
    """Lattice points (voxel centres of any index) with ``g >= thr`` for every wall, shape idx.shape[:-1]."""
    if len(planes) == 0:
        return np.ones(np.asarray(idx).shape[:-1], dtype=bool)
    return np.all(_plane(planes, _centres(idx, h)) >= thr, axis=-1)


def _padded(inside, planes, h, pad, thr):
    """``inside`` (nx, ny, nz) padded by ``pad`` (per axis) with the lattice points beyond the box that pass the
    walls (``g >= thr`` for every wall; all of them without walls)."""
    pad = [int(p) for p in pad]
    out = np.pad(inside, [(p, p) for p in pad], constant_values=True)
    if len(planes):
        shape = out.shape
        idx = np.stack(np.meshgrid(*(np.arange(shape[a]) - pad[a] for a in range(3)), indexing="ij"), axis=-1)
        beyond = np.ones(shape, dtype=bool)
        beyond[pad[0] : shape[0] - pad[0], pad[1] : shape[1] - pad[1], pad[2] : shape[2] - pad[2]] = False
        out[beyond] = _outside_ok(planes, idx[beyond], h, thr)
    return out


def _walls_fluid(planes, x, rho):
    """The virtual fluid beyond the box at points x (M, 3): within rho of the convex set of points with ``g >= rho``
    for every wall, decided at its nearest point (x itself, a wall's face point, two walls' line point, three walls'
    corner), which must keep rho from the other walls. Everywhere without walls."""
    x = np.asarray(x, dtype=np.float64).reshape(-1, 3)
    m, nw = len(x), len(planes)
    if nw == 0:
        return np.ones(m, dtype=bool)
    rho2 = rho * rho
    g = _plane(planes, x)
    out = np.all(g >= rho, axis=1)
    n = planes[:, :3]
    tags = np.arange(nw)

    def valid(z, own):
        gz = _plane(planes, z)
        return np.all((gz >= rho) | np.isin(tags, own)[None, :], axis=1) & (_dot(x - z, x - z) <= rho2)

    for w in range(nw):
        z = x - n[w] * ((g[:, w] - rho) / _dot(n[w], n[w]))[:, None]
        out |= valid(z, [w])
    for w in range(nw):
        for v in range(w + 1, nw):
            n1, n2 = n[w], n[v]
            a11, a12, a22 = _dot(n1, n1), _dot(n1, n2), _dot(n2, n2)
            det = a11 * a22 - a12 * a12
            if det > 0.0:
                e1 = rho - g[:, w]
                e2 = rho - g[:, v]
                al = (e1 * a22 - e2 * a12) / det
                be = (e2 * a11 - e1 * a12) / det
                out |= valid((x + n1 * al[:, None]) + n2 * be[:, None], [w, v])
            for u in range(v + 1, nw):
                z, ok = _walls_corners(planes[w : w + 1], planes[v : v + 1], planes[u : u + 1], rho)
                if ok[0]:
                    out |= valid(np.broadcast_to(z, x.shape), [w, v, u])
    return out & np.all(g >= 0.0, axis=1)


def _wall_faces(x, planes, rho):
    """x projected onto every wall's offset plane g = rho, (W, 3)."""
    n = planes[:, :3]
    return x - n * ((_plane(planes, x) - rho) / _dot(n, n))[:, None]


def _circle_nearest(x, m, axis, axis2, rc2, ok):
    """Per row: the point nearest to x on the circle of centre m, squared radius rc2, in the plane normal to
    ``axis`` (``axis2`` its squared length); on the circle's axis, the point toward the coordinate axis along which
    ``axis`` is smallest. Rows where ``ok`` is False hold no meaningful point."""
    q = x - m
    qp = q - axis * (_dot(q, axis) / axis2)[:, None]
    qp2 = _dot(qp, qp)
    for row in np.flatnonzero((qp2 == 0.0) & ok):
        ar = axis[row]
        b = 0
        if abs(ar[1]) < abs(ar[b]):
            b = 1
        if abs(ar[2]) < abs(ar[b]):
            b = 2
        qp[row] = _cross(ar, np.eye(3)[b])
        qp2[row] = _dot(qp[row], qp[row])
    with np.errstate(invalid="ignore", divide="ignore"):
        return m + qp * np.sqrt(rc2 / qp2)[:, None]


def _wall_circle_points(x, c, big, planes, rho):
    """Per row (sphere (c, big), wall plane): the point nearest to x on the circle where the inflated sphere meets
    the offset plane, and whether they meet in a circle (on the circle's axis: toward the coordinate axis along
    which the normal is smallest)."""
    n = planes[:, :3]
    nn = _dot(n, n)
    gc = ((n[:, 0] * c[:, 0] + n[:, 1] * c[:, 1]) + n[:, 2] * c[:, 2]) - planes[:, 3] - rho
    rc2 = big * big - (gc * gc) / nn
    ok = rc2 > 0.0
    return _circle_nearest(x, c - n * (gc / nn)[:, None], n, nn, rc2, ok), ok


def _wall_line_points(x, p1, p2, rho):
    """Per row (two walls): the point nearest to x on the line where their offset planes meet, and whether they do
    (not parallel)."""
    n1, n2 = p1[:, :3], p2[:, :3]
    a11, a12, a22 = _dot(n1, n1), _dot(n1, n2), _dot(n2, n2)
    det = a11 * a22 - a12 * a12
    ok = det > 0.0
    dets = np.where(ok, det, 1.0)
    e1 = rho - (((n1[:, 0] * x[0] + n1[:, 1] * x[1]) + n1[:, 2] * x[2]) - p1[:, 3])
    e2 = rho - (((n2[:, 0] * x[0] + n2[:, 1] * x[1]) + n2[:, 2] * x[2]) - p2[:, 3])
    al = (e1 * a22 - e2 * a12) / dets
    be = (e2 * a11 - e1 * a12) / dets
    return (x + n1 * al[:, None]) + n2 * be[:, None], ok


def _ball_planes_points(ci, bi2, e1, b1, e2, b2):
    """Per row: the two points ``ci + u`` with ``|u|^2 = bi2``, ``e1 . u = b1``, ``e2 . u = b2``, and whether they
    exist."""
    a11, a12, a22 = _dot(e1, e1), _dot(e1, e2), _dot(e2, e2)
    det = a11 * a22 - a12 * a12
    ok = det > 0.0
    dets = np.where(ok, det, 1.0)
    al = (b1 * a22 - b2 * a12) / dets
    be = (b2 * a11 - b1 * a12) / dets
    w0 = e1 * al[:, None] + e2 * be[:, None]
    nrm = _cross(e1, e2)
    nn = _dot(nrm, nrm)
    ok &= nn > 0.0
    g2 = (bi2 - _dot(w0, w0)) / np.where(ok, nn, 1.0)
    ok &= g2 >= 0.0
    g = np.sqrt(np.where(ok, g2, 0.0))
    base = ci + w0
    return base + nrm * g[:, None], base - nrm * g[:, None], ok


def _walls_corners(p1, p2, p3, rho):
    """Per row (three walls): the point where their offset planes meet, and whether it exists."""
    n1, n2, n3 = p1[:, :3], p2[:, :3], p3[:, :3]
    c23 = _cross(n2, n3)
    det = _dot(n1, c23)
    ok = (det != 0.0) & np.isfinite(det)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = (
            (c23 * (p1[:, 3] + rho)[:, None] + _cross(n3, n1) * (p2[:, 3] + rho)[:, None])
            + _cross(n1, n2) * (p3[:, 3] + rho)[:, None]
        ) / np.where(ok, det, 1.0)[:, None]
    return z, ok


def _circle_points(x, ci, bi, cj, bj):
    """Per row: the point of the circle where inflated spheres (ci, bi) and (cj, bj) meet that is nearest to x, and
    whether they meet in a circle. On the circle's axis every point is as near: the one toward the coordinate axis
    along which the centres differ least."""
    e = cj - ci
    l2 = _dot(e, e)
    ok = l2 != 0.0
    l2s = np.where(ok, l2, 1.0)
    bi2 = bi * bi
    frac = ((bi2 - bj * bj) + l2s) / (2.0 * l2s)
    rc2 = bi2 - (frac * frac) * l2s
    ok &= rc2 > 0.0
    return _circle_nearest(x, ci + e * frac[:, None], e, l2s, rc2, ok), ok


def _vertex_points(ci, bi, cj, bj, ck, bk):
    """Per row: the two points where three inflated spheres meet (two planes and a sphere), and whether they do (in
    two points, with centres not collinear)."""
    e1 = cj - ci
    e2 = ck - ci
    a11, a12, a22 = _dot(e1, e1), _dot(e1, e2), _dot(e2, e2)
    det = a11 * a22 - a12 * a12
    ok = det > 0.0
    dets = np.where(ok, det, 1.0)
    bi2 = bi * bi
    b1 = ((bi2 - bj * bj) + a11) * 0.5
    b2 = ((bi2 - bk * bk) + a22) * 0.5
    al = (b1 * a22 - b2 * a12) / dets
    be = (b2 * a11 - b1 * a12) / dets
    w0 = e1 * al[:, None] + e2 * be[:, None]
    nrm = _cross(e1, e2)
    nn = _dot(nrm, nrm)
    ok &= nn > 0.0
    g2 = (bi2 - _dot(w0, w0)) / np.where(ok, nn, 1.0)
    ok &= g2 >= 0.0
    g = np.sqrt(np.where(ok, g2, 0.0))
    base = ci + w0
    return base + nrm * g[:, None], base - nrm * g[:, None], ok


class _Exact:
    """The exact fluid test at any point, over every valid active sphere (frame coordinates)."""

    def __init__(self, local, r, rho, n, h, reachable, exposed, planes):
        from scipy.spatial import cKDTree

        self.c, self.r, self.rho, self.n, self.h = local, r, rho, n, h
        self.planes = planes
        self.big = r + rho
        self.reachable = reachable
        self.exposed = exposed
        self.diag = voxel_diagonal(h)
        self.tree = cKDTree(local) if len(r) else None
        self.rmax = float(r.max()) if len(r) else 0.0
        # Exact copies (same centre and radius) share a group: a candidate on one is on all of them.
        if len(r):
            self.group = np.unique(np.column_stack([local, r]), axis=0, return_inverse=True)[1].reshape(-1)
        else:
            self.group = np.zeros(0, dtype=np.int64)

    def _near(self, x, reach):
        if self.tree is None:
            return np.zeros(0, dtype=np.int64)
        return np.array(sorted(self.tree.query_ball_point(x, reach * (1.0 + 1e-6) + 1e-9)), dtype=np.int64)

    def _own(self, near, own):
        """(M, K): sphere near[k] is one of candidate m's own spheres ``own[m]`` (-1: none) or an exact copy."""
        out = np.zeros((len(own), len(near)), dtype=bool)
        g = self.group[near][None, :]
        for t in range(own.shape[1]):
            s = own[:, t]
            out |= (s >= 0)[:, None] & (g == self.group[np.maximum(s, 0)][:, None])
        return out

    def _reachable(self, z, own, others):
        """Allowed candidate z joined to a reached corner of its voxel-centre cube by a segment that stays outside
        every inflated ball: its own spheres' by the tangent test, the ``others``' by the clamped nearest point."""
        lo = np.clip(np.floor(z / self.h - 0.5), -2.0, self.n + 1.0).astype(np.int64)
        for corner in range(8):
            idx = lo + np.array([corner & 1, (corner >> 1) & 1, (corner >> 2) & 1])
            inside = np.all((idx >= 0) & (idx < self.n))
            if inside and not self.reachable[tuple(idx)]:
                continue
            if not inside and not _outside_ok(self.planes, idx, self.h, self.rho):
                continue
            y = (idx + 0.5) * self.h
            if any(_dot(y - z, z - self.c[s]) < 0.0 for s in own if s >= 0):
                continue
            d = z - y
            dd = _dot(d, d)
            w = y - self.c[others]
            t = np.clip(-_dot(w, d) / dd, 0.0, 1.0) if dd > 0.0 else np.zeros(len(others))
            p = w + d * t[:, None]
            if not np.any(_dot(p, p) < self.big[others] * self.big[others]):
                return True
        return False

    def _any_valid(self, zs, own, near):
        """Whether one of the candidates ``zs`` (M, 3), on the inflated spheres or walls ``own`` (M, 3; -1: none,
        ``-2 - w``: wall w), is allowed (outside every other inflated ball, ``g >= rho`` for every other wall) and
        reachable. A wall never blocks the segment to a reached corner: g is affine, and both ends keep rho."""
        if not len(zs):
            return False
        mine = self._own(near, own)
        v = zs[:, None, :] - self.c[near][None, :, :]
        blocked = (_dot(v, v) < (self.big[near] * self.big[near])[None, :]) & ~mine
        if len(self.planes):
            w = np.arange(len(self.planes))
            own_wall = (own[:, :, None] == (-2 - w)[None, None, :]).any(axis=1)
            blocked = np.concatenate([blocked, (_plane(self.planes, zs) < self.rho) & ~own_wall], axis=1)
        return any(self._reachable(zs[m], own[m], near[~mine[m]]) for m in np.flatnonzero(~blocked.any(axis=1)))

    def fluid(self, x, lattice):
        """Whether x is fluid by the exact test (for a lattice point the caller has checked solid and the
        dilation). All candidates are computed; the kernels stop at the first valid one (same answer)."""
        rho = self.rho
        rho2 = rho * rho
        near = self._near(x, self.rmax + 2.0 * rho + self.diag)
        v = x - self.c[near]
        d2 = _dot(v, v)
        if not lattice:
            if np.any(d2 < self.r[near] * self.r[near]):
                return False
            if len(self.planes) and np.any(_plane(self.planes, x) < 0.0):
                return False
            if self._any_valid(x[None, :], np.full((1, 3), -1), near):
                return True
        g = (self.r[near] + 2.0 * rho) * (1.0 + SLACK)
        keep = self.exposed[near] & (d2 <= g * g)
        ids = near[keep]  # increasing index
        c, big = self.c[ids], self.big[ids]
        v, d2 = v[keep], d2[keep]
        # Faces.
        with np.errstate(invalid="ignore", divide="ignore"):
            z = c + v * (big / np.sqrt(d2))[:, None]
        w = x - z
        sel = (d2 > 0.0) & (_dot(w, w) <= rho2)
        own = np.full((len(ids), 3), -1)
        own[:, 0] = ids
        if self._any_valid(z[sel], own[sel], near):
            return True
        # Edges (pairs a < b), and the vertices (triples a < b < k) on every circle that passes within rho of x.
        pa, pb = np.triu_indices(len(ids), 1)
        z, ok = _circle_points(x, c[pa], big[pa], c[pb], big[pb])
        w = x - z
        e2 = _dot(w, w)
        sel = ok & (e2 <= rho2)
        own = np.stack([ids[pa], ids[pb], np.full(len(pa), -1)], axis=1)
        if self._any_valid(z[sel], own[sel], near):
            return True
        gated = np.flatnonzero(ok & (e2 <= rho2 * (1.0 + SLACK)))
        per = len(ids) - pb[gated] - 1  # third spheres after b
        ta, tb = np.repeat(pa[gated], per), np.repeat(pb[gated], per)
        start = np.repeat(np.cumsum(per) - per, per)
        tk = np.arange(int(per.sum())) - start + tb + 1
        z1, z2, okv = _vertex_points(c[ta], big[ta], c[tb], big[tb], c[tk], big[tk])
        own = np.stack([ids[ta], ids[tb], ids[tk]], axis=1)
        zs = np.concatenate([z1, z2])
        own = np.concatenate([own, own])
        w = x - zs
        sel = np.concatenate([okv, okv]) & (_dot(w, w) <= rho2)
        if self._any_valid(zs[sel], own[sel], near):
            return True
        return self._walls_valid(x, ids, near)

    def _walls_valid(self, x, ids, near):
        """The candidates with a wall, all of them (no gates but the distance): the walls' faces, the circles of the
        spheres ``ids`` with them, the lines of two walls, the points of two spheres and a wall, of a sphere and two
        walls, of three walls."""
        planes, rho = self.planes, self.rho
        nw = len(planes)
        if nw == 0:
            return False
        tag = -2 - np.arange(nw)
        zs, owns = [], []

        def add(z, ok, own):
            w = x - z
            sel = ok & (_dot(w, w) <= rho * rho)
            zs.append(z[sel])
            owns.append(own[sel])

        none = np.full(nw, -1)
        add(_wall_faces(x, planes, rho), np.ones(nw, dtype=bool), np.stack([tag, none, none], axis=1))
        c, big = self.c[ids], self.big[ids]
        si, wi = (a.ravel() for a in np.meshgrid(np.arange(len(ids)), np.arange(nw), indexing="ij"))
        z, ok = _wall_circle_points(x, c[si], big[si], planes[wi], rho)
        add(z, ok, np.stack([ids[si], tag[wi], np.full(len(si), -1)], axis=1))
        w1, w2 = np.triu_indices(nw, 1)
        z, ok = _wall_line_points(x, planes[w1], planes[w2], rho)
        add(z, ok, np.stack([tag[w1], tag[w2], np.full(len(w1), -1)], axis=1))
        # A sphere and two walls.
        si, pi = (a.ravel() for a in np.meshgrid(np.arange(len(ids)), np.arange(len(w1)), indexing="ij"))
        p1, p2 = planes[w1[pi]], planes[w2[pi]]
        ci = c[si]
        b1 = rho - (((p1[:, 0] * ci[:, 0] + p1[:, 1] * ci[:, 1]) + p1[:, 2] * ci[:, 2]) - p1[:, 3])
        b2 = rho - (((p2[:, 0] * ci[:, 0] + p2[:, 1] * ci[:, 1]) + p2[:, 2] * ci[:, 2]) - p2[:, 3])
        z1, z2, ok = _ball_planes_points(ci, big[si] * big[si], p1[:, :3], b1, p2[:, :3], b2)
        own = np.stack([ids[si], tag[w1[pi]], tag[w2[pi]]], axis=1)
        add(np.concatenate([z1, z2]), np.concatenate([ok, ok]), np.concatenate([own, own]))
        # Two spheres (a < b) and a wall.
        pa, pb = np.triu_indices(len(ids), 1)
        qa, wq = (a.ravel() for a in np.meshgrid(np.arange(len(pa)), np.arange(nw), indexing="ij"))
        ia, ib, pl = pa[qa], pb[qa], planes[wq]
        ci = c[ia]
        bi2 = big[ia] * big[ia]
        e1 = c[ib] - ci
        b1 = ((bi2 - big[ib] * big[ib]) + _dot(e1, e1)) * 0.5
        b2 = rho - (((pl[:, 0] * ci[:, 0] + pl[:, 1] * ci[:, 1]) + pl[:, 2] * ci[:, 2]) - pl[:, 3])
        z1, z2, ok = _ball_planes_points(ci, bi2, e1, b1, pl[:, :3], b2)
        own = np.stack([ids[ia], ids[ib], tag[wq]], axis=1)
        add(np.concatenate([z1, z2]), np.concatenate([ok, ok]), np.concatenate([own, own]))
        # Three walls.
        t = np.array(
            [(a, b, k) for a in range(nw) for b in range(a + 1, nw) for k in range(b + 1, nw)], dtype=np.int64
        ).reshape(-1, 3)
        z, ok = _walls_corners(planes[t[:, 0]], planes[t[:, 1]], planes[t[:, 2]], rho)
        add(z, ok, tag[t])
        return self._any_valid(np.concatenate(zs), np.concatenate(owns), near)


def _exposed(local, r, rho, n, h, reachable):
    """Spheres with a reached voxel (or the outside) within r + rho + 2 diagonals: a looser pruning than the
    kernels' (r + rho + one diagonal), so that a sphere the kernels drop wrongly would show as a difference."""
    from scipy import ndimage

    g = voxel_diagonal(h)
    padded = np.pad(reachable, 1, constant_values=True)
    dist = ndimage.distance_transform_edt(~padded, sampling=h)
    idx = np.clip(np.floor(local / h).astype(np.int64) + 1, 0, np.array(padded.shape) - 1)
    d = dist[idx[:, 0], idx[:, 1], idx[:, 2]] - g
    outside = np.any((local - (r + rho + 2 * g)[:, None] <= 0) | (local + (r + rho + 2 * g)[:, None] >= n * h), axis=1)
    return outside | (d <= r + rho + 2.0 * g)


# --- thin chords -------------------------------------------------------------------------------------------------


def _thin_chords(local, r, n, h, a):
    """Every thin chord on the rows along axis a: arrays (sphere, iu, iv, m0, lo, hi). A row meets the open ball
    when ``t^2 < r^2`` (the voxel test with the a-term zero); the chord is thin when none of the centres m0 - 1 ...
    m0 + 2 is inside, ``m0 = floor(c_a / h_a - 1/2)`` in [-1, n_a - 1]."""
    u, v = (a + 1) % 3, (a + 2) % 3
    out = []
    for s in range(len(r)):
        c, rr = local[s], r[s]
        r2 = rr * rr
        f = c[a] / h[a] - 0.5
        if not (f >= -1.0 and f < float(n[a])):
            continue
        m0 = int(np.floor(f))
        iu = np.arange(
            max(int(np.floor((c[u] - rr) / h[u] - 0.5)) - 1, 0), min(int(np.ceil((c[u] + rr) / h[u])), n[u] - 1) + 1
        )
        iv = np.arange(
            max(int(np.floor((c[v] - rr) / h[v] - 0.5)) - 1, 0), min(int(np.ceil((c[v] + rr) / h[v])), n[v] - 1) + 1
        )
        if len(iu) == 0 or len(iv) == 0:
            continue
        gu, gv = np.meshgrid(iu, iv, indexing="ij")
        d = np.zeros((*gu.shape, 3))
        d[..., u] = (gu + 0.5) * h[u] - c[u]
        d[..., v] = (gv + 0.5) * h[v] - c[v]
        t2 = _dot(d, d)
        thin = t2 < r2
        for m in range(m0 - 1, m0 + 3):
            d[..., a] = (m + 0.5) * h[a] - c[a]
            thin &= ~(_dot(d, d) < r2)
        for k in np.flatnonzero(thin.ravel()):
            half = np.sqrt(r2 - t2.ravel()[k])
            out.append((s, gu.ravel()[k], gv.ravel()[k], m0, c[a] - half, c[a] + half))
    return out


def _row_point(a, t, iu, iv, h):
    p = np.zeros(3)
    p[a] = t
    u, v = (a + 1) % 3, (a + 2) % 3
    p[u] = (iu + 0.5) * h[u]
    p[v] = (iv + 0.5) * h[v]
    return p


def _merge_thin(chords, fluid, n, h, a, exact, planes):
    """Merged thin dry intervals between two fluid samples (a virtual sample beyond the box is fluid on the fluid
    side of every wall): list of (iu, iv, face, entry sphere, exit sphere)."""
    groups = {}
    for s, iu, iv, m0, lo, hi in chords:
        groups.setdefault((iu, iv, m0), []).append((lo, s, hi))
    out = []
    for (iu, iv, m0), items in groups.items():
        ok = True
        for m in (m0, m0 + 1):
            idx = [0, 0, 0]
            idx[a], idx[(a + 1) % 3], idx[(a + 2) % 3] = m, iu, iv
            if 0 <= m < n[a]:
                ok &= bool(fluid[tuple(idx)])
            else:
                ok &= bool(_walls_fluid(planes, _centres(np.array(idx), h), exact.rho)[0])
        if not ok:
            continue
        items.sort()
        first, cur, end = None, None, None
        for lo, s, hi in items:
            if first is not None and not (
                lo <= cur or not exact.fluid(_row_point(a, (cur + lo) * 0.5, iu, iv, h), False)
            ):
                out.append((iu, iv, m0 + 1, first, end))
                first = None
            if first is None:
                first, cur, end = s, hi, s
            elif hi > cur or (hi == cur and s < end):
                cur, end = hi, s
        out.append((iu, iv, m0 + 1, first, end))
    return out


# --- attribution -------------------------------------------------------------------------------------------------


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


def frame_walls(walls, grid: LampGrid) -> np.ndarray:
    """Wall planes (W, 4) in world coordinates (n, d: fluid where n . x > d, as ``validate.check_walls`` gives them)
    in the grid's frame, as the kernels read them for positions already in the frame: ``n_f = R^T n``, ``d_f = d -
    n . o`` in float64 (o the frame origin in world coordinates), rounded to float32."""
    planes = np.asarray(walls, dtype=np.float64).reshape(-1, 4)
    n_f = planes[:, :3] @ grid.rotation
    d_f = planes[:, 3] - planes[:, :3] @ grid.world_origin
    return np.concatenate([n_f, d_f[:, None]], axis=1).astype(np.float32).astype(np.float64)


def wetted_reference(
    centers,
    radii,
    grid: LampGrid,
    *,
    probe_radius: float,
    lamps="all",
    active=None,
    allowed=None,
    in_frame=False,
    walls=None,
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
        in_frame: ``centers`` are frame coordinates already (``grid.origin`` is not subtracted): pass the float32
            positions the kernels saw to get their answer bit for bit.
        walls: Optional wall planes (W, 4) in world coordinates (unit normal n into the fluid, offset d; the fluid
            where n . x > d), placed in the frame as :func:`frame_walls` does.
    """
    n, h = _voxel_box(grid)
    rho = check_positive("probe_radius", probe_radius, allow_zero=True)
    mask = lamp_mask(lamps)
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    count = len(r)
    on = np.ones(count, dtype=bool) if active is None else np.asarray(active) != 0
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(c).all(axis=1) & np.isfinite(r) & (r > 0)
    visible = on & valid
    invalid = int((on & ~valid).sum())
    local = c[visible] if in_frame else c[visible] - grid.origin
    rv = r[visible]
    ids = np.flatnonzero(visible)
    size = n * h
    outside = int(np.any((local - rv[:, None] < 0) | (local + rv[:, None] > size), axis=1).sum())
    big = rv[:, None] + rho
    tight = int(np.any((local - big < -0.5 * h) | (local + big > size + 0.5 * h), axis=1).sum())

    planes = frame_walls(np.zeros((0, 4)) if walls is None else walls, grid)
    own_allowed, allowed_near, solid = _rasterize(local, rv, rho, n, h, planes)
    if allowed is None:
        allowed = own_allowed
    else:
        allowed = np.asarray(allowed, dtype=bool)
        if allowed.shape != tuple(n):
            raise ValueError(f"allowed: expected shape {tuple(n)}, got {allowed.shape}")
    reachable = _reachable(allowed, planes, h, rho)
    fluid, near_rho, _ = _dilate(reachable, h, rho, dilation_table(h, rho), planes, rho)
    radius = band_radius(h, rho)
    band, near_band, _ = _dilate(reachable, h, radius, dilation_table(h, radius), planes, rho)

    exact = _Exact(local, rv, rho, n, h, reachable, _exposed(local, rv, rho, n, h, reachable), planes)
    todo = np.argwhere(band & ~fluid & ~solid)
    rescued = 0
    for idx in todo:
        if exact.fluid((idx + 0.5) * h, True):
            fluid[tuple(idx)] = True
            rescued += 1

    tol = 4.0 * EPS32 * ((float(np.abs(local).max()) if len(local) else 0.0) + (float(rv.max()) if len(rv) else 0.0))
    crossings, thin, thin_faces, ray_crossings, virtual = {}, {}, {}, {}, {}
    counts = np.zeros((count, 3), dtype=np.int64)
    hits = np.zeros(count, dtype=np.int64)
    wall_counts = np.zeros((len(planes), 3), dtype=np.int64)
    bound = attribution_bound(h, rho)
    bound_search = bound + 1e-9 * (bound + float(np.linalg.norm(n * h)))
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        f = np.pad(np.transpose(fluid, (u, v, a)), ((0, 0), (0, 0), (1, 1)), constant_values=True)
        if len(planes):
            # The virtual samples just past both ends of every row: the walls' own fluid.
            for end, m in ((0, -1), (-1, int(n[a]))):
                idx = np.zeros((int(n[u]), int(n[v]), 3), dtype=np.int64)
                idx[..., u], idx[..., v] = np.meshgrid(np.arange(n[u]), np.arange(n[v]), indexing="ij")
                idx[..., a] = m
                f[..., end] = _walls_fluid(planes, _centres(idx, h).reshape(-1, 3), rho).reshape(idx.shape[:2])
        virtual[a] = np.stack([f[..., 0], f[..., -1]], axis=-1)
        before, after = f[..., :-1], f[..., 1:]
        iu, iv, face = np.nonzero(before != after)
        enters = ~after[iu, iv, face]
        pts = np.empty((len(face), 3))
        pts[:, a] = face * h[a]
        pts[:, u] = (iu + 0.5) * h[u]
        pts[:, v] = (iv + 0.5) * h[v]
        if len(planes):
            # A sphere wholly inside a wall (g(c) + r < 0) is part of it: never an owner.
            free = ~np.any(_plane(planes, local) + rv[:, None] < 0.0, axis=1)
            owner, dist, tie = _nearest(pts, local[free], rv[free], ids[free], tol)
        else:
            owner, dist, tie = _nearest(pts, local, rv, ids, tol)
        wall = np.full(len(face), -1, dtype=np.int64)
        if len(planes):
            # No sphere within the attribution bound: none (a crossing there is a wall's).
            sphere = (owner >= 0) & (dist <= bound_search[a])
            g_p = _plane(planes, pts)
            cuts = planes[:, a] != 0.0
            rows = np.arange(len(face))
            best_cut = np.argmin(np.where(cuts, g_p, np.inf), axis=1)
            takes = cuts.any() & (~sphere | (g_p[rows, best_cut] < dist))
            wall = np.where(takes, best_cut, -1)
            owner = np.where((wall < 0) & sphere, owner, -1)
        crossings[a] = dict(u=iu, v=iv, face=face, enters=enters, owner=owner, wall=wall, distance=dist, near_tie=tie)
        merged = _merge_thin(_thin_chords(local, rv, n, h, a), fluid, n, h, a, exact, planes)
        tu, tv, tf, te, tx = (np.array([m[k] for m in merged], dtype=np.int64) for k in range(5))
        thin[a] = dict(u=tu, v=tv, face=tf, entry=ids[te] if len(te) else te, exit=ids[tx] if len(tx) else tx)
        tfaces = np.zeros((int(n[u]), int(n[v]), int(n[a]) + 1), dtype=np.int64)
        np.add.at(tfaces, (tu, tv, tf), 1)
        thin_faces[a] = tfaces
        rc = np.zeros((int(n[u]), int(n[v])), dtype=np.int64)
        np.add.at(rc, (iu[enters], iv[enters]), 1)
        np.add.at(rc, (tu, tv), 1)
        ray_crossings[a] = rc
        for side, sel, sign, thin_owner in ((0, enters, 1, thin[a]["entry"]), (1, ~enters, -1, thin[a]["exit"])):
            if not (mask >> (2 * a + side)) & 1:
                continue
            got = sel & (owner >= 0)
            np.add.at(counts[:, a], owner[got], sign)
            np.add.at(hits, owner[got], 1)
            np.add.at(wall_counts[:, a], wall[sel & (wall >= 0)], sign)
            np.add.at(counts[:, a], thin_owner, sign)
            np.add.at(hits, thin_owner, 1)
    return WettedReference(
        shape=tuple(int(x) for x in n),
        h=h,
        allowed=allowed,
        allowed_ambiguous=allowed_near,
        solid=solid,
        reachable=reachable,
        band=band,
        fluid=fluid,
        dilation_near=near_rho | near_band,
        crossings=crossings,
        thin=thin,
        thin_faces=thin_faces,
        ray_crossings=ray_crossings,
        virtual=virtual,
        counts=counts,
        hits=hits,
        wall_counts=wall_counts,
        walls=planes,
        bound=bound,
        uncertain=len(todo),
        rescued=rescued,
        invalid=invalid,
        outside=outside,
        tight=tight,
    )


def dry_certificate(x, centers, radii, rho: float, shrink: float) -> bool:
    """The skin's dry certificate at point x (frame coordinates) [m]: every point within rho of x lies inside some
    ball of radius ``r + rho - shrink`` about the given centres, checked as the kernels do it, in float64 loops.

    The point of the shrunk balls' free set nearest to x is x itself, a radial projection onto a sphere, the point
    of a pairwise circle nearest to x, or a triple point; each within ``rho^2 (1 + 1e-6)`` of x must lie inside
    another ball by 1e-6 (relative, squared). Declined (False): more than 48 spheres within ``r + rho - shrink +
    rho`` of x, x on a circle's axis, nearly tangent balls or nearly collinear triples near x (the kernels' rules;
    no pruning of covered spheres here, which changes no answer).

    Args:
        x: The point, 3 values [m].
        centers: Sphere centres, shape (N, 3) [m] (those the kernels bin: active, finite, near the box).
        radii: Radii, shape (N,) [m].
        rho: Probe radius [m].
        shrink: The skin distance [m].
    """
    x = np.asarray(x, dtype=np.float64)
    c = np.asarray(centers, dtype=np.float64)
    r = np.asarray(radii, dtype=np.float64)
    rs = rho - shrink
    thr2 = rho * rho * (1.0 + 1e-6)
    thr = np.sqrt(thr2)
    big = r + rs
    lim = (big + thr) * (1.0 + SLACK)
    near = [q for q in range(len(r)) if _dot(x - c[q], x - c[q]) < lim[q] * lim[q]]
    if len(near) > 48:
        return False
    cc = [c[q] for q in near]
    bb = [float(big[q]) for q in near]
    n = len(near)

    def covered(z, skip):
        for t in range(n):
            if t not in skip:
                v = z - cc[t]
                if _dot(v, v) < bb[t] * bb[t] * (1.0 - 1e-6):
                    return True
        return False

    inside = False
    for t in range(n):
        d2 = _dot(x - cc[t], x - cc[t])
        if d2 < bb[t] * bb[t] * (1.0 - 1e-6):
            inside = True
            if np.sqrt(d2) + thr < bb[t] * (1.0 - 1e-6):
                return True
    if not inside:
        return False
    for t in range(n):
        v = x - cc[t]
        d2 = _dot(v, v)
        if d2 == 0.0:
            return False
        z = cc[t] + v * (bb[t] / np.sqrt(d2))
        if _dot(x - z, x - z) <= thr2 and not covered(z, (t,)):
            return False
    tiny = 1e-12
    for a in range(n):
        ci, bi = cc[a], bb[a]
        bi2 = bi * bi
        for b in range(a + 1, n):
            cj, bj = cc[b], bb[b]
            e = cj - ci
            l2 = _dot(e, e)
            if l2 == 0.0:
                continue
            frac = ((bi2 - bj * bj) + l2) / (2.0 * l2)
            rc2 = bi2 - (frac * frac) * l2
            m = ci + e * frac
            xm = x - m
            tol = tiny * (bi2 + bj * bj)
            if rc2 <= tol:
                near_t = thr + 1e-5 * (bi + bj)
                if rc2 >= -tol and _dot(xm, xm) <= near_t * near_t:
                    return False
                continue
            qe = _dot(xm, e)
            qp = xm - e * (qe / l2)
            qp2 = _dot(qp, qp)
            if qp2 <= tiny * rc2:
                if (qe * qe) / l2 + rc2 * 0.999 <= thr2:
                    return False
                continue
            z = m + qp * np.sqrt(rc2 / qp2)
            e2 = _dot(x - z, x - z)
            if e2 <= thr2 and not covered(z, (a, b)):
                return False
            if e2 > thr2 * (1.0 + 1e-6):
                continue
            for k in range(b + 1, n):
                ck, bk = cc[k], bb[k]
                f = ck - ci
                a12 = _dot(e, f)
                a22 = _dot(f, f)
                det = l2 * a22 - a12 * a12
                if det <= 1e-6 * l2 * a22:
                    if a22 == 0.0 or _dot(ck - cj, ck - cj) == 0.0:
                        continue
                    return False
                b1 = ((bi2 - bj * bj) + l2) * 0.5
                b2 = ((bi2 - bk * bk) + a22) * 0.5
                al = (b1 * a22 - b2 * a12) / det
                be = (b2 * l2 - b1 * a12) / det
                w0 = e * al + f * be
                nrm = _cross(e, f)
                nn = _dot(nrm, nrm)
                g2 = (bi2 - _dot(w0, w0)) / nn
                base = ci + w0
                if abs(g2) <= tiny * bi2 / nn:
                    near_t = thr + 1e-5 * bi
                    if _dot(x - base, x - base) <= near_t * near_t:
                        return False
                    continue
                if g2 < 0.0:
                    continue
                g = np.sqrt(g2)
                for z in (base + nrm * g, base - nrm * g):
                    if _dot(x - z, x - z) <= thr2 and not covered(z, (a, b, k)):
                        return False
    return True


def witness_clearance(z, y, own, centers, radii, rho: float, cap: float) -> float:
    """The skin's margin of a wet voxel's witness [m], by brute force over every sphere: the least distance by which
    the inflated balls (radius ``r + rho``) of all spheres but the candidate's own keep out of the probe centre z
    and of the segment from z to the lattice point y, at most ``cap``.

    Args:
        z: The candidate probe centre, 3 values [m] (frame coordinates).
        y: The reached lattice point (a corner of z's voxel-centre cube), 3 values [m].
        own: Indices of the spheres z lies on (1 to 3; the others' balls are measured).
        centers: Sphere centres, shape (N, 3) [m].
        radii: Radii, shape (N,) [m].
        rho: Probe radius [m].
        cap: The largest margin reported [m].
    """
    z = np.asarray(z, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    c = np.asarray(centers, dtype=np.float64)
    big = np.asarray(radii, dtype=np.float64) + rho
    others = np.ones(len(c), dtype=bool)
    others[[int(i) for i in own]] = False
    c, big = c[others], big[others]
    if len(c) == 0:
        return float(cap)
    point = np.linalg.norm(c - z, axis=1) - big
    d = z - y
    dd = float(d @ d)
    s = np.clip(((c - y) @ d) / dd, 0.0, 1.0) if dd > 0.0 else np.zeros(len(c))
    segment = np.linalg.norm(c - y - s[:, None] * d, axis=1) - big
    return float(min(cap, point.min(), segment.min()))
