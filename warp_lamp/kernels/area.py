"""Per-cell kernel of the lamp's visible-area criterion (issues 15, 19): gather, order, resolve, balance, scatter.

One thread per cell of the three grids handles both lamps of its cell. It reads the D-slot keys the depth pass
left at the cell's sample rays (the cell corners) and does, in this order, exactly what
``warp_lamp.reference.area.area_estimate_reference`` documents:

1. gather the seeds: the D slots of the 4 corner samples and slot 0 of the 8 ring samples, deduplicated, kept
   when the disk meets the cell's interior, ordered by (centre depth, id), at most ``MAX_SEEDS``; then cull those
   that cannot be first anywhere in the cell. With :data:`GATHER_BOTH` in the lamp mask the candidates are both
   lamps' keys. The depth pass may have left out the spheres :func:`area_hidden` found hidden (its D slots then
   hold the next spheres along each ray);
2. order the seeds for the cell: every pair whose disks overlap is ordered by which surface a ray meets first
   (the entry point for the low lamp, the exit point for the high one: :func:`surface_depth`) where that order
   holds on the whole cell (:func:`pair_relation`), and the seeds are put in a sequence that keeps every such
   pair (:func:`topo_order`). The cell is *undecided* where a pair's order may change inside it (the projection
   of two intersecting spheres' intersection circle, an ellipse, may cross it) or no sequence exists;
3. resolve each seed's share of the cell, every point to the seed whose surface its ray meets first.
   Sub-points: S x S points, each to the first seed whose disk holds it, or, in an undecided cell, by its surface
   depths (:func:`first_surface`). Exact: circle arcs clipped front to back in the sequence
   (:func:`exact_areas`); in an undecided cell a ``RASTER`` x ``RASTER`` raster of surface depths moves units
   between the seeds where the clip's sequence is wrong (:func:`raster_correction`);
4. balance: both lamps distribute the larger of their two rounded totals, by floor, remainder to the largest
   share;
5. scatter the units with integer atomic adds: + for the low lamp, - for the high lamp.

Key layout (the depth pass's output): grid a has (n_u + 1) x (n_v + 1) samples, row-major (j (n_u + 1) + i) from
``sample_offset[a]``; sample s holds ``2 D`` keys at ``keys[(2 s + side) D + k]``, k = 0 .. D-1 ascending,
side 0 the low lamp, 1 the high lamp, EMPTY_KEY where fewer than k + 1 spheres meet the ray. The keys order by the
surface depth at the corner ray (entry, or negated exit), the same order as step 2's.

Counts are int64: a particle's units on one axis reach ``cells x unit`` (4096 per whole cell for the exact
resolver), which passes 2^31 for a sphere of about 410 cells radius, a size the grid budget allows.

Everything is fixed-size local storage; nothing allocates. A cell with more than MAX_SEEDS seeds keeps the front
ones and counts itself in ``diag[DIAG_OVERFLOW]``; a cell one lamp cannot pay out counts in ``diag[DIAG_ONE_SIDED]``.

Candidates are spheres. A later kind (a planar occluder, whose depth is linear across the cell) enters through
:func:`surface_depth` and :func:`first_holder` for the points, and through :func:`pair_relation` as a pair that is
undecided wherever the plane may cut a sphere's surface inside the cell, which sends that cell to the per-point
surface depths (sub-points) or the raster (exact); the clip itself only ever sees disks.
"""

import warp as wp

from warp_lamp.kernels.grid import LampGridParams, frame_point, grid_cell
from warp_lamp.kernels.keys import EMPTY_KEY, key_owner, pack_key
from warp_lamp.kernels.lamp import LampParticles, frame_sphere

# fuse_fp off: the sub-point tests and the gather must round alike on CPU and CUDA (bitwise equal units).
wp.set_module_options({"enable_backward": False, "fuse_fp": False})

#: Most seeds per cell and lamp; the gather keeps the frontmost ones.
MAX_SEEDS = wp.constant(16)
#: Angular intervals per circle: the other seeds, plus 4 cell edges, rounded up.
MAX_IVL = wp.constant(20)
#: Points per cell edge of the exact resolver's raster (RASTER^2 = EXACT_UNIT: one unit per point).
RASTER = wp.constant(64)
#: Depth of a ray that misses a candidate.
MISS = wp.constant(wp.inf)

RESOLVER_EXACT = wp.constant(0)
RESOLVER_SUBPOINTS = wp.constant(1)
#: Lamp-mask bit (past the six lamps): each lamp gathers its cell's seeds from both lamps' keys.
GATHER_BOTH = wp.constant(64)
DIAG_OVERFLOW = wp.constant(0)
DIAG_ONE_SIDED = wp.constant(1)

#: Pair relations (:func:`pair_relation`).
REL_APART = wp.constant(0)
REL_KEEP = wp.constant(1)
REL_SWAP = wp.constant(2)
REL_UNDECIDED = wp.constant(3)

PI = wp.constant(3.14159265358979)
TWO_PI = wp.constant(6.28318530717959)

vec_seed_i = wp.types.vector(length=16, dtype=wp.int32)
vec_seed_f = wp.types.vector(length=16, dtype=wp.float32)
vec_seed_k = wp.types.vector(length=16, dtype=wp.uint64)
vec_ivl_f = wp.types.vector(length=20, dtype=wp.float32)
vec_ivl_i = wp.types.vector(length=20, dtype=wp.int32)
vec_cut = wp.types.vector(length=40, dtype=wp.float32)


@wp.func
def sort_cuts(cuts: vec_cut, n: wp.int32, end: wp.float32) -> vec_cut:
    """cuts[0 .. n-1] and ``end`` as cuts[n], sorted ascending by insertion (n <= 40: fewer compares than anything
    cleverer); the pieces are then cuts[k] .. cuts[k + 1] for k < n."""
    cuts[n] = end
    for m in range(1, n + 1):
        x = cuts[m]
        pos = m
        while pos > 0:
            if cuts[pos - 1] > x:
                cuts[pos] = cuts[pos - 1]
                pos -= 1
            else:
                break
        cuts[pos] = x
    return cuts


@wp.func
def cut_piece(cuts: vec_cut, k: wp.int32) -> wp.vec3:
    """Piece k of sorted cuts: (start, end, midpoint)."""
    return wp.vec3(cuts[k], cuts[k + 1], 0.5 * (cuts[k] + cuts[k + 1]))


@wp.func
def in_interval(t: wp.float32, phi: wp.float32, alpha: wp.float32) -> wp.int32:
    """Whether angle t lies within alpha of phi (alpha >= pi: always; alpha <= 0: never)."""
    if alpha >= PI:
        return 1
    if alpha <= 0.0:
        return 0
    off = t - phi
    off = off - TWO_PI * wp.floor((off + PI) / TWO_PI)
    if wp.abs(off) <= alpha:
        return 1
    return 0


@wp.func
def arc_integral(x: wp.float32, y: wp.float32, r: wp.float32, t1: wp.float32, t2: wp.float32) -> wp.float32:
    """1/2 of the integral of (x dy - y dx) along the circle (x, y, r) from angle t1 to t2 (counter-clockwise)."""
    return 0.5 * (r * r * (t2 - t1) + x * r * (wp.sin(t2) - wp.sin(t1)) - y * r * (wp.cos(t2) - wp.cos(t1)))


@wp.func
def exact_areas(ox: vec_seed_f, oy: vec_seed_f, rr: vec_seed_f, count: wp.int32, hu: wp.float32, hv: wp.float32):
    """Visible area of each seed (front to back) inside the cell [0, hu] x [0, hv], exact up to float32.

    Green's theorem about the cell centre; every boundary point is attributed, never clipped (see
    ``warp_lamp.reference_area``): a point of circle j inside the cell and not covered by an earlier seed is on
    the boundary of j's visible region, and reversed on that of the first later seed that covers it; a point of
    a cell edge belongs to the first seed that covers it. Coverage of circle j by disk i is an angular interval
    whose half-width acos((d^2 + (r_j - r_i)(r_j + r_i)) / (2 d r_j)) is clamped, so tangency (external or
    internal) and near-tangency move no decision abruptly; identical circles go to the earlier seed by rule.
    """
    hw = 0.5 * hu
    hh = 0.5 * hv
    area = vec_seed_f()
    for j in range(count):
        xj = ox[j] - hw
        yj = oy[j] - hh
        rj = rr[j]
        phi = vec_ivl_f()
        alpha = vec_ivl_f()
        owner = vec_ivl_i()
        n = int(0)
        for i in range(count):
            if i != j:
                dx = ox[i] - ox[j]
                dy = oy[i] - oy[j]
                if dx == 0.0 and dy == 0.0:
                    if rr[i] > rj or (rr[i] == rj and i < j):
                        phi[n] = 0.0
                        alpha[n] = PI
                        owner[n] = i
                        n += 1
                else:
                    d = wp.sqrt(dx * dx + dy * dy)
                    ca = (d * d + (rj - rr[i]) * (rj + rr[i])) / (2.0 * d * rj)
                    if ca < 1.0:
                        phi[n] = wp.atan2(dy, dx)
                        alpha[n] = wp.acos(wp.max(ca, -1.0))
                        owner[n] = i
                        n += 1
        # Outside the cell: left of x = 0 is |t - pi| < acos(ox / r), and so on; owner -1.
        gone = int(0)
        for e in range(4):
            v = float(0.0)
            c = float(0.0)
            if e == 0:
                v = ox[j]
                c = PI
            elif e == 1:
                v = hu - ox[j]
                c = 0.0
            elif e == 2:
                v = oy[j]
                c = -0.5 * PI
            else:
                v = hv - oy[j]
                c = 0.5 * PI
            q = v / rj
            if q <= -1.0:
                gone = 1
            if q < 1.0:
                phi[n] = c
                alpha[n] = wp.acos(wp.max(q, -1.0))
                owner[n] = -1
                n += 1
        if gone != 0:
            continue
        cuts = vec_cut()
        cuts[0] = 0.0
        m = int(1)
        for k in range(n):
            if alpha[k] > 0.0 and alpha[k] < PI:
                t_lo = phi[k] - alpha[k]
                t_hi = phi[k] + alpha[k]
                if t_lo < 0.0:
                    t_lo += TWO_PI
                if t_hi < 0.0:
                    t_hi += TWO_PI
                if t_lo >= TWO_PI:
                    t_lo -= TWO_PI
                if t_hi >= TWO_PI:
                    t_hi -= TWO_PI
                cuts[m] = t_lo
                cuts[m + 1] = t_hi
                m += 2
        cuts = sort_cuts(cuts, m, TWO_PI)
        for k in range(m):
            piece = cut_piece(cuts, k)
            if piece[1] > piece[0]:
                t1 = piece[0]
                t2 = piece[1]
                mid = piece[2]
                outside = int(0)
                first = count
                for b in range(n):
                    if in_interval(mid, phi[b], alpha[b]) != 0:
                        if owner[b] < 0:
                            outside = 1
                        elif owner[b] < first:
                            first = owner[b]
                if outside == 0 and first > j:
                    arc = arc_integral(xj, yj, rj, t1, t2)
                    area[j] = area[j] + arc
                    if first < count:
                        area[first] = area[first] - arc
    # Cell edges, counter-clockwise: each piece adds 1/2 (its line's distance from the centre) x length.
    for e in range(4):
        half = float(0.0)
        weight = float(0.0)
        lo = vec_seed_f()
        hi = vec_seed_f()
        cuts = vec_cut()
        if e < 2:
            half = hh
            weight = hw
        else:
            half = hw
            weight = hh
        cuts[0] = -half
        m = int(1)
        for i in range(count):
            dp = float(0.0)
            par = float(0.0)
            if e == 0:
                dp = ox[i]
                par = oy[i] - hh
            elif e == 1:
                dp = ox[i] - hu
                par = oy[i] - hh
            elif e == 2:
                dp = oy[i]
                par = ox[i] - hw
            else:
                dp = oy[i] - hv
                par = ox[i] - hw
            s2 = rr[i] * rr[i] - dp * dp
            if s2 > 0.0:
                w = wp.sqrt(s2)
                lo[i] = par - w
                hi[i] = par + w
                cuts[m] = wp.clamp(par - w, -half, half)
                cuts[m + 1] = wp.clamp(par + w, -half, half)
                m += 2
            else:
                lo[i] = 1.0
                hi[i] = -1.0
        cuts = sort_cuts(cuts, m, half)
        for k in range(m):
            piece = cut_piece(cuts, k)
            if piece[1] > piece[0]:
                first = int(-1)
                for i in range(count):
                    if first < 0 and piece[2] >= lo[i] and piece[2] <= hi[i]:
                        first = i
                if first >= 0:
                    area[first] = area[first] + 0.5 * weight * (piece[1] - piece[0])
    return area


@wp.func
def holds_corners(ox: wp.float32, oy: wp.float32, r: wp.float32, hu: wp.float32, hv: wp.float32) -> wp.int32:
    """Whether the disk holds all four corners of the cell [0, hu] x [0, hv] (float32, as the reference)."""
    r2 = r * r
    ax = 0.0 - ox
    bx = hu - ox
    ay = 0.0 - oy
    by = hv - oy
    if ax * ax + ay * ay <= r2 and bx * bx + ay * ay <= r2 and ax * ax + by * by <= r2 and bx * bx + by * by <= r2:
        return 1
    return 0


@wp.func
def surface_depth(
    ox: wp.float32, oy: wp.float32, oz: wp.float32, r: wp.float32, full: wp.int32, tx: wp.float32, ty: wp.float32
) -> wp.float32:
    """Depth at which the ray at (tx, ty) first meets a sphere (centre (ox, oy) in the cell, depth ``oz`` along the
    lamp, radius r): ``oz - sqrt(r^2 - d^2)``, or MISS where ``d^2 > r^2``; a sphere marked ``full`` (its disk
    holds the whole cell) is met everywhere. Float32, each product and sum rounded (the reference repeats it)."""
    dx = tx - ox
    dy = ty - oy
    d2 = dx * dx + dy * dy
    r2 = r * r
    if full == 0 and d2 > r2:
        return MISS
    return oz - wp.sqrt(wp.max(r2 - d2, 0.0))


@wp.func
def first_surface(
    ox: vec_seed_f,
    oy: vec_seed_f,
    oz: vec_seed_f,
    rr: vec_seed_f,
    full: wp.int32,
    count: wp.int32,
    tx: wp.float32,
    ty: wp.float32,
):
    """(the seed whose surface the ray at (tx, ty) meets first, ties to the earlier seed; the first seed whose disk
    holds the point), each ``count`` where none does. Seed ``full`` holds every point. Depths are only computed
    where a second seed holds the point (the same answer: the first holder wins unless another comes first)."""
    best = count
    holder = count
    depth = MISS
    for m in range(count):
        dx = tx - ox[m]
        dy = ty - oy[m]
        if m == full or dx * dx + dy * dy <= rr[m] * rr[m]:
            if holder == count:
                holder = m
                best = m
            else:
                if depth == MISS:
                    depth = surface_depth(ox[best], oy[best], oz[best], rr[best], 1, tx, ty)
                dm = surface_depth(ox[m], oy[m], oz[m], rr[m], 1, tx, ty)
                if dm < depth:
                    depth = dm
                    best = m
    return best, holder


@wp.func
def first_holder(
    ox: vec_seed_f, oy: vec_seed_f, rr: vec_seed_f, full: wp.int32, count: wp.int32, tx: wp.float32, ty: wp.float32
) -> wp.int32:
    """The first seed whose disk holds the point (tx, ty), ``count`` where none does; seed ``full`` holds every
    point. Where the seeds are in the surface order for the whole cell, it is the seed whose surface comes first."""
    for m in range(count):
        if m == full:
            return m
        dx = tx - ox[m]
        dy = ty - oy[m]
        if dx * dx + dy * dy <= rr[m] * rr[m]:
            return m
    return count


@wp.func
def subpoint_shares(
    ox: vec_seed_f,
    oy: vec_seed_f,
    oz: vec_seed_f,
    rr: vec_seed_f,
    full: wp.int32,
    count: wp.int32,
    hu: float,
    hv: float,
    s: int,
    undecided: wp.int32,
):
    """Sub-points won per seed: point (k, l) at ((k + 1/2) hu / S, (l + 1/2) hv / S) goes to the seed whose surface
    its ray meets first: the first seed whose disk holds it where the seeds are in the surface order for the whole
    cell, else by its surface depths (``undecided``). Float32, each product and sum rounded: the reference repeats
    it bitwise. Seed ``full`` holds every point. ``count`` >= 1."""
    shares = vec_seed_f()
    if count == 1 and full == 0:
        shares[0] = float(s * s)
        return shares
    su = hu / float(s)
    sv = hv / float(s)
    for k in range(s):
        tx = (float(k) + 0.5) * su
        for kv in range(s):
            ty = (float(kv) + 0.5) * sv
            won = count
            if undecided != 0:
                won, _holder = first_surface(ox, oy, oz, rr, full, count, tx, ty)
            else:
                won = first_holder(ox, oy, rr, full, count, tx, ty)
            if won < count:
                shares[won] = shares[won] + 1.0
    return shares


@wp.func
def subpoint_shares_rows(
    ox: vec_seed_f, oy: vec_seed_f, rr: vec_seed_f, full: wp.int32, count: wp.int32, hu: float, hv: float, s: int
) -> vec_seed_f:
    """``subpoint_shares`` of a decided cell (each point to the first seed whose disk holds it), seed by seed instead
    of point by point, for s <= 8: a 64-bit mask of the points already taken; a row of points whose squared distance
    along u alone exceeds r^2 is skipped (adding dy^2 >= 0 rounds to no less), as is a row already taken. The same
    float32 tests on the same points, so the same points per seed: bitwise ``subpoint_shares``'s shares."""
    shares = vec_seed_f()
    if count == 1 and full == 0:
        shares[0] = float(s * s)
        return shares
    su = hu / float(s)
    sv = hv / float(s)
    row_bits = (wp.uint64(1) << wp.uint64(s)) - wp.uint64(1)
    row_full = wp.uint32(row_bits)
    taken = wp.uint64(0)
    left = s * s
    for m in range(count):
        if left == 0:
            break
        xm = ox[m]
        ym = oy[m]
        r2 = rr[m] * rr[m]
        won = int(0)
        for k in range(s):
            shift = wp.uint64(k * s)
            # The row's points in 32 bits: the per-point tests and updates were most of this loop's instructions
            # in 64-bit shifts and masks.
            row = wp.uint32((taken >> shift) & row_bits)
            if row == row_full:
                continue
            tx = (float(k) + 0.5) * su
            dx = tx - xm
            ax = dx * dx
            if m != full and ax > r2:
                continue
            for kv in range(s):
                bit = wp.uint32(1) << wp.uint32(kv)
                if (row & bit) == wp.uint32(0):
                    ty = (float(kv) + 0.5) * sv
                    dy = ty - ym
                    if m == full or ax + dy * dy <= r2:
                        row = row | bit
                        won += 1
            taken = taken | (wp.uint64(row) << shift)
        shares[m] = float(won)
        left -= won
    return shares


@wp.func
def pair_relation(
    xe: wp.float32,
    ye: wp.float32,
    ze: wp.float32,
    re: wp.float32,
    xl: wp.float32,
    yl: wp.float32,
    zl: wp.float32,
    rl: wp.float32,
    hu: wp.float32,
    hv: wp.float32,
) -> wp.int32:
    """How seeds e (the earlier by centre depth) and l must be ordered for the clip in the cell [0, hu] x [0, hv].

    REL_APART: their disks do not overlap. REL_KEEP / REL_SWAP: e's surface (or l's) is the first of the two
    wherever both disks hold a point of the cell. REL_UNDECIDED: it may change inside the cell.

    l's surface can come first where both disks hold a point only where e's chord along the ray lies inside l's
    (else e enters first: its chord's midpoint, the centre depth, comes first). That region of e's disk is bounded
    by e's outline and by the projection of the points of the spheres' intersection circle where both chords
    begin or both end: those in front of both centres or behind both. So where the circle has no such point, or
    its projection (an ellipse) misses the cell (its bounding box misses it, or all four corners lie inside it),
    one answer holds on the whole of e's disk in the cell, read at its point nearest e's centre. Disjoint spheres
    keep e first; a sphere inside the other is behind it everywhere. Float32 (the reference repeats it bitwise).
    """
    dx = xl - xe
    dy = yl - ye
    dz = zl - ze
    rs = re + rl
    dp = dx * dx + dy * dy
    if dp >= rs * rs:
        return REL_APART
    d2 = dp + dz * dz
    if d2 >= rs * rs:
        return REL_KEEP
    rd = re - rl
    if d2 <= rd * rd:
        if re < rl:
            return REL_SWAP
        return REL_KEEP
    re2 = re * re
    rl2 = rl * rl
    # The intersection circle: centre e + t (l - e), radius^2 rho2, normal along (dx, dy, dz).
    t = (d2 + re2 - rl2) / (2.0 * d2)
    rho2 = wp.max(re2 - t * t * d2, 0.0)
    mu = xe + t * dx
    mv = ye + t * dy
    ma = ze + t * dz
    bu = wp.sqrt(rho2 * (dy * dy + dz * dz) / d2)
    bv = wp.sqrt(rho2 * (dx * dx + dz * dz) / d2)
    ba = wp.sqrt(rho2 * (dx * dx + dy * dy) / d2)
    # Only points of the circle in front of both centres or behind both bound the region; and only if the
    # ellipse's bounding box meets the cell.
    flips = (ma - ba < ze or ma + ba > zl) and mu - bu <= hu and mu + bu >= 0.0 and mv - bv <= hv and mv + bv >= 0.0
    if flips:
        # Inside the ellipse: dz^2 |q - m|^2 + ((dx, dy) . (q - m))^2 < dz^2 rho2.
        inside = int(1)
        for corner in range(4):
            du = wp.where(corner % 2 == 1, hu, 0.0) - mu
            dv = wp.where(corner / 2 == 1, hv, 0.0) - mv
            w = dx * du + dy * dv
            q = dz * dz * (du * du + dv * dv) + w * w - dz * dz * rho2
            if not (q < 0.0):
                inside = 0
        if inside == 0:
            return REL_UNDECIDED
    qx = wp.clamp(xe, 0.0, hu)
    qy = wp.clamp(ye, 0.0, hv)
    lx = qx - xl
    ly = qy - yl
    dl = lx * lx + ly * ly
    if dl > rl2:
        return REL_KEEP
    ex = qx - xe
    ey = qy - ye
    se = wp.sqrt(wp.max(re2 - (ex * ex + ey * ey), 0.0))
    sl = wp.sqrt(rl2 - dl)
    if zl - sl <= ze - se and ze + se <= zl + sl:
        return REL_SWAP
    return REL_KEEP


@wp.func
def topo_order(prec: vec_seed_i, count: wp.int32) -> vec_seed_i:
    """An order of seeds 0 .. count-1 in which every seed comes after those in its ``prec`` bit mask, taking the
    lowest free index at each step; order[0] = -1 where the constraints have a cycle."""
    order = vec_seed_i()
    placed = int(0)
    for step in range(count):
        pick = int(-1)
        for k in range(count):
            if pick < 0 and ((placed >> k) & 1) == 0 and (prec[k] & ~placed) == 0:
                pick = k
        if pick < 0:
            order[0] = -1
            return order
        order[step] = pick
        placed = placed | (1 << pick)
    return order


@wp.func
def raster_correction(
    ox: vec_seed_f,
    oy: vec_seed_f,
    oz: vec_seed_f,
    rr: vec_seed_f,
    full: wp.int32,
    count: wp.int32,
    hu: float,
    hv: float,
    weight: float,
) -> vec_seed_f:
    """On RASTER x RASTER points of the cell (as the sub-points), ``weight`` per point from the first seed whose disk
    holds it (whom the clip gave it) to the seed whose surface comes first there, where they differ."""
    corr = vec_seed_f()
    su = hu / float(RASTER)
    sv = hv / float(RASTER)
    for k in range(RASTER):
        tx = (float(k) + 0.5) * su
        for kv in range(RASTER):
            ty = (float(kv) + 0.5) * sv
            won, holder = first_surface(ox, oy, oz, rr, full, count, tx, ty)
            if won != holder:
                corr[won] = corr[won] + weight
                corr[holder] = corr[holder] - weight
    return corr


@wp.struct
class SeedList:
    """One lamp's seeds for one cell after steps 1-2: particle ids and their disks in the cell's coordinates
    (centre ``ox``, ``oy``, depth ``oz`` along the lamp, radius ``rr``) in clip order, how many, the first that holds
    the whole cell (-1: none), whether the order is ``undecided`` somewhere in the cell, and the gather's
    ``overflow``."""

    ids: vec_seed_i
    ox: vec_seed_f
    oy: vec_seed_f
    oz: vec_seed_f
    rr: vec_seed_f
    count: wp.int32
    full: wp.int32
    undecided: wp.int32
    overflow: wp.int32


@wp.struct
class SideShares:
    """One lamp's shares of one cell: its seeds' particle ids and shares (units of ``unit`` per cell), how many,
    their float sum in seed order, whether the gather overflowed, and the deferred-work item that still owes points
    (-1: none; the exact resolver's clip is in ``shares`` already)."""

    ids: vec_seed_i
    shares: vec_seed_f
    count: wp.int32
    total: wp.float32
    overflow: wp.int32
    work: wp.int32


@wp.func
def side_seeds(
    grid: LampGridParams,
    particles: LampParticles,
    keys: wp.array[wp.uint64],
    d: wp.int32,
    sample_offset: wp.vec3i,
    a: wp.int32,
    i: wp.int32,
    j: wp.int32,
    side_gather: wp.int32,
) -> SeedList:
    """Steps 1-2 of the module docstring for lamp ``side`` of cell (i, j) of grid a: gather, cull, order.
    ``side_gather`` is side + 2 (:data:`GATHER_BOTH` set in the lamp mask): the candidates are both lamps' keys
    (the reference's ``_cell_seeds="both"``), each ordered by this lamp's depth."""
    side = side_gather & 1
    passes = 1 + (side_gather >> 1)
    nu = grid.n_u[a]
    nv = grid.n_v[a]
    hu = grid.h_u[a]
    hv = grid.h_v[a]
    x0 = float(i) * hu
    y0 = float(j) * hv
    overflow = int(0)
    ids = vec_seed_i()
    okeys = vec_seed_k()
    ox = vec_seed_f()
    oy = vec_seed_f()
    oz = vec_seed_f()
    rr = vec_seed_f()
    count = int(0)
    # The frame read once: every candidate is moved into it alike.
    frame_o = grid.origin[0]
    frame_r = grid.rotation[0]
    # Candidates in this order: corner samples (0,0) (1,0) (0,1) (1,1), all D slots; then the ring, slot 0 (then
    # the other lamp's, with GATHER_BOTH). Counters, not divisions of the loop index: the gather's index arithmetic
    # was a third of its instructions on CUDA (D is known only at run time).
    corner = int(0)
    slot = int(-1)
    ring = int(-1)
    key_side = side
    for _mm in range(passes * (4 * d + 8)):
        if ring < 0:
            slot += 1
            if slot == d:
                slot = 0
                corner += 1
                if corner == 4:
                    ring = 0
        else:
            ring += 1
            if ring == 8:
                ring = -1
                corner = 0
                slot = 0
                key_side = 1 - side
        di = corner & 1
        dj = corner >> 1
        sl = slot
        if ring >= 0:
            sl = 0
            if ring < 4:
                di = wp.where(ring < 2, -1, 2)
                dj = ring & 1
            else:
                di = ring & 1
                dj = wp.where(ring < 6, -1, 2)
        si = i + di
        sj = j + dj
        if si < 0 or si > nu or sj < 0 or sj > nv:
            continue
        key = keys[(2 * (sample_offset[a] + sj * (nu + 1) + si) + key_side) * d + sl]
        if key == EMPTY_KEY:
            continue
        pid = key_owner(key)
        # The duplicate scan runs to the end: a break at a match splits the warp, and the rest of the candidate's
        # work then runs once per split (measured: 3x the particle reads' instructions on CUDA).
        dup = int(0)
        for k in range(count):
            if ids[k] == pid:
                dup = 1
        if dup != 0:
            continue
        p = frame_point(frame_o, frame_r, particles.positions[pid])
        r = particles.radii[pid]
        cx = (p[(a + 1) % 3] - grid.corner_u[a]) - x0
        cy = (p[(a + 2) % 3] - grid.corner_v[a]) - y0
        gx = wp.max(wp.max(-cx, cx - hu), 0.0)
        gy = wp.max(wp.max(-cy, cy - hv), 0.0)
        if not (gx * gx + gy * gy < r * r):
            continue
        depth = p[a]
        if side == 1:
            depth = -p[a]
        okey = pack_key(depth, pid)
        if count == MAX_SEEDS:
            overflow = 1
            if okey >= okeys[MAX_SEEDS - 1]:
                continue
            count = MAX_SEEDS - 1
        pos = count
        while pos > 0:
            if okeys[pos - 1] > okey:
                okeys[pos] = okeys[pos - 1]
                ids[pos] = ids[pos - 1]
                ox[pos] = ox[pos - 1]
                oy[pos] = oy[pos - 1]
                oz[pos] = oz[pos - 1]
                rr[pos] = rr[pos - 1]
                pos -= 1
            else:
                break
        okeys[pos] = okey
        ids[pos] = pid
        ox[pos] = cx
        oy[pos] = cy
        oz[pos] = depth
        rr[pos] = r
        count += 1
    # Cull seeds that can win nothing (the reference's _cull): concentric with a kept earlier seed and not
    # larger; or, after the first seed whose disk holds all four corners (it holds the whole cell), one whose
    # surface is behind that one's on the whole cell (pair_relation: disjoint spheres, nested, or chords
    # never holding that one's there).
    kept = int(0)
    full = int(-1)
    for k in range(count):
        drop = int(0)
        for k2 in range(kept):
            if ox[k2] == ox[k] and oy[k2] == oy[k] and rr[k] <= rr[k2]:
                drop = 1
        if drop == 0 and full >= 0:
            rel = pair_relation(ox[full], oy[full], oz[full], rr[full], ox[k], oy[k], oz[k], rr[k], hu, hv)
            if rel == REL_KEEP or rel == REL_APART:
                drop = 1
        if drop == 0:
            ids[kept] = ids[k]
            ox[kept] = ox[k]
            oy[kept] = oy[k]
            oz[kept] = oz[k]
            rr[kept] = rr[k]
            if full < 0 and holds_corners(ox[k], oy[k], rr[k], hu, hv) != 0:
                full = kept
            kept += 1
    count = kept
    # The seeds' order: the surface order wherever it holds on the whole cell; else each point's surface
    # depths decide (sub-points), or the raster corrects the clip (exact).
    undecided = int(0)
    if count > 1:
        prec = vec_seed_i()
        for k1 in range(1, count):
            for k0 in range(k1):
                rel = pair_relation(ox[k0], oy[k0], oz[k0], rr[k0], ox[k1], oy[k1], oz[k1], rr[k1], hu, hv)
                if rel == REL_KEEP:
                    prec[k1] = prec[k1] | (1 << k0)
                elif rel == REL_SWAP:
                    prec[k0] = prec[k0] | (1 << k1)
                elif rel == REL_UNDECIDED:
                    undecided = 1
        order = topo_order(prec, count)
        if order[0] < 0:
            undecided = 1
        else:
            ids_c = ids
            ox_c = ox
            oy_c = oy
            oz_c = oz
            rr_c = rr
            full_c = full
            for k in range(count):
                o = order[k]
                ids[k] = ids_c[o]
                ox[k] = ox_c[o]
                oy[k] = oy_c[o]
                oz[k] = oz_c[o]
                rr[k] = rr_c[o]
                if o == full_c:
                    full = k
    out = SeedList()
    out.ids = ids
    out.ox = ox
    out.oy = oy
    out.oz = oz
    out.rr = rr
    out.count = count
    out.full = full
    out.undecided = undecided
    out.overflow = overflow
    return out


@wp.func
def clip_shares(seeds: SeedList, hu: wp.float32, hv: wp.float32, unit: wp.int32) -> vec_seed_f:
    """The exact resolver's clip, in units: circle arcs clipped front to back in the seeds' order."""
    shares = vec_seed_f()
    areas = exact_areas(seeds.ox, seeds.oy, seeds.rr, seeds.count, hu, hv)
    for k in range(seeds.count):
        shares[k] = areas[k] / (hu * hv) * float(unit)
    return shares


@wp.func
def finish_shares(seeds: SeedList, shares: vec_seed_f) -> SideShares:
    """Step 3's result as the payout reads it: the shares and their float sum in seed order."""
    total = float(0.0)
    for k in range(seeds.count):
        total += shares[k]
    out = SideShares()
    out.ids = seeds.ids
    out.shares = shares
    out.count = seeds.count
    out.total = total
    out.overflow = seeds.overflow
    out.work = -1
    return out


@wp.func
def resolve_subpoints(seeds: SeedList, hu: wp.float32, hv: wp.float32, subpoints: wp.int32) -> vec_seed_f:
    """Step 3 on sub-points, in one thread: each point to the first seed whose disk holds it (the surface order
    holds on the whole cell), or by its surface depths (``undecided``)."""
    shares = vec_seed_f()
    if seeds.count > 0:
        shares = subpoint_shares(
            seeds.ox, seeds.oy, seeds.oz, seeds.rr, seeds.full, seeds.count, hu, hv, subpoints, seeds.undecided
        )
    return shares


@wp.func
def resolve_exact(seeds: SeedList, hu: wp.float32, hv: wp.float32, unit: wp.int32) -> vec_seed_f:
    """Step 3 exactly, in one thread: the clip, and in an undecided cell the raster's correction."""
    shares = vec_seed_f()
    if seeds.count > 0:
        shares = clip_shares(seeds, hu, hv, unit)
        if seeds.undecided != 0:
            weight = float(unit) / float(RASTER * RASTER)
            corr = raster_correction(seeds.ox, seeds.oy, seeds.oz, seeds.rr, seeds.full, seeds.count, hu, hv, weight)
            for k in range(seeds.count):
                shares[k] = wp.max(shares[k] + corr[k], 0.0)
    return shares


@wp.func
def resolve(
    seeds: SeedList, hu: wp.float32, hv: wp.float32, resolver: wp.int32, subpoints: wp.int32, unit: wp.int32
) -> SideShares:
    """Step 3 in one thread, the resolver chosen at run time."""
    if resolver == RESOLVER_SUBPOINTS:
        return finish_shares(seeds, resolve_subpoints(seeds, hu, hv, subpoints))
    return finish_shares(seeds, resolve_exact(seeds, hu, hv, unit))


@wp.func
def side_shares(
    grid: LampGridParams,
    particles: LampParticles,
    keys: wp.array[wp.uint64],
    d: wp.int32,
    sample_offset: wp.vec3i,
    a: wp.int32,
    i: wp.int32,
    j: wp.int32,
    side: wp.int32,
    resolver: wp.int32,
    subpoints: wp.int32,
    unit: wp.int32,
) -> SideShares:
    """Steps 1-3 for lamp ``side`` of cell (i, j) of grid a, in one thread (``side`` as ``side_seeds``'s
    ``side_gather``)."""
    seeds = side_seeds(grid, particles, keys, d, sample_offset, a, i, j, side)
    return resolve(seeds, grid.h_u[a], grid.h_v[a], resolver, subpoints, unit)


@wp.func
def pay_out(
    a: wp.int32,
    bits: wp.int32,
    s0: SideShares,
    s1: SideShares,
    resolver: wp.int32,
    # outputs
    counts: wp.array[wp.int64],
    diag: wp.array[wp.int32],
):
    """Steps 4-5: both lamps pay the larger of their rounded totals, by floor, remainder to the largest share."""
    ids0 = s0.ids
    ids1 = s1.ids
    share0 = s0.shares
    share1 = s1.shares
    count0 = s0.count
    count1 = s1.count
    sum0 = s0.total
    sum1 = s1.total
    total0 = int(wp.floor(sum0 + 0.5))
    total1 = int(wp.floor(sum1 + 0.5))
    overflow = s0.overflow | s1.overflow
    if overflow != 0:
        wp.atomic_add(diag, DIAG_OVERFLOW, 1)
    big = wp.max(total0, total1)
    if big <= 0:
        return
    # A lamp that is on but holds no positive share cannot pay out: the cell gives nothing on either side.
    for side in range(2):
        if ((bits >> side) & 1) != 0:
            s = sum0
            if side == 1:
                s = sum1
            if not (s > 0.0):
                big = 0
    if big == 0:
        wp.atomic_add(diag, DIAG_ONE_SIDED, 1)
        return
    for side in range(2):
        if ((bits >> side) & 1) == 0:
            continue
        sh = share0
        ids = ids0
        n = count0
        s = sum0
        sign = wp.int64(1)
        if side == 1:
            sh = share1
            ids = ids1
            n = count1
            s = sum1
            sign = wp.int64(-1)
        units = vec_seed_i()
        given = int(0)
        best = int(0)
        for k in range(n):
            if resolver == RESOLVER_SUBPOINTS:
                # Integer floor division: exact, as the reference's float64 floor of the same quotient.
                units[k] = (big * int(sh[k])) / int(s)
            else:
                units[k] = int(wp.floor(float(big) * sh[k] / s))
            given += units[k]
            if sh[k] > sh[best]:
                best = k
        units[best] = units[best] + (big - given)
        for k in range(n):
            if units[k] != 0:
                wp.atomic_add(counts, 3 * ids[k] + a, sign * wp.int64(units[k]))


@wp.kernel
def area_cells(
    grid: LampGridParams,
    particles: LampParticles,
    keys: wp.array[wp.uint64],
    depth_slots: wp.int32,
    sample_offset: wp.vec3i,
    lamp_mask: wp.int32,
    resolver: wp.int32,
    subpoints: wp.int32,
    unit: wp.int32,
    # outputs
    counts: wp.array[wp.int64],
    diag: wp.array[wp.int32],
):
    """One thread per cell: gather, resolve, balance and scatter both lamps of the cell (module docstring)."""
    c = wp.tid()
    cell = grid_cell(grid, c)
    a = cell[0]
    bits = (lamp_mask >> (2 * a)) & 3
    if bits == 0:
        return
    both = wp.where((lamp_mask & GATHER_BOTH) != 0, 2, 0)
    s0 = SideShares()
    s1 = SideShares()
    if (bits & 1) != 0:
        s0 = side_shares(
            grid, particles, keys, depth_slots, sample_offset, a, cell[1], cell[2], 0 + both, resolver, subpoints, unit
        )
    if (bits & 2) != 0:
        s1 = side_shares(
            grid, particles, keys, depth_slots, sample_offset, a, cell[1], cell[2], 1 + both, resolver, subpoints, unit
        )
    pay_out(a, bits, s0, s1, resolver, counts, diag)


@wp.func
def row_points(
    seeds: SeedList, hu: wp.float32, hv: wp.float32, n: wp.int32, row: wp.int32, exact: wp.bool
) -> vec_seed_i:
    """One row (k = ``row``) of an undecided cell's n x n points, by surface depth: the points each seed wins
    (sub-points), or the raster correction's units per seed (exact: +1 to the surface's seed, -1 to the clip's where
    they differ), exactly what ``subpoint_shares`` and ``raster_correction`` add in that row."""
    out = vec_seed_i()
    su = hu / float(n)
    sv = hv / float(n)
    tx = (float(row) + 0.5) * su
    for kv in range(n):
        ty = (float(kv) + 0.5) * sv
        won, holder = first_surface(seeds.ox, seeds.oy, seeds.oz, seeds.rr, seeds.full, seeds.count, tx, ty)
        if exact:
            if won != holder:
                out[won] = out[won] + 1
                out[holder] = out[holder] - 1
        elif won < seeds.count:
            out[won] = out[won] + 1
    return out


def _area_kernels(exact: bool):
    """The cell pass specialised for one resolver (a kernel that never runs the other's code keeps fewer registers),
    with its undecided cells deferred: the cells whose order the pair relations cannot settle for the whole cell
    are the pass's stragglers (one thread would run S x S or 64 x 64 surface depths alone), so the cell pass leaves
    them in a work list and a second kernel spreads their points over a thread per row; a third pays them out.
    Bitwise the same as ``area_cells``: the rows add the same integers the one thread adds."""
    rows_per_cell = RASTER

    @wp.kernel
    def area_cells_deferred(
        grid: LampGridParams,
        particles: LampParticles,
        keys: wp.array[wp.uint64],
        depth_slots: wp.int32,
        sample_offset: wp.vec3i,
        lamp_mask: wp.int32,
        subpoints: wp.int32,
        unit: wp.int32,
        # outputs
        counts: wp.array[wp.int64],
        diag: wp.array[wp.int32],
        work: wp.array[SeedList],
        work_shares: wp.array[SideShares],
        work_cells: wp.array[wp.int32],
        work_count: wp.array[wp.int32],
    ):
        """One thread per cell: decided cells as ``area_cells``; a cell with an undecided lamp goes to the work
        list (both lamps' seeds, the clip's shares for the exact resolver) while there is room."""
        c = wp.tid()
        cell = grid_cell(grid, c)
        a = cell[0]
        bits = (lamp_mask >> (2 * a)) & 3
        if bits == 0:
            return
        hu = grid.h_u[a]
        hv = grid.h_v[a]
        both = wp.where((lamp_mask & GATHER_BOTH) != 0, 2, 0)
        q0 = SeedList()
        q1 = SeedList()
        if (bits & 1) != 0:
            q0 = side_seeds(grid, particles, keys, depth_slots, sample_offset, a, cell[1], cell[2], 0 + both)
        if (bits & 2) != 0:
            q1 = side_seeds(grid, particles, keys, depth_slots, sample_offset, a, cell[1], cell[2], 1 + both)
        slot = int(-1)
        if q0.undecided != 0 or q1.undecided != 0:
            slot = wp.atomic_add(work_count, 0, 1)
            if slot >= work_cells.shape[0]:
                slot = -1
        s0 = SideShares()
        s1 = SideShares()
        for side in range(2):
            q = q0
            if side == 1:
                q = q1
            sh = vec_seed_f()
            if wp.static(exact):
                if slot >= 0 and q.count > 0:
                    sh = clip_shares(q, hu, hv, unit)
                else:
                    sh = resolve_exact(q, hu, hv, unit)
            else:
                if slot < 0 or q.undecided == 0:
                    sh = resolve_subpoints(q, hu, hv, subpoints)
            out = finish_shares(q, sh)
            if slot >= 0 and q.undecided != 0:
                out.work = 2 * slot + side
            if side == 0:
                s0 = out
            else:
                s1 = out
        if slot < 0:
            pay_out(a, bits, s0, s1, RESOLVER_EXACT if wp.static(exact) else RESOLVER_SUBPOINTS, counts, diag)
            return
        work[2 * slot] = q0
        work[2 * slot + 1] = q1
        work_shares[2 * slot] = s0
        work_shares[2 * slot + 1] = s1
        work_cells[slot] = c

    @wp.kernel
    def area_rows(
        grid: LampGridParams,
        work: wp.array[SeedList],
        work_shares: wp.array[SideShares],
        work_cells: wp.array[wp.int32],
        work_count: wp.array[wp.int32],
        subpoints: wp.int32,
        # outputs
        work_units: wp.array[wp.int32],
    ):
        """One thread per (deferred cell, lamp, row of points): that row's units per seed, added atomically."""
        t = wp.tid()
        n = subpoints
        if wp.static(exact):
            n = rows_per_cell
        item = t / n
        row = t - item * n
        slot = item / 2
        if slot >= wp.min(work_count[0], work_cells.shape[0]):
            return
        if work_shares[item].work < 0 or row >= n:
            return
        a = grid_cell(grid, work_cells[slot])[0]
        seeds = work[item]
        units = row_points(seeds, grid.h_u[a], grid.h_v[a], n, row, wp.static(exact))
        for k in range(seeds.count):
            if units[k] != 0:
                wp.atomic_add(work_units, 16 * item + k, units[k])

    @wp.kernel
    def area_payout_deferred(
        grid: LampGridParams,
        work_shares: wp.array[SideShares],
        work_cells: wp.array[wp.int32],
        work_count: wp.array[wp.int32],
        work_units: wp.array[wp.int32],
        lamp_mask: wp.int32,
        unit: wp.int32,
        # outputs
        counts: wp.array[wp.int64],
        diag: wp.array[wp.int32],
    ):
        """One thread per deferred cell: the rows' units into the shares, then the payout."""
        slot = wp.tid()
        if slot >= wp.min(work_count[0], work_cells.shape[0]):
            return
        a = grid_cell(grid, work_cells[slot])[0]
        bits = (lamp_mask >> (2 * a)) & 3
        s0 = work_shares[2 * slot]
        s1 = work_shares[2 * slot + 1]
        for side in range(2):
            s = s0
            if side == 1:
                s = s1
            if s.work >= 0:
                sh = s.shares
                for k in range(s.count):
                    u = float(work_units[16 * s.work + k])
                    if wp.static(exact):
                        sh[k] = wp.max(sh[k] + u * (float(unit) / float(RASTER * RASTER)), 0.0)
                    else:
                        sh[k] = u
                total = float(0.0)
                for k in range(s.count):
                    total += sh[k]
                s.shares = sh
                s.total = total
                if side == 0:
                    s0 = s
                else:
                    s1 = s
        pay_out(a, bits, s0, s1, RESOLVER_EXACT if wp.static(exact) else RESOLVER_SUBPOINTS, counts, diag)

    return area_cells_deferred, area_rows, area_payout_deferred


AREA_DEFERRED = {RESOLVER_SUBPOINTS: _area_kernels(False), RESOLVER_EXACT: _area_kernels(True)}


def _side_kernels(exact: bool):
    """The cell pass with a thread per (lamp side, cell) instead of one per cell, for one resolver: each thread
    runs one lamp's gather, order and resolution (a cell's two lamps share no seeds, so one thread per cell ran two
    independent chains back to back and the pass waited for the longest pair), leaves its shares in ``sides``, and a
    light kernel per cell balances and pays both lamps. Undecided lamps go to a work list (one item per lamp, not
    per cell) whose rows a thread each resolves, as ``_area_kernels``. Bitwise the same as ``area_cells``: each lamp's
    shares come from the same functions on the same seeds, the rows add the same integers, and the payout is
    ``pay_out`` on the same two ``SideShares``. Threads are numbered side-major (t = side n_cells + c), so that a warp
    holds neighbouring cells of one lamp, whose seeds and branches are alike."""
    rows_per_cell = RASTER

    @wp.kernel
    def area_sides(
        grid: LampGridParams,
        particles: LampParticles,
        keys: wp.array[wp.uint64],
        depth_slots: wp.int32,
        sample_offset: wp.vec3i,
        lamp_mask: wp.int32,
        subpoints: wp.int32,
        unit: wp.int32,
        row_masks: wp.int32,
        # outputs
        sides: wp.array[SideShares],
        work: wp.array[SeedList],
        work_items: wp.array[wp.int32],
        work_count: wp.array[wp.int32],
    ):
        """One thread per (lamp side, cell): steps 1-3 for that lamp into ``sides[t]``; an undecided lamp goes to the
        work list while there is room (with the exact resolver's clip in its shares), else it is resolved here."""
        t = wp.tid()
        side = wp.where(t >= grid.n_cells, 1, 0)
        c = t - side * grid.n_cells
        cell = grid_cell(grid, c)
        a = cell[0]
        if ((lamp_mask >> (2 * a + side)) & 1) == 0:
            return
        hu = grid.h_u[a]
        hv = grid.h_v[a]
        both = wp.where((lamp_mask & GATHER_BOTH) != 0, 2, 0)
        q = side_seeds(grid, particles, keys, depth_slots, sample_offset, a, cell[1], cell[2], side + both)
        slot = int(-1)
        if q.undecided != 0 and work.shape[0] > 0:
            slot = wp.atomic_add(work_count, 0, 1)
            if slot >= work.shape[0]:
                slot = -1
        sh = vec_seed_f()
        if wp.static(exact):
            if slot >= 0 and q.count > 0:
                sh = clip_shares(q, hu, hv, unit)
            else:
                sh = resolve_exact(q, hu, hv, unit)
        else:
            if slot < 0:
                if q.undecided == 0 and q.count > 0 and subpoints <= 8 and row_masks != 0:
                    sh = subpoint_shares_rows(q.ox, q.oy, q.rr, q.full, q.count, hu, hv, subpoints)
                else:
                    sh = resolve_subpoints(q, hu, hv, subpoints)
        out = finish_shares(q, sh)
        if slot >= 0:
            out.work = slot
            work[slot] = q
            work_items[slot] = t
        sides[t] = out

    @wp.kernel
    def area_side_rows(
        grid: LampGridParams,
        work: wp.array[SeedList],
        work_items: wp.array[wp.int32],
        work_count: wp.array[wp.int32],
        subpoints: wp.int32,
        # outputs
        work_units: wp.array[wp.int32],
    ):
        """One thread per (work item, row of points): that row's units per seed, added atomically."""
        t = wp.tid()
        n = subpoints
        if wp.static(exact):
            n = rows_per_cell
        item = t / n
        row = t - item * n
        if item >= wp.min(work_count[0], work.shape[0]):
            return
        c = work_items[item]
        if c >= grid.n_cells:
            c -= grid.n_cells
        a = grid_cell(grid, c)[0]
        seeds = work[item]
        units = row_points(seeds, grid.h_u[a], grid.h_v[a], n, row, wp.static(exact))
        for k in range(seeds.count):
            if units[k] != 0:
                wp.atomic_add(work_units, 16 * item + k, units[k])

    @wp.kernel
    def area_side_payout(
        grid: LampGridParams,
        sides: wp.array[SideShares],
        work_units: wp.array[wp.int32],
        lamp_mask: wp.int32,
        unit: wp.int32,
        # outputs
        counts: wp.array[wp.int64],
        diag: wp.array[wp.int32],
    ):
        """One thread per cell: the work list's units into an undecided lamp's shares (as
        ``area_payout_deferred``), then steps 4-5 for both lamps."""
        c = wp.tid()
        a = grid_cell(grid, c)[0]
        bits = (lamp_mask >> (2 * a)) & 3
        if bits == 0:
            return
        s0 = SideShares()
        s1 = SideShares()
        for side in range(2):
            if ((bits >> side) & 1) != 0:
                s = sides[side * grid.n_cells + c]
                if s.work >= 0:
                    sh = s.shares
                    for k in range(s.count):
                        u = float(work_units[16 * s.work + k])
                        if wp.static(exact):
                            sh[k] = wp.max(sh[k] + u * (float(unit) / float(RASTER * RASTER)), 0.0)
                        else:
                            sh[k] = u
                    total = float(0.0)
                    for k in range(s.count):
                        total += sh[k]
                    s.shares = sh
                    s.total = total
                if side == 0:
                    s0 = s
                else:
                    s1 = s
        pay_out(a, bits, s0, s1, RESOLVER_EXACT if wp.static(exact) else RESOLVER_SUBPOINTS, counts, diag)

    return area_sides, area_side_rows, area_side_payout


AREA_SIDES = {RESOLVER_SUBPOINTS: _side_kernels(False), RESOLVER_EXACT: _side_kernels(True)}


@wp.kernel
def area_hidden(
    grid: LampGridParams,
    particles: LampParticles,
    keys: wp.array[wp.uint64],
    depth_slots: wp.int32,
    sample_offset: wp.vec3i,
    lamp_mask: wp.int32,
    # outputs
    hidden: wp.array[wp.int32],
):
    """One thread per sphere B: set bit 2 a + side of ``hidden[B]`` where one sphere A among the D keys of the corner
    sample nearest B's centre hides B from that lamp (``warp_lamp.reference.hidden_spheres``, bitwise): B's disk
    inside A's, ``e = |o| + r_B < r_A``, and B's nearest point behind A's surface at its deepest over B's disk,
    ``z_B - r_B > z_A - sqrt(r_A^2 - e^2)``. Bits already set stay set (a later round adds to them)."""
    b = wp.tid()
    sphere = frame_sphere(grid, particles, b)
    if not sphere.casts:
        return
    bits = hidden[b]
    rb = sphere.radius
    frame_o = grid.origin[0]
    frame_r = grid.rotation[0]
    for a in range(3):
        if ((lamp_mask >> (2 * a)) & 3) == 0:
            continue
        nu = grid.n_u[a]
        nv = grid.n_v[a]
        pu = sphere.center[(a + 1) % 3] - grid.corner_u[a]
        pv = sphere.center[(a + 2) % 3] - grid.corner_v[a]
        si = wp.clamp(int(wp.floor(pu / grid.h_u[a] + 0.5)), 0, nu)
        sj = wp.clamp(int(wp.floor(pv / grid.h_v[a] + 0.5)), 0, nv)
        sample = sample_offset[a] + sj * (nu + 1) + si
        for side in range(2):
            bit = 1 << (2 * a + side)
            if (lamp_mask & bit) == 0 or (bits & bit) != 0:
                continue
            zb = sphere.center[a]
            if side == 1:
                zb = -zb
            for k in range(depth_slots):
                key = keys[(2 * sample + side) * depth_slots + k]
                if key == EMPTY_KEY:
                    continue
                h = key_owner(key)
                if h == b:
                    continue
                ph = frame_point(frame_o, frame_r, particles.positions[h])
                rh = particles.radii[h]
                du = pu - (ph[(a + 1) % 3] - grid.corner_u[a])
                dv = pv - (ph[(a + 2) % 3] - grid.corner_v[a])
                e = wp.sqrt(du * du + dv * dv) + rb
                zh = ph[a]
                if side == 1:
                    zh = -zh
                if e < rh and zb - rb > zh - wp.sqrt(wp.max(rh * rh - e * e, 0.0)):
                    bits = bits | bit
    hidden[b] = bits


@wp.kernel
def area_unhide(
    sample_offset: wp.vec3i,
    depth_slots: wp.int32,
    hidden: wp.array[wp.int32],
    # outputs
    keys: wp.array[wp.uint64],
):
    """One thread per (corner sample, lamp side): drop from its D-slot list the keys of the spheres ``hidden`` flags
    for that lamp, the rest moved up in order and EMPTY_KEY after them. What stays is a prefix of the D smallest keys
    the flagged spheres leave (the list held the D smallest of all), so a depth pass that offers every sphere but
    the flagged ones over it ends with the same D keys as one over emptied slots (``offer_slots`` keeps a key once),
    while the offers that cannot enter cost a load instead of a chain of atomics."""
    t = wp.tid()
    s = t / 2
    side = t - 2 * s
    a = int(0)
    if s >= sample_offset[2]:
        a = 2
    elif s >= sample_offset[1]:
        a = 1
    bit = 1 << (2 * a + side)
    base = t * depth_slots
    kept = int(0)
    for k in range(depth_slots):
        key = keys[base + k]
        if key == EMPTY_KEY:
            break
        if (hidden[key_owner(key)] & bit) == 0:
            if kept != k:
                keys[base + kept] = key
            kept += 1
    for k in range(kept, depth_slots):
        keys[base + k] = EMPTY_KEY
