"""Wetted-surface kernels: a rolling-probe fluid region on the lamp's voxel grid, and every crossing loaded.

Voxel grid: the lamp's box grid, ``n = (nx, ny, nz)`` voxels of edge ``h``, centres at ``(index + 1/2) h`` in frame
coordinates. Every voxel map is a bitmap of 32-bit words along x: word ``w`` of row ``(j, k)`` sits at
``(k ny + j) nwx + w`` and holds voxels ``x = 32 w + b`` in bit ``b``. Bits at ``x >= nx`` are padding.

Pipeline of one update (each step's decisions are exact, so CPU and CUDA agree bitwise):

1. ``wet_rasterize``: one thread per sphere marks ``blocked`` every voxel whose centre is closer than
   ``r + rho`` (float64 test, the reference evaluates the same expression), inserts the sphere into a
   linked-list bin grid for the nearest-sphere search, and counts invalid and outside particles.
2. Connectivity to the outside, rounds of directional sweeps (x, y, z) until a frontier check finds no
   allowed voxel left next to a reached one (``wp.capture_while``), or ``max_rounds``.
3. Dilation of the reached set by the probe's offset set: a pass along y builds planes
   ``Q_m`` = "some reached voxel within the table's x-reach in some row j, for |dz| = m"; a pass along z ORs them.
   Run twice: by rho (``fluid``, certainly wet) and by rho + the voxel diagonal (``band``, possibly wet).
4. ``wet_expose`` flags the spheres with a reached voxel within r + rho + diagonal (only they can hold a probe
   centre that is reachable); ``wet_classify`` decides every voxel of ``band`` that is not yet fluid by exact
   distances (``probe_reaches``): fluid iff a reachable probe centre lies within rho of its centre.
5. Crossings along every x, y and z row, virtual fluid past both ends; each one goes to its nearest sphere.
6. ``wet_thin``: a sphere chord that holds no voxel centre, between two fluid samples of a row, is a dry interval
   the samples cannot see; overlapping ones (or ones whose gap is dry) merge, and each merged interval loads an
   entry and an exit crossing.

Walls (``LampWalls``, planes in the frame; none: every result as without them): ``wet_rasterize_walls`` adds them to
the blocked (``g < rho``) and solid (``g < 0``) maps, the outside is reached only where it keeps rho from every wall
(runs along x, ``wall_row_run``), the virtual samples past the box are the walls' own fluid (``walls_fluid``), the
exact test has the offset planes among its candidates (``wall_search``), and a crossing nearer a wall that cuts its
axis than to any sphere goes to the wall (``load_crossing``, ``wall_counts``).
"""

from typing import Any

import warp as wp

from warp_lamp.kernels.walls import LampWalls, plane_value
from warp_lamp.kernels.wetted_base import (
    CANDIDATE_OK,
    CERT_IN,
    CERT_LIST,
    CERT_NEAR,
    CERT_TINY,
    CONDITIONED,
    DEEP,
    DIAG_GAPS,
    DIAG_RESCUED,
    DIAG_THIN,
    DIAG_UNCERTAIN,
    GATHER,
    KEEP_ABS,
    KEEP_CAP,
    KEEP_REL,
    MARGIN_PENDING,
    MASK_SPHERES,
    QUEUE_SPREAD,
    QUEUE_SPREAD_FROM,
    REACH_POINTS,
    REACH_ROWS,
    SKIN_CERTIFIED,
    SKIN_COUNT,
    SKIN_CROSS_FILLED,
    SKIN_CROSS_KEPT,
    SKIN_CROSS_WIPE,
    SKIN_FILLED,
    SKIN_HELD,
    SKIN_KEPT,
    SKIN_LAST,
    SKIN_PRIMED,
    SKIN_RESET,
    SKIN_RESETS,
    SKIN_WIPE,
    SKIN_WITNESSED,
    SLACK,
    WALL_SLACK,
    WALL_TAG,
    BinSpan,
    CertIds,
    Chord,
    DeepDepths,
    DeepIds,
    GatherIds,
    NearList,
    ReachMasks,
    ReachPoints,
    Vec8d,
    WetBox,
    WitMargin,
    bin_head,
    bin_span,
    centre_offset,
    cross3,
    dot3,
    low_mask,
    lowest_bit,
    no_margin,
    row_mask,
    span_from,
    table_claim,
    table_find,
    virtual_point,
    voxel_centre,
    wall_face_point,
    wall_line_point,
    wall_normal,
    walls_allow,
    walls_corner,
    walls_fluid,
    word_at,
    word_coords,
)

# The same options in every module of the wetted surface (kernels/wetted_base.py says why).
wp.set_module_options({"enable_backward": False, "fuse_fp": False, "max_unroll": 1})


@wp.func
def outside_ok(walls: LampWalls, thr: wp.float64, ijk: wp.vec3i, box: WetBox) -> wp.bool:
    """The voxel centre ijk (any index, also beyond the box) has ``g >= thr`` for every wall: the same test as
    ``wall_row_run``'s, point by point."""
    p = wp.vec3d(voxel_centre(ijk[0], box.h[0]), voxel_centre(ijk[1], box.h[1]), voxel_centre(ijk[2], box.h[2]))
    for w in range(walls.n):
        if not (plane_value(walls.frame[w], p) >= thr):
            return False
    return True


@wp.func
def centre_of(i: wp.int32, positions: wp.array[wp.vec3]) -> wp.vec3d:
    p = positions[i]
    return wp.vec3d(wp.float64(p[0]), wp.float64(p[1]), wp.float64(p[2]))


@wp.func
def same_sphere(q: wp.int32, s: wp.int32, positions: wp.array[wp.vec3], radii: wp.array[wp.float32]) -> wp.bool:
    """q is s, or a copy of it (same float32 centre and radius): a candidate on s is on q too."""
    if s < 0:
        return False
    if q == s:
        return True
    a = positions[q]
    b = positions[s]
    return a[0] == b[0] and a[1] == b[1] and a[2] == b[2] and radii[q] == radii[s]


@wp.func
def defining(
    q: wp.int32, i: wp.int32, j: wp.int32, k: wp.int32, positions: wp.array[wp.vec3], radii: wp.array[wp.float32]
) -> wp.bool:
    return (
        same_sphere(q, i, positions, radii)
        or same_sphere(q, j, positions, radii)
        or same_sphere(q, k, positions, radii)
    )


@wp.func
def reached_at(
    ix: wp.int32, iy: wp.int32, iz: wp.int32, reach: wp.array[wp.uint32], box: WetBox, walls: LampWalls
) -> wp.bool:
    """Voxel (ix, iy, iz) reached; a lattice point beyond the box is when it keeps rho from every wall."""
    if ix < 0 or iy < 0 or iz < 0 or ix >= box.n[0] or iy >= box.n[1] or iz >= box.n[2]:
        return outside_ok(walls, box.rho, wp.vec3i(ix, iy, iz), box)
    word = reach[word_at(box, ix / 32, iy, iz)]
    return ((word >> wp.uint32(ix % 32)) & wp.uint32(1)) != wp.uint32(0)


@wp.func
def tangent_ok(y: wp.vec3d, z: wp.vec3d, s: wp.int32, positions: wp.array[wp.vec3]) -> wp.bool:
    """The segment from z (on inflated sphere s) toward y leaves s's ball outward or along its tangent plane."""
    if s < 0:
        return True
    return dot3(y - z, z - centre_of(s, positions)) >= wp.float64(0.0)


@wp.func
def inside_inflated(
    z: wp.vec3d, q: wp.int32, positions: wp.array[wp.vec3], radii: wp.array[wp.float32], box: WetBox
) -> wp.bool:
    big = wp.float64(radii[q]) + box.rho
    v = z - centre_of(q, positions)
    return dot3(v, v) < big * big


@wp.func
def blocked_point(
    x: wp.vec3d,
    z: wp.vec3d,
    i: wp.int32,
    j: wp.int32,
    k: wp.int32,
    reach: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    box: WetBox,
) -> wp.int32:
    """A sphere other than the candidate's own (i, j, k and their copies) that has z strictly inside its inflated
    ball (the rasterizer's allowed test, ``|z - c|^2 < (r + rho)^2``), or -1. Searched around x, which is within
    rho of z: every ball holding z has its centre within r_max + 2 rho of x."""
    span = bin_span(x, reach, box)
    for bz in range(span.lo[2], span.hi[2] + 1):
        for by in range(span.lo[1], span.hi[1] + 1):
            for bx in range(span.lo[0], span.hi[0] + 1):
                q = bin_head(bx, by, bz, box, heads)
                while q >= 0:
                    if inside_inflated(z, q, positions, radii, box):
                        if not defining(q, i, j, k, positions, radii):
                            return q
                    q = next_in_bin[q]
    return -1


@wp.func
def segment_cut(
    y: wp.vec3d,
    d: wp.vec3d,
    dd: wp.float64,
    mid: wp.vec3d,
    half: wp.float64,
    q: wp.int32,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    box: WetBox,
) -> wp.bool:
    """The segment from y along d (``dd = |d|^2``; midpoint ``mid``, half-length ``half``) passes strictly inside
    sphere q's inflated ball: its nearest point to the centre, at the clamped parameter, is closer than r + rho.
    Every point of the segment lies within ``half`` of ``mid``, so a centre farther than r + rho + half (with
    slack for rounding) is out of reach without the nearest point's division: most gathered spheres are."""
    big = wp.float64(radii[q]) + box.rho
    c = centre_of(q, positions)
    e = c - mid
    reach = (big + half) * (wp.float64(1.0) + SLACK)
    if dot3(e, e) > reach * reach:
        return False
    w = y - c
    s = wp.float64(0.0)
    if dd > wp.float64(0.0):
        s = wp.clamp(-dot3(w, d) / dd, wp.float64(0.0), wp.float64(1.0))
    p = w + d * s
    return dot3(p, p) < big * big


@wp.func
def segment_blocked(
    x: wp.vec3d,
    y: wp.vec3d,
    z: wp.vec3d,
    i: wp.int32,
    j: wp.int32,
    k: wp.int32,
    reach: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    box: WetBox,
) -> wp.bool:
    """The segment y-z passes strictly inside the inflated ball of a sphere other than the candidate's own (those
    are checked by ``tangent_ok``): its nearest point to the centre, at the clamped parameter t, is closer than
    r + rho. Searched around x: the segment is within rho + diagonal of x."""
    d = z - y
    dd = dot3(d, d)
    mid = y + d * wp.float64(0.5)
    half = wp.sqrt(dd) * wp.float64(0.5)
    span = bin_span(x, reach, box)
    for bz in range(span.lo[2], span.hi[2] + 1):
        for by in range(span.lo[1], span.hi[1] + 1):
            for bx in range(span.lo[0], span.hi[0] + 1):
                q = bin_head(bx, by, bz, box, heads)
                while q >= 0:
                    if segment_cut(y, d, dd, mid, half, q, positions, radii, box):
                        if not defining(q, i, j, k, positions, radii):
                            return True
                    q = next_in_bin[q]
    return False


@wp.func
def cube_corner_low(z: wp.vec3d, box: WetBox):
    """(lo, clamped): the lowest corner of the voxel-centre cube that holds z, clamped to the box's surroundings
    [-2, n + 1], and 1 when the clamp moved it (its corners may then lie farther from z)."""
    lo = wp.vec3i(0)
    clamped = int(0)
    for a in range(3):
        u = wp.floor(z[a] / box.h[a] - wp.float64(0.5))
        f = wp.clamp(u, wp.float64(-2.0), wp.float64(box.n[a] + 1))
        if f != u:
            clamped = 1
        lo[a] = wp.int32(f)
    return lo, clamped


@wp.func
def reached_corners(lo: wp.vec3i, reach: wp.array[wp.uint32], box: WetBox, walls: LampWalls) -> wp.int32:
    """Bit c set: corner c = dx + 2 dy + 4 dz of the cube at ``lo`` is reached (``reached_at``). Read before a
    candidate's searches: most candidates have no reached corner (97% of the checks on the specimen at rho = r),
    and then nothing else about them matters. Inside the box and one word wide, four independent word loads."""
    ix = lo[0]
    iy = lo[1]
    iz = lo[2]
    if ix >= 0 and iy >= 0 and iz >= 0 and ix + 1 < box.n[0] and iy + 1 < box.n[1] and iz + 1 < box.n[2]:
        if ix % 32 != 31:
            w = ix / 32
            s = wp.uint32(ix % 32)
            r00 = reach[word_at(box, w, iy, iz)]
            r10 = reach[word_at(box, w, iy + 1, iz)]
            r01 = reach[word_at(box, w, iy, iz + 1)]
            r11 = reach[word_at(box, w, iy + 1, iz + 1)]
            three = wp.uint32(3)
            bits = ((r00 >> s) & three) | (((r10 >> s) & three) << wp.uint32(2))
            bits = bits | (((r01 >> s) & three) << wp.uint32(4)) | (((r11 >> s) & three) << wp.uint32(6))
            return wp.int32(bits)
    m = int(0)
    for corner in range(8):
        if reached_at(ix + (corner & 1), iy + ((corner >> 1) & 1), iz + ((corner >> 2) & 1), reach, box, walls):
            m = m | (1 << corner)
    return m


@wp.func
def candidate_check(
    x: wp.vec3d,
    z: wp.vec3d,
    i: wp.int32,
    j: wp.int32,
    k: wp.int32,
    hint: wp.int32,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
) -> wp.int32:
    """Probe centre z, on inflated spheres or offset walls i, j, k (-1: none; ``WALL_TAG - w``: wall w), within rho
    of x: ``CANDIDATE_OK`` when it is allowed and reachable; else the sphere that blocks it (>= 0, tried first as the
    next call's ``hint``: neighbouring candidates are mostly blocked by the same sphere; the answer does not depend
    on it), or -1. Allowed: outside every other inflated ball and ``g >= rho`` for every other wall. A wall never
    blocks the segment to a reached corner: g is affine, the corner keeps rho from every wall and z from every wall
    but its own, on whose offset plane it lies. Without a reached corner z is not valid, whatever blocks it: -1
    before any search."""
    lo, _clamped = cube_corner_low(z, box)
    corners = reached_corners(lo, reach, box, walls)
    if corners == 0:
        return -1
    if hint >= 0:
        if inside_inflated(z, hint, positions, radii, box):
            if not defining(hint, i, j, k, positions, radii):
                return hint
    if not walls_allow(z, i, j, k, walls, box.rho):
        return -1
    near = (rmax + wp.float64(2.0) * box.rho) * (wp.float64(1.0) + SLACK)
    blocker = blocked_point(x, z, i, j, k, near, positions, radii, heads, next_in_bin, box)
    if blocker >= 0:
        return blocker
    far = (rmax + wp.float64(2.0) * box.rho + box.diag) * (wp.float64(1.0) + SLACK)
    for corner in range(8):
        ix = lo[0] + (corner & 1)
        iy = lo[1] + ((corner >> 1) & 1)
        iz = lo[2] + ((corner >> 2) & 1)
        if ((corners >> corner) & 1) != 0:
            y = wp.vec3d(
                (wp.float64(ix) + wp.float64(0.5)) * box.h[0],
                (wp.float64(iy) + wp.float64(0.5)) * box.h[1],
                (wp.float64(iz) + wp.float64(0.5)) * box.h[2],
            )
            if tangent_ok(y, z, i, positions) and tangent_ok(y, z, j, positions) and tangent_ok(y, z, k, positions):
                if not segment_blocked(x, y, z, i, j, k, far, positions, radii, heads, next_in_bin, box):
                    return CANDIDATE_OK
    return -1


@wp.func
def candidate_check_list(
    x: wp.vec3d,
    z: wp.vec3d,
    i: wp.int32,
    j: wp.int32,
    k: wp.int32,
    hint: wp.int32,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
    gathered: Any,
    gbase: wp.int32,
    gstride: wp.int32,
    ng: wp.int32,
) -> wp.int32:
    """``candidate_check`` for z within rho of x, its blocker and segment searches over the spheres ``gather_near``
    collected around x (``gathered[gbase + t * gstride]`` for t < ng, as ``gather_near`` stored them; ng -1: too many,
    so the bins are walked). The same answer and the same blocker:
    the list holds, in the bins' order, every sphere of the bins that the walks visit that can hold z (centre within
    r + 2 rho of x) or cut a segment from z to a corner of its voxel-centre cube (within r + 2 rho + diagonal) and
    only the spheres beyond, which can do neither. A corner clamped to the box's surroundings may lie farther from
    z: then the segments walk the bins."""
    if ng < 0:
        return candidate_check(x, z, i, j, k, hint, rmax, positions, radii, heads, next_in_bin, reach, box, walls)
    lo, clamped = cube_corner_low(z, box)
    corners = reached_corners(lo, reach, box, walls)
    if corners == 0:
        return -1
    if hint >= 0:
        if inside_inflated(z, hint, positions, radii, box):
            if not defining(hint, i, j, k, positions, radii):
                return hint
    if not walls_allow(z, i, j, k, walls, box.rho):
        return -1
    for t in range(ng):
        q = gathered[gbase + t * gstride]
        if inside_inflated(z, q, positions, radii, box):
            if not defining(q, i, j, k, positions, radii):
                return q
    far = (rmax + wp.float64(2.0) * box.rho + box.diag) * (wp.float64(1.0) + SLACK)
    for corner in range(8):
        ix = lo[0] + (corner & 1)
        iy = lo[1] + ((corner >> 1) & 1)
        iz = lo[2] + ((corner >> 2) & 1)
        if ((corners >> corner) & 1) != 0:
            y = wp.vec3d(
                (wp.float64(ix) + wp.float64(0.5)) * box.h[0],
                (wp.float64(iy) + wp.float64(0.5)) * box.h[1],
                (wp.float64(iz) + wp.float64(0.5)) * box.h[2],
            )
            if tangent_ok(y, z, i, positions) and tangent_ok(y, z, j, positions) and tangent_ok(y, z, k, positions):
                if clamped != 0:
                    if not segment_blocked(x, y, z, i, j, k, far, positions, radii, heads, next_in_bin, box):
                        return CANDIDATE_OK
                else:
                    d = z - y
                    dd = dot3(d, d)
                    mid = y + d * wp.float64(0.5)
                    half = wp.sqrt(dd) * wp.float64(0.5)
                    cut = int(0)
                    for t in range(ng):
                        q = gathered[gbase + t * gstride]
                        if segment_cut(y, d, dd, mid, half, q, positions, radii, box):
                            if not defining(q, i, j, k, positions, radii):
                                cut = 1
                                break
                    if cut == 0:
                        return CANDIDATE_OK
    return -1


@wp.func
def gather_near(
    store: Any,
    base: wp.int32,
    stride: wp.int32,
    x: wp.vec3d,
    span: BinSpan,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    box: WetBox,
) -> tuple[Any, wp.int32, wp.int32]:
    """(store, n, n_near): the spheres whose centres lie within (r + 2 rho + diagonal)(1 + slack) of x, from the
    bins within (rmax + 2 rho + diagonal)(1 + slack) of x: first those of the bins ``span`` (the candidates' blocker
    search, in its walk order), then the others. Every sphere that can hold a candidate within rho of x or cut a
    segment from it to a corner of its voxel-centre cube is among them: ``store[base + t * stride]`` for t < n, the
    first ``n_near`` from the bins of ``span`` (n -1: more than ``box.gather``). ``store`` is a local ``GatherIds``
    (base 0, stride 1; filled and returned) or a scratch array (a row per thread, interleaved so that a warp's lanes
    coalesce; filled in place): passed to the candidates' checks, an array costs no copy, where a local list is
    copied whole into each call (measured: six copies of the list in the queued tests' frame)."""
    n = int(0)
    n_near = int(0)
    far = (rmax + wp.float64(2.0) * box.rho + box.diag) * (wp.float64(1.0) + SLACK)
    fs = bin_span(x, far, box)
    for part in range(2):
        for bz in range(fs.lo[2], fs.hi[2] + 1):
            for by in range(fs.lo[1], fs.hi[1] + 1):
                for bx in range(fs.lo[0], fs.hi[0] + 1):
                    inner = (
                        bx >= span.lo[0]
                        and bx <= span.hi[0]
                        and by >= span.lo[1]
                        and by <= span.hi[1]
                        and bz >= span.lo[2]
                        and bz <= span.hi[2]
                    )
                    if inner == (part == 0) and n >= 0:
                        q = bin_head(bx, by, bz, box, heads)
                        while q >= 0 and n >= 0:
                            lim = (wp.float64(radii[q]) + wp.float64(2.0) * box.rho + box.diag) * (
                                wp.float64(1.0) + SLACK
                            )
                            v = x - centre_of(q, positions)
                            if dot3(v, v) <= lim * lim:
                                if n < box.gather:
                                    store[base + n * stride] = q
                                    n += 1
                                else:
                                    n = -1
                            q = next_in_bin[q]
        if part == 0:
            n_near = n
    return store, n, n_near


@wp.func
def gate_ok(
    x: wp.vec3d, q: wp.int32, positions: wp.array[wp.vec3], radii: wp.array[wp.float32], box: WetBox
) -> wp.bool:
    """Inflated sphere q passes within rho of x (with slack): only then can it carry an edge or vertex candidate."""
    v = x - centre_of(q, positions)
    g = (wp.float64(radii[q]) + wp.float64(2.0) * box.rho) * (wp.float64(1.0) + SLACK)
    return dot3(v, v) <= g * g


@wp.func
def circle_nearest(x: wp.vec3d, m: wp.vec3d, axis: wp.vec3d, axis2: wp.float64, rc2: wp.float64) -> wp.vec4d:
    """The point nearest to x on the circle of centre m, squared radius rc2 > 0, in the plane normal to ``axis``
    (``axis2`` its squared length), and 1 in the last component. On the circle's axis every point is as near: the
    one toward the coordinate axis along which ``axis`` is smallest."""
    q = x - m
    qp = q - axis * (dot3(q, axis) / axis2)
    qp2 = dot3(qp, qp)
    if qp2 == wp.float64(0.0):
        b = int(0)
        if wp.abs(axis[1]) < wp.abs(axis[b]):
            b = 1
        if wp.abs(axis[2]) < wp.abs(axis[b]):
            b = 2
        unit = wp.vec3d(0.0)
        unit[b] = wp.float64(1.0)
        qp = cross3(axis, unit)
        qp2 = dot3(qp, qp)
    z = m + qp * wp.sqrt(rc2 / qp2)
    return wp.vec4d(z[0], z[1], z[2], wp.float64(1.0))


@wp.func
def circle_point(x: wp.vec3d, ci: wp.vec3d, big_i: wp.float64, cj: wp.vec3d, big_j: wp.float64) -> wp.vec4d:
    """The point nearest to x on the circle where the inflated spheres (ci, big_i) and (cj, big_j) meet, and 1 in
    the last component; 0 there when they do not meet in a circle. On the circle's axis every point is as near:
    the one toward the coordinate axis along which the centres differ least."""
    e = cj - ci
    l2 = dot3(e, e)
    out = wp.vec4d(0.0)
    if l2 == wp.float64(0.0):
        return out
    bi2 = big_i * big_i
    frac = ((bi2 - big_j * big_j) + l2) / (wp.float64(2.0) * l2)
    rc2 = bi2 - (frac * frac) * l2
    if rc2 <= wp.float64(0.0):
        return out
    return circle_nearest(x, ci + e * frac, e, l2, rc2)


@wp.func
def vertex_points(
    ci: wp.vec3d, big_i: wp.float64, cj: wp.vec3d, big_j: wp.float64, ck: wp.vec3d, big_k: wp.float64
) -> wp.mat33d:
    """The two points where three inflated spheres meet, as rows 0 and 1, and (1, 0, 0) in row 2; row 2 is 0 when
    they do not meet in two points (or their centres are collinear)."""
    out = wp.mat33d(0.0)
    e1 = cj - ci
    e2 = ck - ci
    a11 = dot3(e1, e1)
    a12 = dot3(e1, e2)
    a22 = dot3(e2, e2)
    det = a11 * a22 - a12 * a12
    if det <= wp.float64(0.0):
        return out
    bi2 = big_i * big_i
    b1 = ((bi2 - big_j * big_j) + a11) * wp.float64(0.5)
    b2 = ((bi2 - big_k * big_k) + a22) * wp.float64(0.5)
    al = (b1 * a22 - b2 * a12) / det
    be = (b2 * a11 - b1 * a12) / det
    w0 = e1 * al + e2 * be
    nrm = cross3(e1, e2)
    nn = dot3(nrm, nrm)
    if nn <= wp.float64(0.0):
        return out
    g2 = (bi2 - dot3(w0, w0)) / nn
    if g2 < wp.float64(0.0):
        return out
    g = wp.sqrt(g2)
    base = ci + w0
    z1 = base + nrm * g
    z2 = base - nrm * g
    return wp.mat33d(z1[0], z1[1], z1[2], z2[0], z2[1], z2[2], wp.float64(1.0), wp.float64(0.0), wp.float64(0.0))


@wp.func
def vertex_walk(
    x: wp.vec3d,
    i: wp.int32,
    j: wp.int32,
    ci: wp.vec3d,
    big_i: wp.float64,
    cj: wp.vec3d,
    big_j: wp.float64,
    span: BinSpan,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    exposed: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
) -> wp.bool:
    """A valid candidate among the triple points of inflated spheres i < j < k, k exposed and near x (bin walk)."""
    rho2 = box.rho * box.rho
    for bz in range(span.lo[2], span.hi[2] + 1):
        for by in range(span.lo[1], span.hi[1] + 1):
            for bx in range(span.lo[0], span.hi[0] + 1):
                k = bin_head(bx, by, bz, box, heads)
                while k >= 0:
                    if k > j and exposed[k] != 0 and gate_ok(x, k, positions, radii, box):
                        ck = centre_of(k, positions)
                        vp = vertex_points(ci, big_i, cj, big_j, ck, wp.float64(radii[k]) + box.rho)
                        if vp[2, 0] != wp.float64(0.0):
                            for s in range(2):
                                z = wp.vec3d(vp[s, 0], vp[s, 1], vp[s, 2])
                                w = x - z
                                if dot3(w, w) <= rho2:
                                    res = candidate_check(
                                        x, z, i, j, k, -1, rmax, positions, radii, heads, next_in_bin, reach, box, walls
                                    )
                                    if res == CANDIDATE_OK:
                                        return True
                    k = next_in_bin[k]
    return False


@wp.func
def cert_cap_covered(
    x: wp.vec3d, ci: wp.vec3d, big_i: wp.float64, cj: wp.vec3d, big_j: wp.float64, reach: wp.float64
) -> wp.bool:
    """``cap_covered`` for given balls: every point of sphere (ci, big_i) within ``reach`` of x lies inside ball
    (cj, big_j), by 1e-6 in squared distance."""
    v = x - ci
    d2 = dot3(v, v)
    e = cj - ci
    l2 = dot3(e, e)
    if d2 == wp.float64(0.0) or l2 == wp.float64(0.0):
        return False
    d = wp.sqrt(d2)
    el = wp.sqrt(l2)
    ca = (big_i * big_i + d2 - reach * reach) / (wp.float64(2.0) * big_i * d)
    if ca >= wp.float64(1.0):
        return False
    far2 = (big_i + el) * (big_i + el)
    if ca > wp.float64(-1.0):
        cg = wp.clamp(dot3(v, e) / (d * el), wp.float64(-1.0), wp.float64(1.0))
        if cg + ca >= wp.float64(0.0):
            sa = wp.sqrt(wp.float64(1.0) - ca * ca)
            sg = wp.sqrt(wp.max(wp.float64(1.0) - cg * cg, wp.float64(0.0)))
            far2 = (big_i * big_i + l2) - wp.float64(2.0) * big_i * el * (cg * ca - sg * sa)
    return far2 < big_j * big_j * (wp.float64(1.0) - wp.float64(1.0e-6))


@wp.func
def cap_covered(
    x: wp.vec3d, i: wp.int32, j: wp.int32, positions: wp.array[wp.vec3], radii: wp.array[wp.float32], box: WetBox
) -> wp.bool:
    """Every point of inflated sphere i within rho of x lies inside inflated ball j, with a relative margin of
    1e-6 in squared distance: then every candidate on sphere i (face, edge or vertex) is blocked by j, and the
    search may drop i (pruning: the answer is the same; the margin covers the rounding of the candidates). The cap
    is the set of points of sphere i at angle <= alpha from x's direction, ``cos alpha = (R_i^2 + d^2 - rho^2) /
    (2 R_i d)``; its farthest point from c_j is at angle gamma + alpha from c_j's direction (the antipode when that
    passes pi)."""
    if same_sphere(j, i, positions, radii):
        return False
    rho = box.rho
    return cert_cap_covered(
        x, centre_of(i, positions), wp.float64(radii[i]) + rho, centre_of(j, positions), wp.float64(radii[j]) + rho, rho
    )


@wp.func
def covered_by_deep(
    x: wp.vec3d,
    i: wp.int32,
    top: DeepIds,
    ntop: wp.int32,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    box: WetBox,
) -> wp.bool:
    """Sphere i's cap within rho of x lies inside one of the ``ntop`` inflated balls ``top``."""
    for t in range(ntop):
        if cap_covered(x, i, top[t], positions, radii, box):
            return True
    return False


@wp.func
def probe_walk(
    x: wp.vec3d,
    span: BinSpan,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    exposed: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
) -> wp.bool:
    """``probe_reaches``'s search over faces, edges and vertices by walking the bins (for more near spheres than
    the local list holds): the same candidates, pairs and triples in increasing index order."""
    rho = box.rho
    rho2 = rho * rho
    for bz in range(span.lo[2], span.hi[2] + 1):
        for by in range(span.lo[1], span.hi[1] + 1):
            for bx in range(span.lo[0], span.hi[0] + 1):
                i = bin_head(bx, by, bz, box, heads)
                while i >= 0:
                    if exposed[i] != 0 and gate_ok(x, i, positions, radii, box):
                        c = centre_of(i, positions)
                        v = x - c
                        d2 = dot3(v, v)
                        if d2 > wp.float64(0.0):
                            z = c + v * ((wp.float64(radii[i]) + rho) / wp.sqrt(d2))
                            w = x - z
                            if dot3(w, w) <= rho2:
                                res = candidate_check(
                                    x, z, i, -1, -1, -1, rmax, positions, radii, heads, next_in_bin, reach, box, walls
                                )
                                if res == CANDIDATE_OK:
                                    return True
                    i = next_in_bin[i]
    for bz in range(span.lo[2], span.hi[2] + 1):
        for by in range(span.lo[1], span.hi[1] + 1):
            for bx in range(span.lo[0], span.hi[0] + 1):
                i = bin_head(bx, by, bz, box, heads)
                while i >= 0:
                    if exposed[i] != 0 and gate_ok(x, i, positions, radii, box):
                        ci = centre_of(i, positions)
                        big_i = wp.float64(radii[i]) + rho
                        for bz2 in range(span.lo[2], span.hi[2] + 1):
                            for by2 in range(span.lo[1], span.hi[1] + 1):
                                for bx2 in range(span.lo[0], span.hi[0] + 1):
                                    j = bin_head(bx2, by2, bz2, box, heads)
                                    while j >= 0:
                                        if j > i and exposed[j] != 0 and gate_ok(x, j, positions, radii, box):
                                            cj = centre_of(j, positions)
                                            big_j = wp.float64(radii[j]) + rho
                                            cp = circle_point(x, ci, big_i, cj, big_j)
                                            if cp[3] != wp.float64(0.0):
                                                z = wp.vec3d(cp[0], cp[1], cp[2])
                                                w = x - z
                                                e2 = dot3(w, w)
                                                if e2 <= rho2:
                                                    res = candidate_check(
                                                        x,
                                                        z,
                                                        i,
                                                        j,
                                                        -1,
                                                        -1,
                                                        rmax,
                                                        positions,
                                                        radii,
                                                        heads,
                                                        next_in_bin,
                                                        reach,
                                                        box,
                                                        walls,
                                                    )
                                                    if res == CANDIDATE_OK:
                                                        return True
                                                if e2 <= rho2 * (wp.float64(1.0) + SLACK):
                                                    if vertex_walk(
                                                        x,
                                                        i,
                                                        j,
                                                        ci,
                                                        big_i,
                                                        cj,
                                                        big_j,
                                                        span,
                                                        rmax,
                                                        positions,
                                                        radii,
                                                        heads,
                                                        next_in_bin,
                                                        exposed,
                                                        reach,
                                                        box,
                                                        walls,
                                                    ):
                                                        return True
                                        j = next_in_bin[j]
                    i = next_in_bin[i]
    return False


@wp.func
def wall_near(x: wp.vec3d, pl: wp.vec4, rho: wp.float64) -> wp.bool:
    """The wall's offset plane passes within rho of x (with slack: the normal is unit to float32 rounding), so it
    can carry a candidate within rho of x (a pruning; the distance test decides)."""
    return wp.abs(plane_value(pl, x) - rho) <= rho * (wp.float64(1.0) + WALL_SLACK)


@wp.func
def wall_circle_point(x: wp.vec3d, c: wp.vec3d, big: wp.float64, pl: wp.vec4, rho: wp.float64) -> wp.vec4d:
    """The point nearest to x on the circle where the inflated sphere (c, big) meets the wall's offset plane, and 1
    in the last component; 0 there when they do not meet in a circle. On the circle's axis every point is as near:
    the one toward the coordinate axis along which the normal is smallest."""
    out = wp.vec4d(0.0)
    n = wall_normal(pl)
    nn = dot3(n, n)
    gc = plane_value(pl, c) - rho
    rc2 = big * big - (gc * gc) / nn
    if not (rc2 > wp.float64(0.0)):
        return out
    return circle_nearest(x, c - n * (gc / nn), n, nn, rc2)


@wp.func
def ball_planes_points(
    ci: wp.vec3d, bi2: wp.float64, e1: wp.vec3d, b1: wp.float64, e2: wp.vec3d, b2: wp.float64
) -> wp.mat33d:
    """The two points ``ci + u`` with ``|u|^2 = bi2``, ``e1 . u = b1`` and ``e2 . u = b2`` (a sphere and two planes,
    as ``vertex_points`` solves it), as rows 0 and 1, and (1, 0, 0) in row 2; row 2 is 0 when there are none."""
    out = wp.mat33d(0.0)
    a11 = dot3(e1, e1)
    a12 = dot3(e1, e2)
    a22 = dot3(e2, e2)
    det = a11 * a22 - a12 * a12
    if not (det > wp.float64(0.0)):
        return out
    al = (b1 * a22 - b2 * a12) / det
    be = (b2 * a11 - b1 * a12) / det
    w0 = e1 * al + e2 * be
    nrm = cross3(e1, e2)
    nn = dot3(nrm, nrm)
    if not (nn > wp.float64(0.0)):
        return out
    g2 = (bi2 - dot3(w0, w0)) / nn
    if not (g2 >= wp.float64(0.0)):
        return out
    g = wp.sqrt(g2)
    base = ci + w0
    z1 = base + nrm * g
    z2 = base - nrm * g
    return wp.mat33d(z1[0], z1[1], z1[2], z2[0], z2[1], z2[2], wp.float64(1.0), wp.float64(0.0), wp.float64(0.0))


@wp.func
def try_candidate(
    x: wp.vec3d,
    z: wp.vec3d,
    i: wp.int32,
    j: wp.int32,
    k: wp.int32,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
) -> wp.bool:
    """z is within rho of x and a valid candidate (``candidate_check``)."""
    w = x - z
    if not (dot3(w, w) <= box.rho * box.rho):
        return False
    res = candidate_check(x, z, i, j, k, -1, rmax, positions, radii, heads, next_in_bin, reach, box, walls)
    return res == CANDIDATE_OK


@wp.func
def walls_only_candidates(
    x: wp.vec3d,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
) -> wp.bool:
    """Candidates on walls alone: their faces, the lines of pairs, the corners of triples (on lines within rho)."""
    rho = box.rho
    for w in range(walls.n):
        p1 = walls.frame[w]
        if wall_near(x, p1, rho):
            z = wall_face_point(x, p1, rho)
            if try_candidate(x, z, WALL_TAG - w, -1, -1, rmax, positions, radii, heads, next_in_bin, reach, box, walls):
                return True
    for w in range(walls.n):
        p1 = walls.frame[w]
        if wall_near(x, p1, rho):
            for v in range(w + 1, walls.n):
                p2 = walls.frame[v]
                if wall_near(x, p2, rho):
                    lp = wall_line_point(x, p1, p2, rho)
                    if lp[3] != wp.float64(0.0):
                        z = wp.vec3d(lp[0], lp[1], lp[2])
                        t1 = WALL_TAG - w
                        t2 = WALL_TAG - v
                        if try_candidate(
                            x, z, t1, t2, -1, rmax, positions, radii, heads, next_in_bin, reach, box, walls
                        ):
                            return True
                        e = x - z
                        if dot3(e, e) <= rho * rho * (wp.float64(1.0) + SLACK):
                            for u in range(v + 1, walls.n):
                                p3 = walls.frame[u]
                                if wall_near(x, p3, rho):
                                    cp = walls_corner(p1, p2, p3, rho)
                                    if cp[3] != wp.float64(0.0):
                                        z = wp.vec3d(cp[0], cp[1], cp[2])
                                        t3 = WALL_TAG - u
                                        if try_candidate(
                                            x,
                                            z,
                                            t1,
                                            t2,
                                            t3,
                                            rmax,
                                            positions,
                                            radii,
                                            heads,
                                            next_in_bin,
                                            reach,
                                            box,
                                            walls,
                                        ):
                                            return True
    return False


@wp.func
def wall_sphere_candidates(
    x: wp.vec3d,
    i: wp.int32,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
) -> wp.bool:
    """Candidates on sphere i and walls: the circles where it meets each wall's offset plane, and the points where
    it meets two of them (on circles within rho)."""
    rho = box.rho
    ci = centre_of(i, positions)
    big_i = wp.float64(radii[i]) + rho
    for w in range(walls.n):
        p1 = walls.frame[w]
        if wall_near(x, p1, rho):
            cp = wall_circle_point(x, ci, big_i, p1, rho)
            if cp[3] != wp.float64(0.0):
                z = wp.vec3d(cp[0], cp[1], cp[2])
                t1 = WALL_TAG - w
                if try_candidate(x, z, i, t1, -1, rmax, positions, radii, heads, next_in_bin, reach, box, walls):
                    return True
                e = x - z
                if dot3(e, e) <= rho * rho * (wp.float64(1.0) + SLACK):
                    for v in range(w + 1, walls.n):
                        p2 = walls.frame[v]
                        if wall_near(x, p2, rho):
                            vp = ball_planes_points(
                                ci,
                                big_i * big_i,
                                wall_normal(p1),
                                rho - plane_value(p1, ci),
                                wall_normal(p2),
                                rho - plane_value(p2, ci),
                            )
                            if vp[2, 0] != wp.float64(0.0):
                                for t in range(2):
                                    z = wp.vec3d(vp[t, 0], vp[t, 1], vp[t, 2])
                                    if try_candidate(
                                        x,
                                        z,
                                        i,
                                        t1,
                                        WALL_TAG - v,
                                        rmax,
                                        positions,
                                        radii,
                                        heads,
                                        next_in_bin,
                                        reach,
                                        box,
                                        walls,
                                    ):
                                        return True
    return False


@wp.func
def wall_pair_candidates(
    x: wp.vec3d,
    i: wp.int32,
    j: wp.int32,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
) -> wp.bool:
    """Candidates where inflated spheres i < j meet a wall's offset plane (on their circle, when it passes within
    rho of x)."""
    rho = box.rho
    ci = centre_of(i, positions)
    cj = centre_of(j, positions)
    big_i = wp.float64(radii[i]) + rho
    big_j = wp.float64(radii[j]) + rho
    cp = circle_point(x, ci, big_i, cj, big_j)
    if cp[3] == wp.float64(0.0):
        return False
    e = x - wp.vec3d(cp[0], cp[1], cp[2])
    if not (dot3(e, e) <= rho * rho * (wp.float64(1.0) + SLACK)):
        return False
    bi2 = big_i * big_i
    e1 = cj - ci
    b1 = ((bi2 - big_j * big_j) + dot3(e1, e1)) * wp.float64(0.5)
    for w in range(walls.n):
        pl = walls.frame[w]
        if wall_near(x, pl, rho):
            vp = ball_planes_points(ci, bi2, e1, b1, wall_normal(pl), rho - plane_value(pl, ci))
            if vp[2, 0] != wp.float64(0.0):
                for t in range(2):
                    z = wp.vec3d(vp[t, 0], vp[t, 1], vp[t, 2])
                    if try_candidate(
                        x, z, i, j, WALL_TAG - w, rmax, positions, radii, heads, next_in_bin, reach, box, walls
                    ):
                        return True
    return False


@wp.func
def wall_search(
    x: wp.vec3d,
    ids: NearList,
    cnt: wp.int32,
    listed: wp.int32,
    span: BinSpan,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    exposed: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
) -> wp.bool:
    """``probe_reaches``'s candidates that involve a wall: on walls alone, then with the near spheres, from its list
    (``listed`` 1, spheres in increasing index order; a pruned sphere's candidates lie in another ball) or by
    walking the bins (``listed`` 0: exposed spheres within r + 2 rho of x, pairs i < j)."""
    if walls.n == 0:
        return False
    if walls_only_candidates(x, rmax, positions, radii, heads, next_in_bin, reach, box, walls):
        return True
    if listed != 0:
        for a in range(cnt):
            i = ids[a]
            if wall_sphere_candidates(x, i, rmax, positions, radii, heads, next_in_bin, reach, box, walls):
                return True
            for b in range(a + 1, cnt):
                if wall_pair_candidates(x, i, ids[b], rmax, positions, radii, heads, next_in_bin, reach, box, walls):
                    return True
        return False
    for bz in range(span.lo[2], span.hi[2] + 1):
        for by in range(span.lo[1], span.hi[1] + 1):
            for bx in range(span.lo[0], span.hi[0] + 1):
                i = bin_head(bx, by, bz, box, heads)
                while i >= 0:
                    if exposed[i] != 0 and gate_ok(x, i, positions, radii, box):
                        if wall_sphere_candidates(x, i, rmax, positions, radii, heads, next_in_bin, reach, box, walls):
                            return True
                        for bz2 in range(span.lo[2], span.hi[2] + 1):
                            for by2 in range(span.lo[1], span.hi[1] + 1):
                                for bx2 in range(span.lo[0], span.hi[0] + 1):
                                    j = bin_head(bx2, by2, bz2, box, heads)
                                    while j >= 0:
                                        if j > i and exposed[j] != 0 and gate_ok(x, j, positions, radii, box):
                                            if wall_pair_candidates(
                                                x, i, j, rmax, positions, radii, heads, next_in_bin, reach, box, walls
                                            ):
                                                return True
                                        j = next_in_bin[j]
                    i = next_in_bin[i]
    return False


@wp.func
def reach_masks(
    x: wp.vec3d,
    ids: NearList,
    cnt: wp.int32,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
):
    """(masks, on): bit p of ``masks[a]`` set when the p-th reached lattice point within rho + diagonal of x lies
    within r + rho + diagonal of sphere ``ids[a]``'s centre (slack 1e-6). A valid candidate z within rho of x needs
    a reached corner of its voxel-centre cube, which lies within one diagonal of z, hence of every inflated sphere
    z is on: so a candidate on spheres whose masks share no bit is not valid, and need not be computed. ``on`` is
    0 (try every candidate) with fewer than ``box.mask_from`` or more than ``MASK_SPHERES`` spheres or
    ``REACH_POINTS`` points, too many rows, or x near enough to the box's surroundings that a candidate's cube could
    be clamped (its corners then need not lie near z)."""
    masks = ReachMasks()
    if cnt > MASK_SPHERES or cnt < box.mask_from:
        return masks, 0
    rho = box.rho
    loose = wp.float64(1.0) + WALL_SLACK
    lo = wp.vec3i(0)
    hi = wp.vec3i(0)
    far = (rho + box.diag) * loose
    for a in range(3):
        h = box.h[a]
        # No clamped cube: every z within rho of x has -2 <= floor(z / h - 1/2) <= n + 1.
        if x[a] - rho * loose < wp.float64(-1.5) * h * (wp.float64(1.0) - WALL_SLACK):
            return masks, 0
        if x[a] + rho * loose >= (wp.float64(box.n[a]) + wp.float64(2.5)) * h * (wp.float64(1.0) - WALL_SLACK):
            return masks, 0
        lo[a] = wp.int32(wp.ceil((x[a] - far) / h - wp.float64(0.5)))
        hi[a] = wp.int32(wp.floor((x[a] + far) / h - wp.float64(0.5)))
    if (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1) > REACH_ROWS or hi[0] - lo[0] >= 1024:
        return masks, 0
    far2 = far * far
    pts = ReachPoints()
    k = int(0)
    for iz in range(lo[2], hi[2] + 1):
        for iy in range(lo[1], hi[1] + 1):
            inside = iy >= 0 and iz >= 0 and iy < box.n[1] and iz < box.n[2]
            ix = lo[0]
            while ix <= hi[0]:
                bits = wp.uint32(0)
                step = int(1)
                if inside and ix >= 0 and ix < box.n[0]:
                    # The rest of this word at once.
                    w = ix / 32
                    top = wp.min(hi[0], wp.min(32 * w + 31, box.n[0] - 1))
                    step = top - ix + 1
                    bits = (reach[word_at(box, w, iy, iz)] >> wp.uint32(ix - 32 * w)) & low_mask(step)
                elif outside_ok(walls, rho, wp.vec3i(ix, iy, iz), box):
                    # Beyond the box: reached when it keeps rho from every wall (``reached_at``).
                    bits = wp.uint32(1)
                while bits != wp.uint32(0):
                    b = lowest_bit(bits)
                    bits = bits & (bits - wp.uint32(1))
                    y = wp.vec3d(voxel_centre(ix + b, box.h[0]), voxel_centre(iy, box.h[1]), voxel_centre(iz, box.h[2]))
                    v = y - x
                    if dot3(v, v) <= far2:
                        if k == REACH_POINTS:
                            return masks, 0
                        pts[k] = ((iz - lo[2]) * 1024 + (iy - lo[1])) * 1024 + (ix + b - lo[0])
                        k += 1
                ix += step
    for a in range(cnt):
        c = centre_of(ids[a], positions)
        lim = (wp.float64(radii[ids[a]]) + rho + box.diag) * loose
        lim2 = lim * lim
        m = wp.uint64(0)
        for p in range(k):
            q = pts[p]
            y = wp.vec3d(
                voxel_centre(lo[0] + q % 1024, box.h[0]),
                voxel_centre(lo[1] + (q / 1024) % 1024, box.h[1]),
                voxel_centre(lo[2] + q / (1024 * 1024), box.h[2]),
            )
            v = y - c
            if dot3(v, v) <= lim2:
                m = m | (wp.uint64(1) << wp.uint64(p))
        masks[a] = m
    return masks, 1


@wp.func
def conditioned(ci: wp.vec3d, cj: wp.vec3d, ck: wp.vec3d) -> wp.bool:
    """The centres are far from collinear (``CONDITIONED``): the triple's computed points lie on its spheres."""
    e1 = cj - ci
    e2 = ck - ci
    a11 = dot3(e1, e1)
    a12 = dot3(e1, e2)
    a22 = dot3(e2, e2)
    return a11 * a22 - a12 * a12 >= CONDITIONED * (a11 * a22)


@wp.func
def probe_search(
    x: wp.vec3d,
    lattice: wp.int32,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    exposed: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
    store: Any,
    sbase: wp.int32,
    sstride: wp.int32,
) -> wp.vec4i:
    """``probe_reaches`` with its witness: (i, j, k, t) of the valid candidate it found on spheres alone (a radial
    projection on i: j = k = -1; a circle point of i < j: k = -1; point t of the triple i < j < k), (-1, ...) for
    one found otherwise (x itself, a wall's, or by the bin-walk search), (-2, ...) for none.

    Whether x, outside every sphere, is fluid by exact distances: some candidate probe centre within rho of it is
    allowed and reachable (``candidate_check``). Candidates: x itself (only for a point off the lattice,
    ``lattice`` 0: a voxel centre's own reach is the connectivity's), the radial projections of x onto the
    inflated spheres, the points nearest to x on their pairwise circles, and their triple points (pairs and triples
    in increasing index order, triples only on circles that pass within rho); then those with walls
    (``wall_search``). Only exposed spheres (``wet_expose``) within r + 2 rho of x can carry a reachable candidate
    within rho. For a voxel centre the caller has checked the solid map (``|x - c|^2 < r^2`` or ``g < 0``); for
    another point it is checked here."""
    rho = box.rho
    rho2 = rho * rho
    near = (rmax + wp.float64(2.0) * rho) * (wp.float64(1.0) + SLACK)
    span = bin_span(x, near, box)
    # The spheres every candidate's searches visit, gathered once (the walks repeated them per candidate).
    gids, gn, gnear = gather_near(store, sbase, sstride, x, span, rmax, positions, radii, heads, next_in_bin, box)
    if lattice == 0:
        for wi in range(walls.n):
            if plane_value(walls.frame[wi], x) < wp.float64(0.0):
                return wp.vec4i(-2, -1, -1, 0)
        sspan = bin_span(x, rmax * (wp.float64(1.0) + SLACK), box)
        for bz in range(sspan.lo[2], sspan.hi[2] + 1):
            for by in range(sspan.lo[1], sspan.hi[1] + 1):
                for bx in range(sspan.lo[0], sspan.hi[0] + 1):
                    q = bin_head(bx, by, bz, box, heads)
                    while q >= 0:
                        r = wp.float64(radii[q])
                        v = x - centre_of(q, positions)
                        if dot3(v, v) < r * r:
                            return wp.vec4i(-2, -1, -1, 0)
                        q = next_in_bin[q]
        if (
            candidate_check_list(
                x,
                x,
                -1,
                -1,
                -1,
                -1,
                rmax,
                positions,
                radii,
                heads,
                next_in_bin,
                reach,
                box,
                walls,
                gids,
                sbase,
                sstride,
                gn,
            )
            == CANDIDATE_OK
        ):
            return wp.vec4i(-1, -1, -1, 0)
    # The exposed spheres near x, less those whose cap within rho of x another sphere's inflated ball covers:
    # first the DEEP balls that hold x deepest (they cover most), then the listed ones. With more near than the
    # list holds (``box.near_list``), a second walk keeps only those the deep balls leave; with more of those, the
    # bin-walk search (the same answer, slower).
    limit = box.near_list
    ids = NearList()
    cnt = int(0)
    top = DeepIds()
    depth = DeepDepths()
    ntop = int(0)
    if gn >= 0:
        for t in range(gnear):
            i = gids[sbase + t * sstride]
            big = wp.float64(radii[i]) + rho
            v = x - centre_of(i, positions)
            d2 = dot3(v, v)
            if d2 < big * big:
                dep = big - wp.sqrt(d2)
                if ntop < DEEP or dep > depth[DEEP - 1]:
                    slot = wp.min(ntop, DEEP - 1)
                    if ntop < DEEP:
                        ntop += 1
                    while slot > 0 and depth[slot - 1] < dep:
                        depth[slot] = depth[slot - 1]
                        top[slot] = top[slot - 1]
                        slot -= 1
                    depth[slot] = dep
                    top[slot] = i
            if exposed[i] != 0 and gate_ok(x, i, positions, radii, box):
                if cnt < limit:
                    ids[cnt] = i
                cnt += 1
    else:
        for bz in range(span.lo[2], span.hi[2] + 1):
            for by in range(span.lo[1], span.hi[1] + 1):
                for bx in range(span.lo[0], span.hi[0] + 1):
                    i = bin_head(bx, by, bz, box, heads)
                    while i >= 0:
                        big = wp.float64(radii[i]) + rho
                        v = x - centre_of(i, positions)
                        d2 = dot3(v, v)
                        if d2 < big * big:
                            dep = big - wp.sqrt(d2)
                            if ntop < DEEP or dep > depth[DEEP - 1]:
                                slot = wp.min(ntop, DEEP - 1)
                                if ntop < DEEP:
                                    ntop += 1
                                while slot > 0 and depth[slot - 1] < dep:
                                    depth[slot] = depth[slot - 1]
                                    top[slot] = top[slot - 1]
                                    slot -= 1
                                depth[slot] = dep
                                top[slot] = i
                        if exposed[i] != 0 and gate_ok(x, i, positions, radii, box):
                            if cnt < limit:
                                ids[cnt] = i
                            cnt += 1
                        i = next_in_bin[i]
    if cnt > limit:
        cnt = int(0)
        if gn >= 0:
            for t in range(gnear):
                i = gids[sbase + t * sstride]
                if exposed[i] != 0 and gate_ok(x, i, positions, radii, box):
                    if not covered_by_deep(x, i, top, ntop, positions, radii, box):
                        if cnt < limit:
                            ids[cnt] = i
                        cnt += 1
        else:
            for bz in range(span.lo[2], span.hi[2] + 1):
                for by in range(span.lo[1], span.hi[1] + 1):
                    for bx in range(span.lo[0], span.hi[0] + 1):
                        i = bin_head(bx, by, bz, box, heads)
                        while i >= 0:
                            if exposed[i] != 0 and gate_ok(x, i, positions, radii, box):
                                if not covered_by_deep(x, i, top, ntop, positions, radii, box):
                                    if cnt < limit:
                                        ids[cnt] = i
                                    cnt += 1
                            i = next_in_bin[i]
        if cnt > limit:
            if probe_walk(x, span, rmax, positions, radii, heads, next_in_bin, exposed, reach, box, walls):
                return wp.vec4i(-1, -1, -1, 0)
            if wall_search(x, ids, 0, 0, span, rmax, positions, radii, heads, next_in_bin, exposed, reach, box, walls):
                return wp.vec4i(-1, -1, -1, 0)
            return wp.vec4i(-2, -1, -1, 0)
    if (box.skip & 8) != 0:
        return wp.vec4i(-2, -1, -1, 0)
    kept = wp.uint64(0)
    for a in range(cnt):
        covered = int(0)
        if cnt < box.prune_from:
            covered = -1
        elif covered_by_deep(x, ids[a], top, ntop, positions, radii, box):
            covered = 1
        b = int(0)
        while b < cnt and covered == 0:
            if b != a and cap_covered(x, ids[a], ids[b], positions, radii, box):
                covered = 1
            b += 1
        if covered <= 0:
            kept = kept | (wp.uint64(1) << wp.uint64(a))
    m = int(0)
    for a in range(cnt):
        if ((kept >> wp.uint64(a)) & wp.uint64(1)) != wp.uint64(0):
            ids[m] = ids[a]
            m += 1
    cnt = m
    # Increasing index order (insertion sort), so that pairs and triples come as the bin walk takes them.
    for a in range(1, cnt):
        key = ids[a]
        b = a - 1
        while b >= 0 and ids[b] > key:
            ids[b + 1] = ids[b]
            b -= 1
        ids[b + 1] = key
    hint = int(-1)
    if (box.skip & 16) != 0:
        return wp.vec4i(-2, -1, -1, 0)
    # Called below the threshold too (it returns at once): masks assigned in a branch are merged by a whole-vector
    # copy.
    masks, masked = reach_masks(x, ids, cnt, positions, radii, reach, box, walls)
    all_bits = ~wp.uint64(0)
    # Faces: the commonest answer, so first.
    for a in range(cnt * wp.where((box.skip & 4) != 0, 0, 1)):
        if masked != 0:
            if masks[a] == wp.uint64(0):
                continue
        i = ids[a]
        c = centre_of(i, positions)
        v = x - c
        d2 = dot3(v, v)
        if d2 > wp.float64(0.0):
            z = c + v * ((wp.float64(radii[i]) + rho) / wp.sqrt(d2))
            w = x - z
            if dot3(w, w) <= rho2:
                res = candidate_check_list(
                    x,
                    z,
                    i,
                    -1,
                    -1,
                    hint,
                    rmax,
                    positions,
                    radii,
                    heads,
                    next_in_bin,
                    reach,
                    box,
                    walls,
                    gids,
                    sbase,
                    sstride,
                    gn,
                )
                if res == CANDIDATE_OK:
                    return wp.vec4i(i, -1, -1, 0)
                if res >= 0:
                    hint = res
    # Edges, and the vertices on every circle that passes within rho of x.
    for a in range(cnt):
        i = ids[a]
        ci = centre_of(i, positions)
        big_i = wp.float64(radii[i]) + rho
        mask_a = all_bits
        if masked != 0:
            mask_a = masks[a]
        # Every candidate of a pair or triple led by sphere a lies on its inflated sphere (to rounding, however
        # ill-conditioned the triple: its points are built on a's sphere).
        if mask_a == wp.uint64(0):
            continue
        for b in range(a + 1, cnt * wp.where((box.skip & 2) != 0, 0, 1)):
            mask_ab = mask_a
            if masked != 0:
                mask_ab = mask_a & masks[b]
            j = ids[b]
            cj = centre_of(j, positions)
            big_j = wp.float64(radii[j]) + rho
            cp = circle_point(x, ci, big_i, cj, big_j)
            if cp[3] != wp.float64(0.0):
                z = wp.vec3d(cp[0], cp[1], cp[2])
                w = x - z
                e2 = dot3(w, w)
                # A circle point lies on both inflated spheres (to rounding): without a point in both masks, it has
                # no reached corner. The pair's triples are still enumerated (an ill-conditioned one's points need
                # not lie on sphere j).
                if e2 <= rho2 and mask_ab != wp.uint64(0):
                    res = candidate_check_list(
                        x,
                        z,
                        i,
                        j,
                        -1,
                        hint,
                        rmax,
                        positions,
                        radii,
                        heads,
                        next_in_bin,
                        reach,
                        box,
                        walls,
                        gids,
                        sbase,
                        sstride,
                        gn,
                    )
                    if res == CANDIDATE_OK:
                        return wp.vec4i(i, j, -1, 0)
                    if res >= 0:
                        hint = res
                if e2 <= rho2 * (wp.float64(1.0) + SLACK) and (box.skip & 1) == 0:
                    for e in range(b + 1, cnt):
                        k = ids[e]
                        ck = centre_of(k, positions)
                        if masked != 0:
                            if (mask_ab & masks[e]) == wp.uint64(0):
                                if conditioned(ci, cj, ck):
                                    continue
                        big_k = wp.float64(radii[k]) + rho
                        vp = vertex_points(ci, big_i, cj, big_j, ck, big_k)
                        if vp[2, 0] != wp.float64(0.0):
                            for t in range(2):
                                z = wp.vec3d(vp[t, 0], vp[t, 1], vp[t, 2])
                                w = x - z
                                if dot3(w, w) <= rho2:
                                    res = candidate_check_list(
                                        x,
                                        z,
                                        i,
                                        j,
                                        k,
                                        hint,
                                        rmax,
                                        positions,
                                        radii,
                                        heads,
                                        next_in_bin,
                                        reach,
                                        box,
                                        walls,
                                        gids,
                                        sbase,
                                        sstride,
                                        gn,
                                    )
                                    if res == CANDIDATE_OK:
                                        return wp.vec4i(i, j, k, t)
                                    if res >= 0:
                                        hint = res
    if wall_search(x, ids, cnt, 1, span, rmax, positions, radii, heads, next_in_bin, exposed, reach, box, walls):
        return wp.vec4i(-1, -1, -1, 0)
    return wp.vec4i(-2, -1, -1, 0)


@wp.func
def probe_reaches(
    x: wp.vec3d,
    lattice: wp.int32,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    exposed: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
) -> wp.bool:
    """Whether x is fluid by exact distances (``probe_search``, whose docstring says how)."""
    w = probe_search(
        x, lattice, rmax, positions, radii, heads, next_in_bin, exposed, reach, box, walls, GatherIds(), 0, 1
    )
    return w[0] != -2


@wp.kernel
def wet_expose(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    active: wp.array[wp.int32],
    box: WetBox,
    reach: wp.array[wp.uint32],
    slices: wp.int32,
    # outputs
    exposed: wp.array[wp.int32],
):
    """``slices`` threads per sphere (``exposed`` zeroed before the launch), thread s scanning the z planes
    ks[0] + s, ks[0] + s + slices, ...: sets 1 when a reached voxel (or the outside) lies within
    (r + rho + diagonal)(1 + slack) of the centre. A reachable candidate on the sphere's inflated surface has a
    reached cube corner within one diagonal, so a sphere that is not exposed carries none (a necessary condition:
    pruning, not a decision). An unexposed sphere reads every row of its ball (about a hundred words); the slices
    share them out (one thread each ran 147 us on the specimen, on 19 SMs)."""
    t = wp.tid()
    pid = t / slices
    sl = t - pid * slices
    if active.shape[0] > 0:
        if active[pid] == 0:
            return
    p = positions[pid]
    r32 = radii[pid]
    if not (wp.isfinite(p[0]) and wp.isfinite(p[1]) and wp.isfinite(p[2]) and wp.isfinite(r32) and r32 > 0.0):
        return
    c = wp.vec3d(wp.float64(p[0]), wp.float64(p[1]), wp.float64(p[2]))
    rd = (wp.float64(r32) + box.rho + box.diag) * (wp.float64(1.0) + SLACK)
    for a in range(3):
        if c[a] - rd <= wp.float64(0.0) or c[a] + rd >= wp.float64(box.n[a]) * box.h[a]:
            exposed[pid] = 1
            return
    rd2 = rd * rd
    ks = span_from(c[2], rd, box.h[2], box.n[2])
    js = span_from(c[1], rd, box.h[1], box.n[1])
    for k in range(ks[0] + sl, ks[1] + 1, slices):
        dz = centre_offset(k, box.h[2], c[2])
        for j in range(js[0], js[1] + 1):
            dy = centre_offset(j, box.h[1], c[1])
            t2 = dy * dy + dz * dz
            if t2 > rd2:
                continue
            xs = span_from(c[0], wp.sqrt(rd2 - t2), box.h[0], box.n[0])
            if xs[0] > xs[1]:
                continue
            row = word_at(box, 0, j, k)
            for w in range(xs[0] / 32, xs[1] / 32 + 1):
                m = low_mask(xs[1] + 1 - 32 * w) & ~low_mask(xs[0] - 32 * w)
                if (reach[row + w] & m) != wp.uint32(0):
                    exposed[pid] = 1
                    return


@wp.func
def voxel_point(wjk: wp.vec3i, b: wp.int32, box: WetBox) -> wp.vec3d:
    """Centre of bit b of x-word wjk[0] in row (j, k) = wjk[1], wjk[2], in frame coordinates [m]."""
    return wp.vec3d(
        (wp.float64(32 * wjk[0] + b) + wp.float64(0.5)) * box.h[0],
        (wp.float64(wjk[1]) + wp.float64(0.5)) * box.h[1],
        (wp.float64(wjk[2]) + wp.float64(0.5)) * box.h[2],
    )


@wp.func
def cert_covered(
    z: wp.vec3d,
    a: wp.int32,
    b: wp.int32,
    c: wp.int32,
    ids: CertIds,
    n: wp.int32,
    rs: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
) -> wp.bool:
    """z lies inside a listed ball of radius r + rs other than list entries a, b, c, by the rounding allowance."""
    for t in range(n):
        if t != a and t != b and t != c:
            q = ids[t]
            big = wp.float64(radii[q]) + rs
            v = z - centre_of(q, positions)
            if dot3(v, v) < big * big * (wp.float64(1.0) - CERT_IN):
                return True
    return False


@wp.func
def dry_certificate(
    x: wp.vec3d,
    shrink: wp.float64,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    box: WetBox,
) -> wp.bool:
    """The skin's certificate that x stays dry while no sphere moves ``shrink`` or more (radii and the set of spheres
    as now, more spheres allowed): every point within rho of x lies inside a ball of radius r + rho - shrink.

    Then every point within rho of x lies inside some inflated ball of any such later configuration, so no probe
    centre within rho of x is allowed, whatever the reach, the exposure or the walls (which only forbid more), and
    the exact test (``probe_reaches``) finds x dry. Checked as the exact test finds candidates: the point of the
    shrunk balls' free set nearest to x is x itself, a radial projection, a nearest point on a circle where two
    spheres meet, or a point where three meet; each of those within rho (times 1 + CERT_NEAR) of x must lie inside
    another listed ball by CERT_IN. Near-degenerate geometry (tangent balls, x on a circle's axis, nearly collinear
    centres, a circle nearly tangent to a third sphere) and more than CERT_LIST spheres near x: no certificate."""
    rho = box.rho
    rs = rho - shrink
    thr2 = rho * rho * (wp.float64(1.0) + CERT_NEAR)
    thr = wp.sqrt(thr2)
    ids = CertIds()
    n = int(0)
    span = bin_span(x, (rmax + rs + thr) * (wp.float64(1.0) + SLACK), box)
    for bz in range(span.lo[2], span.hi[2] + 1):
        for by in range(span.lo[1], span.hi[1] + 1):
            for bx in range(span.lo[0], span.hi[0] + 1):
                q = bin_head(bx, by, bz, box, heads)
                while q >= 0:
                    lim = (wp.float64(radii[q]) + rs + thr) * (wp.float64(1.0) + SLACK)
                    v = x - centre_of(q, positions)
                    if dot3(v, v) < lim * lim:
                        if n == CERT_LIST:
                            return False
                        ids[n] = q
                        n += 1
                    q = next_in_bin[q]
    # x itself must be covered; one ball holding all of x's rho-ball certifies at once.
    inside = int(0)
    for t in range(n):
        q = ids[t]
        big = wp.float64(radii[q]) + rs
        v = x - centre_of(q, positions)
        d2 = dot3(v, v)
        if d2 < big * big * (wp.float64(1.0) - CERT_IN):
            inside = 1
            if wp.sqrt(d2) + thr < big * (wp.float64(1.0) - CERT_IN):
                return True
    if inside == 0:
        return False
    # A sphere whose points within rho of x another listed ball covers carries no free point there: its faces,
    # circles and triple points are skipped (each of them lies in that ball; a circle or triple it defines with
    # that ball cannot come within rho). The covering tests below still read every listed ball.
    live = wp.uint64(0)
    for t in range(n):
        ct = centre_of(ids[t], positions)
        bt = wp.float64(radii[ids[t]]) + rs
        covered = int(0)
        u = int(0)
        while u < n and covered == 0:
            if u != t:
                if cert_cap_covered(x, ct, bt, centre_of(ids[u], positions), wp.float64(radii[ids[u]]) + rs, thr):
                    covered = 1
            u += 1
        if covered == 0:
            live = live | (wp.uint64(1) << wp.uint64(t))
    for t in range(n):
        if ((live >> wp.uint64(t)) & wp.uint64(1)) == wp.uint64(0):
            continue
        q = ids[t]
        c = centre_of(q, positions)
        v = x - c
        d2 = dot3(v, v)
        if d2 == wp.float64(0.0):
            return False
        z = c + v * ((wp.float64(radii[q]) + rs) / wp.sqrt(d2))
        w = x - z
        if dot3(w, w) <= thr2:
            if not cert_covered(z, t, -1, -1, ids, n, rs, positions, radii):
                return False
    for a in range(n):
        if ((live >> wp.uint64(a)) & wp.uint64(1)) == wp.uint64(0):
            continue
        ci = centre_of(ids[a], positions)
        big_i = wp.float64(radii[ids[a]]) + rs
        bi2 = big_i * big_i
        for b in range(a + 1, n):
            if ((live >> wp.uint64(b)) & wp.uint64(1)) == wp.uint64(0):
                continue
            cj = centre_of(ids[b], positions)
            big_j = wp.float64(radii[ids[b]]) + rs
            e = cj - ci
            l2 = dot3(e, e)
            if l2 == wp.float64(0.0):
                continue
            frac = ((bi2 - big_j * big_j) + l2) / (wp.float64(2.0) * l2)
            rc2 = bi2 - (frac * frac) * l2
            m = ci + e * frac
            xm = x - m
            tol = CERT_TINY * (bi2 + big_j * big_j)
            if rc2 <= tol:
                if rc2 >= -tol:
                    # Nearly tangent: their contact point may be a free point; decline near it.
                    near = thr + wp.float64(1.0e-5) * (big_i + big_j)
                    if dot3(xm, xm) <= near * near:
                        return False
                continue
            qe = dot3(xm, e)
            qp = xm - e * (qe / l2)
            qp2 = dot3(qp, qp)
            if qp2 <= CERT_TINY * rc2:
                # x on the circle's axis: every point of the circle about as near.
                if (qe * qe) / l2 + rc2 * wp.float64(0.999) <= thr2:
                    return False
                continue
            z = m + qp * wp.sqrt(rc2 / qp2)
            w = x - z
            e2 = dot3(w, w)
            if e2 <= thr2:
                if not cert_covered(z, a, b, -1, ids, n, rs, positions, radii):
                    return False
            if e2 <= thr2 * (wp.float64(1.0) + CERT_NEAR):
                for k in range(b + 1, n):
                    if ((live >> wp.uint64(k)) & wp.uint64(1)) == wp.uint64(0):
                        continue
                    ck = centre_of(ids[k], positions)
                    big_k = wp.float64(radii[ids[k]]) + rs
                    f = ck - ci
                    a12 = dot3(e, f)
                    a22 = dot3(f, f)
                    det = l2 * a22 - a12 * a12
                    if det <= wp.float64(1.0e-6) * l2 * a22:
                        gk = ck - cj
                        if a22 == wp.float64(0.0) or dot3(gk, gk) == wp.float64(0.0):
                            continue
                        return False
                    b1 = ((bi2 - big_j * big_j) + l2) * wp.float64(0.5)
                    b2 = ((bi2 - big_k * big_k) + a22) * wp.float64(0.5)
                    al = (b1 * a22 - b2 * a12) / det
                    be = (b2 * l2 - b1 * a12) / det
                    w0 = e * al + f * be
                    nrm = cross3(e, f)
                    nn = dot3(nrm, nrm)
                    g2 = (bi2 - dot3(w0, w0)) / nn
                    base = ci + w0
                    gtol = CERT_TINY * bi2 / nn
                    if wp.abs(g2) <= gtol:
                        # The circle nearly tangent to the third sphere: decline near their contact.
                        wb = x - base
                        near = thr + wp.float64(1.0e-5) * big_i
                        if dot3(wb, wb) <= near * near:
                            return False
                        continue
                    if g2 < wp.float64(0.0):
                        continue
                    g = wp.sqrt(g2)
                    for s in range(2):
                        z = base + nrm * (g * wp.float64(1 - 2 * s))
                        w = x - z
                        if dot3(w, w) <= thr2:
                            if not cert_covered(z, a, b, k, ids, n, rs, positions, radii):
                                return False
    return True


@wp.func
def witness_store(
    v: wp.int32, w: wp.vec4i, keys: wp.array[wp.int32], wits: wp.array[wp.vec4i], skin: wp.array[wp.int32]
) -> wp.int32:
    """Voxel v's witness w (or (-2, ...): none) into its slot, taking a free one when it has none (counted); a
    full probe run drops it. Only the thread deciding v writes v's slot in an update. Returns the slot (-1: none)."""
    s = table_claim(v, w[0] >= 0, keys, skin, SKIN_FILLED)
    if s >= 0:
        wits[s] = w
    return s


@wp.func
def witness_point(
    x: wp.vec3d,
    wit: wp.vec4i,
    n: wp.int32,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    exposed: wp.array[wp.int32],
    box: WetBox,
) -> wp.vec4d:
    """The candidate an earlier update found x wet by (``probe_search``'s witness), recomputed from today's spheres
    as the search computes it: (z, 1) when the search enumerates it today (its spheres exposed and near x, its
    circle or triple not degenerate, z within rho of x), else (0, 0, 0, 0). The search prunes a sphere only when
    another ball covers all its points within rho of x, and then this candidate would be blocked."""
    none = wp.vec4d(0.0)
    i = wit[0]
    j = wit[1]
    k = wit[2]
    if i < 0 or i >= n or j >= n or k >= n or box.skip != 0:
        return none
    if exposed[i] == 0 or not gate_ok(x, i, positions, radii, box):
        return none
    rho = box.rho
    rho2 = rho * rho
    ci = centre_of(i, positions)
    big_i = wp.float64(radii[i]) + rho
    z = wp.vec3d(0.0)
    if j < 0:
        v = x - ci
        d2 = dot3(v, v)
        if not (d2 > wp.float64(0.0)):
            return none
        z = ci + v * (big_i / wp.sqrt(d2))
    else:
        if j <= i or exposed[j] == 0 or not gate_ok(x, j, positions, radii, box):
            return none
        cj = centre_of(j, positions)
        big_j = wp.float64(radii[j]) + rho
        cp = circle_point(x, ci, big_i, cj, big_j)
        if cp[3] == wp.float64(0.0):
            return none
        z = wp.vec3d(cp[0], cp[1], cp[2])
        if k >= 0:
            e = x - z
            if not (dot3(e, e) <= rho2 * (wp.float64(1.0) + SLACK)):
                return none
            if k <= j or exposed[k] == 0 or not gate_ok(x, k, positions, radii, box):
                return none
            vp = vertex_points(ci, big_i, cj, big_j, centre_of(k, positions), wp.float64(radii[k]) + rho)
            if vp[2, 0] == wp.float64(0.0):
                return none
            t = wit[3]
            z = wp.vec3d(vp[t, 0], vp[t, 1], vp[t, 2])
    w = x - z
    if not (dot3(w, w) <= rho2):
        return none
    return wp.vec4d(z[0], z[1], z[2], wp.float64(1.0))


@wp.func
def witness_holds(
    x: wp.vec3d,
    wit: wp.vec4i,
    n: wp.int32,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    exposed: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
) -> wp.bool:
    """The witness's candidate (``witness_point``) is valid today: then the search finds x wet too, since it
    enumerates this candidate and stops at a valid one."""
    zp = witness_point(x, wit, n, positions, radii, exposed, box)
    if zp[3] == wp.float64(0.0):
        return False
    z = wp.vec3d(zp[0], zp[1], zp[2])
    i = wit[0]
    res = candidate_check(x, z, i, wit[1], wit[2], -1, rmax, positions, radii, heads, next_in_bin, reach, box, walls)
    return res == CANDIDATE_OK


@wp.func
def cube_corner(lo: wp.vec3i, corner: wp.int32) -> wp.vec3i:
    return wp.vec3i(lo[0] + (corner & 1), lo[1] + ((corner >> 1) & 1), lo[2] + ((corner >> 2) & 1))


@wp.func
def lattice_point(ijk: wp.vec3i, box: WetBox) -> wp.vec3d:
    return wp.vec3d(
        (wp.float64(ijk[0]) + wp.float64(0.5)) * box.h[0],
        (wp.float64(ijk[1]) + wp.float64(0.5)) * box.h[1],
        (wp.float64(ijk[2]) + wp.float64(0.5)) * box.h[2],
    )


@wp.func
def witness_margin(
    x: wp.vec3d,
    wit: wp.vec4i,
    epoch: wp.int32,
    skin_d: wp.float64,
    n: wp.int32,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    exposed: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
) -> WitMargin:
    """The valid witness ``wit`` of x measured (``WitMargin``): the clearance of every other inflated ball from its
    candidate z and from z's segment to each reached corner of its cube that leaves the candidate's own balls
    outward (``tangent_ok``), the best corner's kept. Every sphere whose ball comes within ``KEEP_CAP`` skins of z
    or of a segment (each within the voxel diagonal of z) is walked; the rest are at least that far, the cap.
    No margin (m = -1) for a cube clamped to the box's surroundings."""
    out = no_margin(epoch)
    zp = witness_point(x, wit, n, positions, radii, exposed, box)
    if zp[3] == wp.float64(0.0):
        return out
    z = wp.vec3d(zp[0], zp[1], zp[2])
    out.z = z
    lo, clamped = cube_corner_low(z, box)
    out.lo = lo
    if clamped != 0:
        return out
    i = wit[0]
    j = wit[1]
    k = wit[2]
    cap = KEEP_CAP * skin_d
    corners = reached_corners(lo, reach, box, walls)
    usable = int(0)
    seg = Vec8d()
    for c in range(8):
        seg[c] = cap
        if ((corners >> c) & 1) != 0:
            y = lattice_point(cube_corner(lo, c), box)
            if tangent_ok(y, z, i, positions) and tangent_ok(y, z, j, positions) and tangent_ok(y, z, k, positions):
                usable = usable | (1 << c)
    if usable == 0:
        return out
    free = cap
    span = bin_span(z, (rmax + box.rho + cap + box.diag) * (wp.float64(1.0) + SLACK), box)
    for bz in range(span.lo[2], span.hi[2] + 1):
        for by in range(span.lo[1], span.hi[1] + 1):
            for bx in range(span.lo[0], span.hi[0] + 1):
                q = bin_head(bx, by, bz, box, heads)
                while q >= 0:
                    big = wp.float64(radii[q]) + box.rho
                    cq = centre_of(q, positions)
                    v = z - cq
                    d2 = dot3(v, v)
                    # Every corner is within the diagonal of z: a ball this far keeps the cap from z and every
                    # segment, and changes no minimum (most of the walk's spheres).
                    far = (big + box.diag + cap) * (wp.float64(1.0) + SLACK)
                    if q != i and q != j and q != k and d2 < far * far:
                        free = wp.min(free, wp.sqrt(d2) - big)
                        for c in range(8):
                            if ((usable >> c) & 1) != 0:
                                y = lattice_point(cube_corner(lo, c), box)
                                d = z - y
                                dd = dot3(d, d)
                                wq = cq - y
                                s = wp.float64(0.0)
                                if dd > wp.float64(0.0):
                                    s = wp.clamp(dot3(wq, d) / dd, wp.float64(0.0), wp.float64(1.0))
                                p = wq - d * s
                                seg[c] = wp.min(seg[c], wp.sqrt(dot3(p, p)) - big)
                    q = next_in_bin[q]
    best = wp.float64(-1.0)
    for c in range(8):
        if ((usable >> c) & 1) != 0:
            if out.corner < 0 or seg[c] > best:
                best = seg[c]
                out.corner = c
    out.m = wp.min(free, best)
    return out


@wp.func
def witness_held(
    x: wp.vec3d,
    wit: wp.vec4i,
    mg: WitMargin,
    epoch: wp.int32,
    skin_d: wp.float64,
    n: wp.int32,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    exposed: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
) -> wp.bool:
    """The witness is valid today by its margin alone, without a search: measured under this reference (every
    sphere within half the skin of the reference then and now, so each has moved less than the skin since), its
    candidate recomputed today (``witness_point``) in the same cube, its corner reached, its own balls left
    outward, the walls allowing it, and the margin beyond the candidate's move plus the skin. Then every other
    inflated ball keeps out of z and of the segment to the corner (each point of which moved no more than z), so
    ``candidate_check`` finds z valid and the search finds x wet."""
    if epoch < 0 or mg.epoch != epoch or mg.corner < 0 or not (mg.m > skin_d):
        return False
    zp = witness_point(x, wit, n, positions, radii, exposed, box)
    if zp[3] == wp.float64(0.0):
        return False
    z = wp.vec3d(zp[0], zp[1], zp[2])
    lo, clamped = cube_corner_low(z, box)
    if clamped != 0 or lo[0] != mg.lo[0] or lo[1] != mg.lo[1] or lo[2] != mg.lo[2]:
        return False
    yi = cube_corner(lo, mg.corner)
    if not reached_at(yi[0], yi[1], yi[2], reach, box, walls):
        return False
    y = lattice_point(yi, box)
    if not (tangent_ok(y, z, wit[0], positions) and tangent_ok(y, z, wit[1], positions)):
        return False
    if not tangent_ok(y, z, wit[2], positions):
        return False
    if not walls_allow(z, wit[0], wit[1], wit[2], walls, box.rho):
        return False
    dz = z - mg.z
    need = (wp.sqrt(dot3(dz, dz)) + skin_d) * (wp.float64(1.0) + KEEP_REL)
    need = need + KEEP_ABS * (rmax + box.rho + box.diag)
    return mg.m > need


@wp.func
def skin_measures(skin: wp.array[wp.int32]) -> wp.bool:
    """This update re-checks witnesses, certifies dry voxels and measures margins: it keeps its reference, or the
    update before it did. Two new references in a row mean particles outrun the skin every update; what this one
    measured would be dropped by the next, so it runs as from scratch."""
    return skin[SKIN_RESET] == 0 or skin[SKIN_LAST] == 0


@wp.func
def skin_epoch(skin: wp.array[wp.int32]) -> wp.int32:
    """The reference a margin measured in this update belongs to: a new reference is taken after it (rebase)."""
    return skin[SKIN_RESETS] + skin[SKIN_RESET]


@wp.func
def witness_recheck(
    v: wp.int32,
    x: wp.vec3d,
    skin_d: wp.float64,
    n: wp.int32,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    exposed: wp.array[wp.int32],
    reach: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
    skin: wp.array[wp.int32],
    keys: wp.array[wp.int32],
    wits: wp.array[wp.vec4i],
    margins: wp.array[WitMargin],
) -> wp.int32:
    """Voxel v's stored witness re-checked: 1 held by its margin (no search), 2 valid by its searches (its margin
    then measured again from today's spheres, unless it was measured under this reference and was too tight to hold
    anyway), 0 none or not valid (the voxel is tested)."""
    s = table_find(v, keys)
    if s < 0:
        return 0
    wit = wits[s]
    if wit[0] < 0:
        return 0
    epoch = int(-1)
    if skin[SKIN_RESET] == 0:
        epoch = skin[SKIN_RESETS]
    if witness_held(x, wit, margins[s], epoch, skin_d, n, rmax, positions, radii, exposed, reach, box, walls):
        return 1
    if witness_holds(x, wit, n, rmax, positions, radii, heads, next_in_bin, exposed, reach, box, walls):
        mg = margins[s]
        # Measured again (``wet_skin_margins``) unless it was measured under this reference and was too tight
        # then: it could not hold.
        if mg.epoch != epoch or mg.m > skin_d:
            mg.epoch = MARGIN_PENDING
            margins[s] = mg
        return 2
    return 0


@wp.func
def witness_keep(
    v: wp.int32,
    found: wp.vec4i,
    skin: wp.array[wp.int32],
    keys: wp.array[wp.int32],
    wits: wp.array[wp.vec4i],
    margins: wp.array[WitMargin],
):
    """The search's answer for voxel v into the witness table; a witness's margin is left to measure
    (``wet_skin_margins``) when this update measures, else marked as none."""
    s = witness_store(v, found, keys, wits, skin)
    if s >= 0 and found[0] >= 0:
        epoch = int(-1)
        if skin_measures(skin):
            epoch = MARGIN_PENDING
        margins[s] = no_margin(epoch)


@wp.kernel
def wet_skin_start(
    n: wp.int32,
    capacity: wp.int32,
    cross_capacity: wp.int32,
    # outputs
    skin: wp.array[wp.int32],
):
    """One thread: this update takes a new reference (none taken yet, or ``n`` particles where the reference had
    another count) or not, wipes the witness table (of ``capacity`` slots) when over three quarters of it are taken,
    and clears the counters. The count is compared here, on the device, so that a graph recorded at any point
    replays right."""
    reset = int(0)
    if skin[SKIN_PRIMED] == 0 or skin[SKIN_COUNT] != n:
        reset = 1
    skin[SKIN_COUNT] = n
    skin[SKIN_LAST] = skin[SKIN_RESET]
    skin[SKIN_RESET] = reset
    skin[SKIN_KEPT] = 0
    skin[SKIN_CERTIFIED] = 0
    skin[SKIN_WITNESSED] = 0
    skin[SKIN_HELD] = 0
    skin[SKIN_WIPE] = 0
    if 4 * skin[SKIN_FILLED] > 3 * capacity or skin[SKIN_PRIMED] == 0:
        skin[SKIN_WIPE] = 1
        skin[SKIN_FILLED] = 0
    skin[SKIN_CROSS_KEPT] = 0
    skin[SKIN_CROSS_WIPE] = 0
    if 4 * skin[SKIN_CROSS_FILLED] > 3 * cross_capacity:
        skin[SKIN_CROSS_WIPE] = 1


@wp.kernel
def wet_skin_moved(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    active: wp.array[wp.int32],
    ref_pos: wp.array[wp.vec3],
    ref_rad: wp.array[wp.float32],
    ref_act: wp.array[wp.int32],
    half: wp.float64,
    # outputs
    skin: wp.array[wp.int32],
):
    """One thread per particle: a particle that moved ``half`` the skin or more from the reference, changed its
    radius, its activity or is not finite makes this update take a new reference (every kept decision dropped)."""
    pid = wp.tid()
    a = int(1)
    if active.shape[0] > 0:
        if active[pid] == 0:
            a = 0
    moved = int(0)
    if a != ref_act[pid]:
        moved = 1
    elif a != 0:
        if not (radii[pid] == ref_rad[pid]):
            moved = 1
        else:
            p = positions[pid]
            o = ref_pos[pid]
            d = wp.vec3d(
                wp.float64(p[0]) - wp.float64(o[0]),
                wp.float64(p[1]) - wp.float64(o[1]),
                wp.float64(p[2]) - wp.float64(o[2]),
            )
            if not (dot3(d, d) < half * half):
                moved = 1
    if moved != 0:
        wp.atomic_max(skin, SKIN_RESET, 1)


@wp.kernel
def wet_skin_clear(
    skin: wp.array[wp.int32],
    # outputs
    kept: wp.array[wp.uint32],
    tried: wp.array[wp.uint32],
    keys: wp.array[wp.int32],
    cross_keys: wp.array[wp.int32],
):
    """One thread per word and per table slot: a new reference drops every kept dry decision, every failed
    certificate's mark and every kept crossing owner (their margins were measured from the old one); a wipe, every
    witness (or owner)."""
    t = wp.tid()
    reset = skin[SKIN_RESET] != 0
    if t < kept.shape[0]:
        if reset:
            kept[t] = wp.uint32(0)
            tried[t] = wp.uint32(0)
    if t < keys.shape[0]:
        if skin[SKIN_WIPE] != 0:
            keys[t] = -1
    if t < cross_keys.shape[0]:
        if reset or skin[SKIN_CROSS_WIPE] != 0:
            cross_keys[t] = -1


@wp.kernel
def wet_skin_rebase(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    active: wp.array[wp.int32],
    n: wp.int32,
    # outputs
    ref_pos: wp.array[wp.vec3],
    ref_rad: wp.array[wp.float32],
    ref_act: wp.array[wp.int32],
    skin: wp.array[wp.int32],
):
    """One thread per particle, after the classification: a new reference is this update's particles."""
    t = wp.tid()
    if t == 0:
        if skin[SKIN_RESET] != 0 or skin[SKIN_CROSS_WIPE] != 0:
            skin[SKIN_CROSS_FILLED] = 0
    if skin[SKIN_RESET] == 0:
        return
    if t < n:
        ref_pos[t] = positions[t]
        ref_rad[t] = radii[t]
        a = int(1)
        if active.shape[0] > 0:
            if active[t] == 0:
                a = 0
        ref_act[t] = a
    if t == 0:
        skin[SKIN_PRIMED] = 1
        skin[SKIN_RESETS] = skin[SKIN_RESETS] + 1


@wp.kernel
def wet_skin_margins(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    box: WetBox,
    walls: LampWalls,
    reach: wp.array[wp.uint32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    rmax: wp.array[wp.float32],
    exposed: wp.array[wp.int32],
    skin_d: wp.float64,
    n_particles: wp.int32,
    keys: wp.array[wp.int32],
    wits: wp.array[wp.vec4i],
    skin: wp.array[wp.int32],
    # outputs
    margins: wp.array[WitMargin],
):
    """One thread per witness table slot, after the classification: a witness that this update stored or re-checked
    by its walk (``MARGIN_PENDING``) gets its margin (``witness_margin``). Apart from the tests, so that their kernels
    carry none of its code: the classification from scratch is as fast with the skin's code as without it."""
    s = wp.tid()
    if margins[s].epoch != MARGIN_PENDING:
        return
    v = keys[s]
    wit = wits[s]
    if v < 0 or wit[0] < 0:
        margins[s] = no_margin(-1)
        return
    idx = v / 32
    x = voxel_point(word_coords(box, idx), v - idx * 32, box)
    margins[s] = witness_margin(
        x, wit, skin_epoch(skin), skin_d, n_particles, wp.float64(rmax[0]), positions, radii, heads, next_in_bin,
        exposed, reach, box, walls,
    )  # fmt: skip


@wp.kernel
def wet_classify(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    box: WetBox,
    walls: LampWalls,
    reach: wp.array[wp.uint32],
    band: wp.array[wp.uint32],
    solid: wp.array[wp.uint32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    rmax: wp.array[wp.float32],
    exposed: wp.array[wp.int32],
    bits: wp.int32,
    capacity: wp.int32,
    shrink: wp.float64,
    n_particles: wp.int32,
    uncertain: wp.array[wp.uint32],
    offsets: wp.array[wp.int32],
    # outputs
    fluid: wp.array[wp.uint32],
    diag: wp.array[wp.int32],
    queue: wp.array[wp.int32],
    queued: wp.array[wp.int32],
    kept: wp.array[wp.uint32],
    tried: wp.array[wp.uint32],
    skin: wp.array[wp.int32],
    keys: wp.array[wp.int32],
    wits: wp.array[wp.vec4i],
    margins: wp.array[WitMargin],
):
    """One thread per ``bits`` bits of a word (32 on the CPU; fewer on CUDA): every voxel of the band (within rho +
    diagonal of a reached voxel) that the dilation by rho left dry and that is not solid gets the exact test. With
    ``capacity`` > 0 the first ``capacity`` such voxels go to ``queue`` (their word * 32 + bit, in no set order;
    ``queued[0]``, zeroed before, counts them all) for ``wet_classify_queued``, and the thread tests the rest
    itself. A thread sets only its own bits of ``fluid``. With ``offsets`` (the exclusive prefix sum of
    ``wet_uncertain_words``'s counts, and its ``uncertain`` words), a voxel's slot is its rank in voxel order, so
    that a warp of queued tests takes neighbouring voxels (measured: the atomics' order scrambled them at 1M
    spheres); else the atomics' order.

    The skin (``kept`` not empty): a voxel whose bit is set in ``kept`` has a dry certificate
    (``dry_certificate``) that still holds, unless this update takes a new reference: it stays dry untested (and
    is counted as decided). A voxel tested dry gets a certificate when one can be made. A voxel found wet by a
    candidate on spheres alone keeps it as its witness (``keys``, ``wits``): a later update re-checks that one
    candidate first (``witness_holds``) and tests the voxel only when it fails."""
    t = wp.tid()
    splits = 32 / bits
    idx = t / splits
    sub = t - idx * splits
    wjk = word_coords(box, idx)
    w = wjk[0]
    own = low_mask(bits) << wp.uint32(sub * bits)
    unc = band[idx] & ~fluid[idx] & ~solid[idx] & row_mask(box, w) & own
    if unc == wp.uint32(0):
        return
    skinned = kept.shape[0] > 0
    tested = int(0)
    if skinned:
        if skin[SKIN_RESET] == 0:
            keep = kept[idx] & unc
            if keep != wp.uint32(0):
                nk = wp.bit_count(keep)
                unc = unc & ~keep
                tested += nk
                wp.atomic_add(skin, SKIN_KEPT, nk)
    r_max = wp.float64(rmax[0])
    add = wp.uint32(0)
    certified = wp.uint32(0)
    n_cert = int(0)
    wet = int(0)
    witnessed = int(0)
    held = int(0)
    while unc != wp.uint32(0):
        b = lowest_bit(unc)
        unc = unc & (unc - wp.uint32(1))
        tested += 1
        # Queued first, witness or not: a witness's re-check walks the neighbour bins as a test does, and in
        # these mostly idle threads it cost more than the tests it saved (measured on an H200).
        if capacity > 0:
            slot = wp.atomic_add(queued, 0, 1)
            if offsets.shape[0] > 0:
                # This thread's bits of ``uncertain`` are its own ``unc``: only it changes ``kept`` there.
                slot = offsets[idx] + wp.bit_count(uncertain[idx] & low_mask(b))
            if slot < capacity:
                queue[slot] = idx * 32 + b
                continue
        x = voxel_point(wjk, b, box)
        if skinned and skin_measures(skin):
            kept_by = witness_recheck(
                idx * 32 + b, x, shrink, n_particles, r_max, positions, radii, heads, next_in_bin, exposed, reach,
                box, walls, skin, keys, wits, margins,
            )  # fmt: skip
            if kept_by != 0:
                add = add | (wp.uint32(1) << wp.uint32(b))
                wet += 1
                witnessed += 1
                if kept_by == 1:
                    held += 1
                continue
        found = probe_search(
            x, 1, r_max, positions, radii, heads, next_in_bin, exposed, reach, box, walls, GatherIds(), 0, 1
        )
        if skinned:
            witness_keep(idx * 32 + b, found, skin, keys, wits, margins)
        if found[0] != -2:
            add = add | (wp.uint32(1) << wp.uint32(b))
            wet += 1
        elif skinned and skin_measures(skin):
            if ((tried[idx] >> wp.uint32(b)) & wp.uint32(1)) == wp.uint32(0):
                if dry_certificate(x, shrink, r_max, positions, radii, heads, next_in_bin, box):
                    certified = certified | (wp.uint32(1) << wp.uint32(b))
                    n_cert += 1
                else:
                    wp.atomic_or(tried, idx, wp.uint32(1) << wp.uint32(b))
    if add != wp.uint32(0):
        if bits == 32:
            fluid[idx] = fluid[idx] | add
        else:
            wp.atomic_or(fluid, idx, add)
    if certified != wp.uint32(0):
        wp.atomic_or(kept, idx, certified)
        wp.atomic_add(skin, SKIN_CERTIFIED, n_cert)
    if witnessed > 0:
        wp.atomic_add(skin, SKIN_WITNESSED, witnessed)
    if held > 0:
        wp.atomic_add(skin, SKIN_HELD, held)
    wp.atomic_add(diag, DIAG_UNCERTAIN, tested)
    wp.atomic_add(diag, DIAG_RESCUED, wet)


@wp.kernel
def wet_classify_queued(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    box: WetBox,
    walls: LampWalls,
    reach: wp.array[wp.uint32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    rmax: wp.array[wp.float32],
    exposed: wp.array[wp.int32],
    queue: wp.array[wp.int32],
    shrink: wp.float64,
    n_particles: wp.int32,
    # outputs
    queued: wp.array[wp.int32],
    scratch: wp.array[wp.int32],
    fluid: wp.array[wp.uint32],
    diag: wp.array[wp.int32],
    kept: wp.array[wp.uint32],
    tried: wp.array[wp.uint32],
    skin: wp.array[wp.int32],
    keys: wp.array[wp.int32],
    wits: wp.array[wp.vec4i],
    margins: wp.array[WitMargin],
):
    """The queued voxels' exact tests (``wet_classify``), packed into as few threads as fit the GPU at once, where
    ``wet_classify``'s threads are mostly idle: launched for ``scratch``'s rows (``GATHER`` int32 each, interleaved:
    row t's entry k at ``k * rows + t``), thread t tests slot t (slot t / stride for every stride-th thread when the
    queue is at least ``QUEUE_SPREAD_FROM`` times shorter than the threads), then the slots past the first ones one
    at a time as it finishes (``queued[1]``, zeroed with the count ``queued[0]``, counts those taken), with its
    gathered list in its row.
    The first slot by thread keeps a warp's lanes on neighbouring voxels and the tests spread over the SMs as
    blocks are (slots taken from the counter from the start cost the specimen 10%); the rest as they finish, because
    a fixed share per thread left the GPU waiting on the threads whose share was slowest (the 1M lattice 13% slower
    than a thread per test; 27% with each warp's share in one run). With the skin, a voxel's witness is re-checked
    here first; a voxel tested dry gets its certificate here, one tested wet its witness."""
    t = wp.tid()
    rows = scratch.shape[0] / GATHER
    r_max = wp.float64(rmax[0])
    n = wp.min(queued[0], queue.shape[0])
    # A queue shorter than the threads is spread, one first slot per `stride` threads: in slot order its tests sat
    # 32 diverging to a warp, on fewer SMs (the specimen at rest: 9,472 slots for 33,792 threads, stride 3).
    stride = wp.max(1, wp.min(QUEUE_SPREAD, rows / wp.max(n, 1)))
    if stride < QUEUE_SPREAD_FROM:
        stride = 1
    leads = (rows + stride - 1) / stride
    first = int(1)
    while True:
        slot = n
        if first == 1 and t % stride == 0:
            slot = t / stride
        elif leads < n:
            slot = leads + wp.atomic_add(queued, 1, 1)
        first = 0
        if slot >= n:
            break
        v = queue[slot]
        idx = v / 32
        b = v - idx * 32
        wjk = word_coords(box, idx)
        x = voxel_point(wjk, b, box)
        if kept.shape[0] > 0 and skin_measures(skin):
            kept_by = witness_recheck(
                v, x, shrink, n_particles, r_max, positions, radii, heads, next_in_bin, exposed, reach, box, walls,
                skin, keys, wits, margins,
            )  # fmt: skip
            if kept_by != 0:
                wp.atomic_or(fluid, idx, wp.uint32(1) << wp.uint32(b))
                wp.atomic_add(diag, DIAG_RESCUED, 1)
                wp.atomic_add(skin, SKIN_WITNESSED, 1)
                if kept_by == 1:
                    wp.atomic_add(skin, SKIN_HELD, 1)
                continue
        found = probe_search(
            x, 1, r_max, positions, radii, heads, next_in_bin, exposed, reach, box, walls, scratch, t, rows
        )
        if kept.shape[0] > 0:
            witness_keep(v, found, skin, keys, wits, margins)
        if found[0] != -2:
            wp.atomic_or(fluid, idx, wp.uint32(1) << wp.uint32(b))
            wp.atomic_add(diag, DIAG_RESCUED, 1)
        elif kept.shape[0] > 0 and skin_measures(skin):
            bit = wp.uint32(1) << wp.uint32(b)
            if (tried[idx] & bit) == wp.uint32(0):
                if dry_certificate(x, shrink, r_max, positions, radii, heads, next_in_bin, box):
                    wp.atomic_or(kept, idx, bit)
                    wp.atomic_add(skin, SKIN_CERTIFIED, 1)
                else:
                    wp.atomic_or(tried, idx, bit)


@wp.func
def thin_chord(
    q: wp.int32,
    a: wp.int32,
    iu: wp.int32,
    iv: wp.int32,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    box: WetBox,
) -> Chord:
    """Sphere q's chord on the row (iu, iv) along axis a when it holds no voxel centre. The row meets the open
    ball when the voxel test with the a-term zero holds, ``t^2 < r^2``; the chord then lies between samples m0 and
    m0 + 1 (``m0 = floor(c_a / h_a - 1/2)``, -1 <= m0 <= n_a - 1) when none of the centres m0 - 1 ... m0 + 2 is
    inside by the voxel test (the two beyond guard against rounding in m0)."""
    out = Chord()
    out.ok = 0
    c = centre_of(q, positions)
    r = wp.float64(radii[q])
    r2 = r * r
    u = (a + 1) % 3
    v = (a + 2) % 3
    d = wp.vec3d(0.0)
    d[u] = centre_offset(iu, box.h[u], c[u])
    d[v] = centre_offset(iv, box.h[v], c[v])
    t2 = dot3(d, d)
    # A chord of half-length h_a or more holds the nearest centre well inside (by 3/4 h_a^2): never thin.
    if not (t2 < r2) or r2 - t2 >= box.h[a] * box.h[a]:
        return out
    f = c[a] / box.h[a] - wp.float64(0.5)
    if not (f >= wp.float64(-1.0) and f < wp.float64(box.n[a])):
        return out
    m0 = wp.int32(wp.floor(f))
    for m in range(m0 - 1, m0 + 3):
        d[a] = centre_offset(m, box.h[a], c[a])
        if dot3(d, d) < r2:
            return out
    half = wp.sqrt(r2 - t2)
    out.ok = 1
    out.m0 = m0
    out.lo = c[a] - half
    out.hi = c[a] + half
    return out


@wp.func
def axis_of(x: wp.vec3d, a: wp.int32) -> wp.float64:
    """Component a of x. A vector indexed by a runtime value lives in local memory, which the thin scan's row
    loop paid for on every row (11 ms of the 1M lattice's update, Warp's activity timing on an H200); selected
    from fixed components, it stays in registers."""
    return wp.where(a == 0, x[0], wp.where(a == 1, x[1], x[2]))


@wp.func
def axis_of_i(x: wp.vec3i, a: wp.int32) -> wp.int32:
    """``axis_of`` for integer vectors."""
    return wp.where(a == 0, x[0], wp.where(a == 1, x[1], x[2]))


@wp.func
def row_ijk(a: wp.int32, m: wp.int32, iu: wp.int32, iv: wp.int32) -> wp.vec3i:
    """Voxel index (i, j, k) of sample m on the row (iu, iv) along axis a (u = a + 1, v = a + 2, modulo 3)."""
    return wp.vec3i(
        wp.where(a == 0, m, wp.where(a == 1, iv, iu)),
        wp.where(a == 0, iu, wp.where(a == 1, m, iv)),
        wp.where(a == 0, iv, wp.where(a == 1, iu, m)),
    )


@wp.func
def fluid_sample(
    a: wp.int32,
    m: wp.int32,
    iu: wp.int32,
    iv: wp.int32,
    fluid: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
) -> wp.bool:
    """Sample m of the row (iu, iv) along axis a is fluid; the virtual samples -1 and n_a are the virtual fluid
    (``walls_fluid``: all of them without walls)."""
    ijk = row_ijk(a, m, iu, iv)
    if m < 0 or m >= axis_of_i(box.n, a):
        return walls_fluid(virtual_point(ijk[0], ijk[1], ijk[2], box), walls, box.rho)
    word = fluid[word_at(box, ijk[0] / 32, ijk[1], ijk[2])]
    return ((word >> wp.uint32(ijk[0] % 32)) & wp.uint32(1)) != wp.uint32(0)


@wp.func
def row_point(a: wp.int32, t: wp.float64, iu: wp.int32, iv: wp.int32, box: WetBox) -> wp.vec3d:
    """The point at coordinate t along axis a on the row (iu, iv)."""
    p = wp.vec3d(0.0)
    p[a] = t
    u = (a + 1) % 3
    v = (a + 2) % 3
    p[u] = (wp.float64(iu) + wp.float64(0.5)) * box.h[u]
    p[v] = (wp.float64(iv) + wp.float64(0.5)) * box.h[v]
    return p


@wp.func
def chord_before(lo_q: wp.float64, q: wp.int32, lo_s: wp.float64, s: wp.int32) -> wp.bool:
    """Chord order along the row: by start, ties to the lower index."""
    return lo_q < lo_s or (lo_q == lo_s and q < s)


@wp.func
def thin_interval(
    s: wp.int32,
    a: wp.int32,
    iu: wp.int32,
    iv: wp.int32,
    me: Chord,
    r_max: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    box: WetBox,
    walls: LampWalls,
    reach: wp.array[wp.uint32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    exposed: wp.array[wp.int32],
    # outputs
    counts: wp.array[wp.int64],
    hits: wp.array[wp.int32],
    rays: wp.array[wp.int32],
    diag: wp.array[wp.int32],
    thin_faces: wp.array[wp.int32],
):
    """Sphere s's thin chord ``me`` on row (iu, iv) of axis a, whose samples on either side are fluid: the chords
    between the same samples merge (``wet_thin``); where this one starts a merged interval, its entry and exit are
    loaded."""
    u = (a + 1) % 3
    m0 = me.m0
    # Every thin chord between these samples has its centre within r_max + h_a of the face point.
    g0 = row_point(a, wp.float64(m0 + 1) * box.h[a], iu, iv, box)
    span = bin_span(g0, (r_max + box.h[a]) * (wp.float64(1.0) + SLACK), box)
    # Where do the chords before this one end?
    has_before = int(0)
    top = wp.float64(0.0)
    for bz in range(span.lo[2], span.hi[2] + 1):
        for by in range(span.lo[1], span.hi[1] + 1):
            for bx in range(span.lo[0], span.hi[0] + 1):
                q = bin_head(bx, by, bz, box, heads)
                while q >= 0:
                    if q != s:
                        ch = thin_chord(q, a, iu, iv, positions, radii, box)
                        if ch.ok != 0 and ch.m0 == m0 and chord_before(ch.lo, q, me.lo, s):
                            if has_before == 0 or ch.hi > top:
                                top = ch.hi
                            has_before = 1
                    q = next_in_bin[q]
    if has_before != 0:
        if top >= me.lo:
            return
        wp.atomic_add(diag, DIAG_GAPS, 1)
        gap = row_point(a, (top + me.lo) * wp.float64(0.5), iu, iv, box)
        if not probe_reaches(gap, 0, r_max, positions, radii, heads, next_in_bin, exposed, reach, box, walls):
            return
    # This chord starts a merged interval: walk the chords after it in order while they join it.
    cur = me.hi
    end = s
    last_lo = me.lo
    last = s
    more = int(1)
    while more != 0:
        nxt = int(-1)
        nxt_lo = wp.float64(0.0)
        nxt_hi = wp.float64(0.0)
        for bz in range(span.lo[2], span.hi[2] + 1):
            for by in range(span.lo[1], span.hi[1] + 1):
                for bx in range(span.lo[0], span.hi[0] + 1):
                    q = bin_head(bx, by, bz, box, heads)
                    while q >= 0:
                        ch = thin_chord(q, a, iu, iv, positions, radii, box)
                        if ch.ok != 0 and ch.m0 == m0 and chord_before(last_lo, last, ch.lo, q):
                            if nxt < 0 or chord_before(ch.lo, q, nxt_lo, nxt):
                                nxt = q
                                nxt_lo = ch.lo
                                nxt_hi = ch.hi
                        q = next_in_bin[q]
        more = 0
        if nxt >= 0:
            join = int(1)
            if nxt_lo > cur:
                wp.atomic_add(diag, DIAG_GAPS, 1)
                gap = row_point(a, (cur + nxt_lo) * wp.float64(0.5), iu, iv, box)
                if probe_reaches(gap, 0, r_max, positions, radii, heads, next_in_bin, exposed, reach, box, walls):
                    join = 0
            if join != 0:
                if nxt_hi > cur or (nxt_hi == cur and nxt < end):
                    cur = nxt_hi
                    end = nxt
                last_lo = nxt_lo
                last = nxt
                more = 1
    ray = iu + box.n[u] * iv
    wp.atomic_add(diag, DIAG_THIN, 1)
    wp.atomic_add(rays, box.offset[a] + ray, 1)
    if thin_faces.shape[0] > 0:
        wp.atomic_add(thin_faces, box.face_offset[a] + ray * (box.n[a] + 1) + m0 + 1, 1)
    if ((box.lamp_mask >> (2 * a)) & 1) != 0:
        wp.atomic_add(counts, 3 * s + a, wp.int64(1))
        wp.atomic_add(hits, s, 1)
    if ((box.lamp_mask >> (2 * a + 1)) & 1) != 0:
        wp.atomic_add(counts, 3 * end + a, wp.int64(-1))
        wp.atomic_add(hits, end, 1)


@wp.struct
class ThinAxis:
    """A sphere's rows along one axis a, as scalars (u = a + 1, v = a + 2, modulo 3): the centre's and the voxel
    edges' components, the rows its footprint spans (first > last: none) and m0, the sample before a thin chord
    (``thin_chord``)."""

    cu: wp.float64
    cv: wp.float64
    ca: wp.float64
    hu: wp.float64
    hv: wp.float64
    ha: wp.float64
    r2: wp.float64
    u0: wp.int32
    u1: wp.int32
    v0: wp.int32
    v1: wp.int32
    m0: wp.int32


@wp.func
def thin_axis(
    s: wp.int32, a: wp.int32, positions: wp.array[wp.vec3], radii: wp.array[wp.float32], box: WetBox
) -> ThinAxis:
    """Sphere s's ``ThinAxis`` along a; no rows for a sphere that is not finite or whose chords along a cannot
    lie between two samples of the box's rows (``thin_chord``'s range of m0)."""
    out = ThinAxis()
    out.u0 = 0
    out.u1 = -1
    out.v0 = 0
    out.v1 = -1
    p = positions[s]
    r32 = radii[s]
    if not (wp.isfinite(p[0]) and wp.isfinite(p[1]) and wp.isfinite(p[2]) and wp.isfinite(r32) and r32 > 0.0):
        return out
    c = centre_of(s, positions)
    u = (a + 1) % 3
    v = (a + 2) % 3
    out.cu = axis_of(c, u)
    out.cv = axis_of(c, v)
    out.ca = axis_of(c, a)
    out.hu = axis_of(box.h, u)
    out.hv = axis_of(box.h, v)
    out.ha = axis_of(box.h, a)
    r = wp.float64(r32)
    out.r2 = r * r
    f = out.ca / out.ha - wp.float64(0.5)
    if not (f >= wp.float64(-1.0) and f < wp.float64(axis_of_i(box.n, a))):
        return out
    out.m0 = wp.int32(wp.floor(f))
    us = span_from(out.cu, r, out.hu, axis_of_i(box.n, u))
    vs = span_from(out.cv, r, out.hv, axis_of_i(box.n, v))
    out.u0 = us[0]
    out.u1 = us[1]
    out.v0 = vs[0]
    out.v1 = vs[1]
    return out


@wp.func
def thin_listable(
    ax: ThinAxis,
    a: wp.int32,
    iu: wp.int32,
    iv: wp.int32,
    du: wp.float64,
    dv: wp.float64,
    fluid: wp.array[wp.uint32],
    box: WetBox,
    walls: LampWalls,
) -> wp.bool:
    """The sphere of ``ax`` has a thin chord on row (iu, iv) (centre offsets du, dv along u and v) and both samples
    beside it are fluid: ``thin_chord``'s tests on the same values, in the same order of summation (x, y, z), so
    the same rows as ``thin_chord(...).ok`` and ``fluid_sample`` on both sides."""
    # thin_chord's first test (two terms add in either order, exactly, and its third term is 0): most rows end here.
    t2 = du * du + dv * dv
    if not (t2 < ax.r2) or ax.r2 - t2 >= ax.ha * ax.ha:
        return False
    for m in range(ax.m0 - 1, ax.m0 + 3):
        da = centre_offset(m, ax.ha, ax.ca)
        x = wp.where(a == 0, da, wp.where(a == 1, dv, du))
        y = wp.where(a == 0, du, wp.where(a == 1, da, dv))
        z = wp.where(a == 0, dv, wp.where(a == 1, du, da))
        if (x * x + y * y) + z * z < ax.r2:
            return False
    return fluid_sample(a, ax.m0, iu, iv, fluid, box, walls) and fluid_sample(a, ax.m0 + 1, iu, iv, fluid, box, walls)


@wp.kernel
def wet_thin_scan(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    active: wp.array[wp.int32],
    box: WetBox,
    walls: LampWalls,
    fluid: wp.array[wp.uint32],
    # outputs
    thin_list: wp.array[wp.vec4i],
    thin_listed: wp.array[wp.int32],
    thin_from: wp.array[wp.int32],
    thin_over: wp.array[wp.int32],
):
    """One thread per (sphere, axis), CUDA's first thin pass: list (sphere, axis, row) for every thin chord with
    fluid on both sides (``thin_listable``) while the list has room, for ``wet_thin_listed``. It walks nothing and
    reads the sphere along its axis as scalars (``thin_axis``), so its row loop runs in registers (the 1M lattice's
    3M sphere-axes: 0.9 ms on an H200, 11 ms with vectors indexed by the axis). Past the list's capacity it writes,
    per thread, 1 + the ordinal of its first chord left unlisted (``thin_from``, 0: none) and sets ``thin_over[0]``:
    ``wet_thin`` walks those."""
    t = wp.tid()
    s = t / 3
    a = t - 3 * s
    first = int(-1)
    if active.shape[0] == 0 or active[s] != 0:
        ax = thin_axis(s, a, positions, radii, box)
        ordinal = int(0)
        for iv in range(ax.v0, ax.v1 + 1):
            dv = centre_offset(iv, ax.hv, ax.cv)
            for iu in range(ax.u0, ax.u1 + 1):
                du = centre_offset(iu, ax.hu, ax.cu)
                if thin_listable(ax, a, iu, iv, du, dv, fluid, box, walls):
                    slot = wp.atomic_add(thin_listed, 0, 1)
                    if slot < thin_list.shape[0]:
                        thin_list[slot] = wp.vec4i(s, a, iu, iv)
                    elif first < 0:
                        first = ordinal
                    ordinal += 1
    thin_from[t] = first + 1
    if first >= 0:
        thin_over[0] = 1


@wp.kernel
def wet_thin(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    active: wp.array[wp.int32],
    box: WetBox,
    walls: LampWalls,
    fluid: wp.array[wp.uint32],
    reach: wp.array[wp.uint32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    rmax: wp.array[wp.float32],
    exposed: wp.array[wp.int32],
    thin_from: wp.array[wp.int32],
    # outputs
    counts: wp.array[wp.int64],
    hits: wp.array[wp.int32],
    rays: wp.array[wp.int32],
    diag: wp.array[wp.int32],
    thin_faces: wp.array[wp.int32],
):
    """One thread per (sphere, axis): the sphere's thin chords on the rows of that axis whose samples on both sides
    are fluid (``thin_listable``), each walked by ``thin_interval``: the thin chords between the same two samples,
    ordered by start, merge where they overlap or touch or where the gap between them is dry (``probe_reaches`` at
    its midpoint); the thread of the first chord of each merged interval loads its entry (the low lamp's +1, to
    that sphere) and its exit (the high lamp's -1, to the sphere whose chord reaches furthest, ties to the lower
    index). Integer counts: the order is immaterial. With ``thin_from`` (CUDA, after ``wet_thin_scan`` and
    ``wet_thin_listed``) a thread walks only its chords from ordinal ``thin_from[t] - 1`` on, the ones the list
    could not hold, and none where it is 0."""
    t = wp.tid()
    s = t / 3
    a = t - 3 * s
    skip = int(0)
    if thin_from.shape[0] > 0:
        skip = thin_from[t] - 1
        if skip < 0:
            return
    if active.shape[0] > 0:
        if active[s] == 0:
            return
    ax = thin_axis(s, a, positions, radii, box)
    r_max = wp.float64(rmax[0])
    ordinal = int(0)
    for iv in range(ax.v0, ax.v1 + 1):
        dv = centre_offset(iv, ax.hv, ax.cv)
        for iu in range(ax.u0, ax.u1 + 1):
            du = centre_offset(iu, ax.hu, ax.cu)
            if thin_listable(ax, a, iu, iv, du, dv, fluid, box, walls):
                ordinal += 1
                if ordinal > skip:
                    me = thin_chord(s, a, iu, iv, positions, radii, box)
                    thin_interval(
                        s,
                        a,
                        iu,
                        iv,
                        me,
                        r_max,
                        positions,
                        radii,
                        box,
                        walls,
                        reach,
                        heads,
                        next_in_bin,
                        exposed,
                        counts,
                        hits,
                        rays,
                        diag,
                        thin_faces,
                    )


@wp.kernel
def wet_thin_listed(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    box: WetBox,
    walls: LampWalls,
    reach: wp.array[wp.uint32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    rmax: wp.array[wp.float32],
    exposed: wp.array[wp.int32],
    thin_list: wp.array[wp.vec4i],
    thin_listed: wp.array[wp.int32],
    # outputs
    counts: wp.array[wp.int64],
    hits: wp.array[wp.int32],
    rays: wp.array[wp.int32],
    diag: wp.array[wp.int32],
    thin_faces: wp.array[wp.int32],
):
    """One thread per listed thin chord (``wet_thin``'s list: sphere, axis, row): the chord again (the same
    function on the same inputs), then ``thin_interval``. Few rows hold a thin chord with fluid on both sides (the
    bin walks and gap tests are theirs); listed, they no longer hold a warp of a thread per sphere and axis each."""
    t = wp.tid()
    if t >= wp.min(thin_listed[0], thin_list.shape[0]):
        return
    item = thin_list[t]
    me = thin_chord(item[0], item[1], item[2], item[3], positions, radii, box)
    thin_interval(
        item[0],
        item[1],
        item[2],
        item[3],
        me,
        wp.float64(rmax[0]),
        positions,
        radii,
        box,
        walls,
        reach,
        heads,
        next_in_bin,
        exposed,
        counts,
        hits,
        rays,
        diag,
        thin_faces,
    )
