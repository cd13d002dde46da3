"""Porosity kernels: sphere volume per CFD cell, as a sum (exact, centroid, polyhedron) or as the union of
sub-cells on a bitmap (voxel, midpoint). Coordinates are relative to the box's lower corner, in float64."""

import warp as wp

from warp_lamp.kernels.footprint import RAY_CENTRE, RAY_OVERLAP, cell_offset, cell_span

wp.set_module_options({"enable_backward": False, "fuse_fp": False})

PI = wp.constant(wp.float64(3.141592653589793))
HALF_PI = wp.constant(wp.float64(1.5707963267948966))
FULL_WORD = wp.constant(wp.uint32(0xFFFFFFFF))


# --- exact sphere-box volume ------------------------------------------------------------------------------


@wp.func
def _octant_antiderivative(y: wp.float64, a: wp.float64, c: wp.float64, r: wp.float64) -> wp.float64:
    """F(y) with V(a, b, c) = F(Y) - F(b): the integral over y of the slab area {x >= a, z >= c} of the ball.

    Every inverse trig function is an atan2 of the two legs: asin(y/sqrt(P)) near 1 amplifies rounding by a
    square root (1e-16 becomes 1e-8), atan2 does not.
    """
    zero = wp.float64(0.0)
    r2 = r * r
    P = r2 - a * a
    Q = r2 - c * c
    sP = wp.sqrt(wp.max(P - y * y, zero))
    sQ = wp.sqrt(wp.max(Q - y * y, zero))
    tP = wp.atan2(y, sP)
    tQ = wp.atan2(y, sQ)
    i1 = wp.float64(0.5) * (y * sP + P * tP)
    i2 = wp.float64(0.5) * (y * sQ + Q * tQ)
    v = r2 * y - y * y * y / wp.float64(3.0)
    acos_a = HALF_PI
    if a > zero:
        acos_a = wp.atan2(sP, a)
    asin_c = wp.atan2(c, sQ)
    third = wp.float64(1.0) / wp.float64(3.0)
    # k(P) = a * integral of y^2 (r^2 - y^2/3) / ((r^2 - y^2) sqrt(P - y^2)) dy, and k(Q) with c.
    kP = a * third * (wp.float64(0.5) * (P * tP - y * sP) - wp.float64(2.0) * r2 * tP)
    kP += wp.float64(2.0) * third * r2 * r * wp.atan2(a * y, r * sP)
    kQ = c * third * (wp.float64(0.5) * (Q * tQ - y * sQ) - wp.float64(2.0) * r2 * tQ)
    kQ += wp.float64(2.0) * third * r2 * r * wp.atan2(c * y, r * sQ)
    i3 = v * acos_a + kP
    i4 = v * asin_c - kQ
    return a * c * y - wp.float64(0.5) * a * i1 - wp.float64(0.5) * c * i2 + wp.float64(0.5) * (i3 - i4)


@wp.func
def octant_volume(a: wp.float64, b: wp.float64, c: wp.float64, r: wp.float64) -> wp.float64:
    """Volume of {|p| <= r, x >= a, y >= b, z >= c} for a, b, c >= 0 (closed form, derived in the docs)."""
    r2 = r * r
    if a * a + b * b + c * c >= r2:
        return wp.float64(0.0)
    top = wp.sqrt(r2 - a * a - c * c)
    return _octant_antiderivative(top, a, c, r) - _octant_antiderivative(b, a, c, r)


@wp.func
def bound_term(x: wp.float64, which: int) -> wp.vec2d:
    """(factor, bound) of term ``which`` (0 or 1) for the half-space {t >= x} of one axis: x >= 0 is the single
    term (1, x); x < 0 is the whole axis, twice the half at 0, minus the mirrored half: (2, 0) and (-1, -x)."""
    zero = wp.float64(0.0)
    if x < zero:
        if which == 0:
            return wp.vec2d(wp.float64(2.0), zero)
        return wp.vec2d(wp.float64(-1.0), -x)
    if which == 0:
        return wp.vec2d(wp.float64(1.0), x)
    return wp.vec2d(zero, zero)


@wp.func
def corner_volume(a: wp.float64, b: wp.float64, c: wp.float64, r: wp.float64) -> wp.float64:
    """Volume of {|p| <= r, x >= a, y >= b, z >= c} for any signs, from octant volumes (see bound_term)."""
    total = wp.float64(0.0)
    for ia in range(2):
        ta = bound_term(a, ia)
        for ib in range(2):
            tb = bound_term(b, ib)
            for ic in range(2):
                tc = bound_term(c, ic)
                f = ta[0] * tb[0] * tc[0]
                if f != wp.float64(0.0):
                    total += f * octant_volume(ta[1], tb[1], tc[1], r)
    return total


@wp.func
def sphere_box_volume(lo: wp.vec3d, hi: wp.vec3d, r: wp.float64) -> wp.float64:
    """Volume of the ball |p| <= r inside the box [lo, hi] (coordinates relative to the ball's centre).

    Boxes wholly outside or inside the ball are answered directly; otherwise the box is clipped to the ball's
    bounding cube and inclusion-exclusion over its 8 corners sums corner volumes. In float64 the cancellation
    of O(r^3) terms costs about 1e-16 (r/h)^3 of a cell: 1e-11 at r/h = 50.
    """
    zero = wp.float64(0.0)
    near = wp.float64(0.0)
    far = wp.float64(0.0)
    for d in range(3):
        g = wp.max(wp.max(lo[d], -hi[d]), zero)
        near += g * g
        e = wp.max(wp.abs(lo[d]), wp.abs(hi[d]))
        far += e * e
    if near >= r * r:
        return zero
    if far <= r * r:
        return (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2])
    cl = wp.vec3d(wp.max(lo[0], -r), wp.max(lo[1], -r), wp.max(lo[2], -r))
    ch = wp.vec3d(wp.min(hi[0], r), wp.min(hi[1], r), wp.min(hi[2], r))
    total = wp.float64(0.0)
    for i in range(2):
        x = cl[0]
        if i == 1:
            x = ch[0]
        for j in range(2):
            y = cl[1]
            if j == 1:
                y = ch[1]
            for k in range(2):
                z = cl[2]
                if k == 1:
                    z = ch[2]
                sign = wp.float64(1.0)
                if (i + j + k) % 2 == 1:
                    sign = wp.float64(-1.0)
                total += sign * corner_volume(x, y, z, r)
    return total


@wp.func
def box_cell_volume(c: wp.vec3d, r: wp.float64, cell: wp.vec3i, h: wp.vec3d, exact: wp.bool) -> wp.float64:
    """The volume a sphere adds to a cell: exact (``sphere_box_volume``), or that of its bounding cube's overlap
    with the cell (PFC's polyhedron mode as the paper describes it). Shared with the distributed fixed-point sums,
    so that both compute every sphere-cell term by the same expressions."""
    if exact:
        lo = wp.vec3d(wp.float64(cell[0]) * h[0], wp.float64(cell[1]) * h[1], wp.float64(cell[2]) * h[2]) - c
        return sphere_box_volume(lo, lo + h, r)
    zero = wp.float64(0.0)
    v = wp.float64(1.0)
    for d in range(3):
        hi = wp.min(c[d] + r, wp.float64(cell[d] + 1) * h[d])
        v *= wp.max(hi - wp.max(c[d] - r, wp.float64(cell[d]) * h[d]), zero)
    return v


#: Per-cell volume of ``porosity_box``.
BOX_EXACT = wp.constant(0)
BOX_CUBE = wp.constant(1)


@wp.kernel
def porosity_box(
    centers: wp.array[wp.vec3d],
    radii: wp.array[wp.float64],
    h: wp.vec3d,
    shape: wp.vec3i,
    volume: wp.int32,
    # outputs
    solid: wp.array3d[wp.float64],
):
    """One thread per sphere adds its volume in every cell its bounding box reaches (overlaps count twice):
    ``BOX_EXACT``, the exact sphere-cell volume; ``BOX_CUBE``, PFC's polyhedron mode as the paper describes it,
    the overlap of the sphere's bounding cube with the cell (so a cell gets up to 6/pi times its share)."""
    s = wp.tid()
    c = centers[s]
    r = radii[s]
    xs = cell_span(c[0] - r, c[0] + r, h[0], shape[0], RAY_OVERLAP)
    ys = cell_span(c[1] - r, c[1] + r, h[1], shape[1], RAY_OVERLAP)
    zs = cell_span(c[2] - r, c[2] + r, h[2], shape[2], RAY_OVERLAP)
    zero = wp.float64(0.0)
    for i in range(xs[0], xs[1] + 1):
        for j in range(ys[0], ys[1] + 1):
            for k in range(zs[0], zs[1] + 1):
                v = box_cell_volume(c, r, wp.vec3i(i, j, k), h, volume == BOX_EXACT)
                if v > zero:
                    wp.atomic_add(solid, i, j, k, v)


@wp.kernel
def porosity_centroid(
    centers: wp.array[wp.vec3d],
    radii: wp.array[wp.float64],
    h: wp.vec3d,
    shape: wp.vec3i,
    # outputs
    solid: wp.array3d[wp.float64],
):
    """PFC's centroid mode: a sphere's whole volume goes to the cell that holds its centre (none if outside)."""
    s = wp.tid()
    c = centers[s]
    r = radii[s]
    idx = wp.vec3i(0)
    for d in range(3):
        f = wp.floor(c[d] / h[d])
        if f < wp.float64(0.0) or f >= wp.float64(shape[d]):
            return
        idx[d] = wp.int32(f)
    wp.atomic_add(solid, idx[0], idx[1], idx[2], wp.float64(4.0) / wp.float64(3.0) * PI * r * r * r)


# --- union on a sub-cell bitmap ---------------------------------------------------------------------------


@wp.func
def set_run(bits: wp.array[wp.uint32], row: wp.int32, i0: wp.int32, i1: wp.int32):
    """Set bits i0..i1 of a bitmap row (32 sub-cells per word), one atomic_or per word touched."""
    w0 = i0 >> 5
    w1 = i1 >> 5
    for w in range(w0, w1 + 1):
        lo = wp.max(i0 - (w << 5), 0)
        hi = wp.min(i1 - (w << 5), 31)
        mask = FULL_WORD
        if hi - lo < 31:
            mask = ((wp.uint32(1) << wp.uint32(hi - lo + 1)) - wp.uint32(1)) << wp.uint32(lo)
        wp.atomic_or(bits, row + w, mask)


@wp.kernel
def voxel_mark(
    centers: wp.array[wp.vec3d],
    radii: wp.array[wp.float64],
    hs: wp.vec3d,
    sub: wp.vec3i,
    words: wp.int32,
    # outputs
    bits: wp.array[wp.uint32],
):
    """One thread per sphere: set every sub-cell whose centre lies in the sphere (|x - c| <= r), one run per
    sub-row. True sub-cell centres, no rounding of the sphere to the sub-grid.

    Rows and runs come from ``footprint.cell_span``, the lamp's span function, in float64.
    """
    s = wp.tid()
    c = centers[s]
    r = radii[s]
    r2 = r * r
    js = cell_span(c[1] - r, c[1] + r, hs[1], sub[1], RAY_CENTRE)
    for j in range(js[0], js[1] + 1):
        dy = cell_offset(j, hs[1], c[1], RAY_CENTRE)
        ry2 = r2 - dy * dy
        if ry2 < wp.float64(0.0):
            continue
        ry = wp.sqrt(ry2)
        ks = cell_span(c[2] - ry, c[2] + ry, hs[2], sub[2], RAY_CENTRE)
        for k in range(ks[0], ks[1] + 1):
            dz = cell_offset(k, hs[2], c[2], RAY_CENTRE)
            rem = ry2 - dz * dz
            if rem < wp.float64(0.0):
                continue
            w = wp.sqrt(rem)
            # The span of centres is a superset (footprint.cell_span): trim it to the exact test, which is
            # monotone in |dx| along the row, so the run is exactly the sub-cells that pass.
            span = cell_span(c[0] - w, c[0] + w, hs[0], sub[0], RAY_CENTRE)
            i0 = span[0]
            i1 = span[1]
            while i0 <= i1:
                dx = cell_offset(i0, hs[0], c[0], RAY_CENTRE)
                if dx * dx <= rem:
                    break
                i0 += 1
            while i1 >= i0:
                dx = cell_offset(i1, hs[0], c[0], RAY_CENTRE)
                if dx * dx <= rem:
                    break
                i1 -= 1
            if i0 <= i1:
                set_run(bits, (k * sub[1] + j) * words, i0, i1)


@wp.func
def isqrt64(n: wp.int64) -> wp.int64:
    """floor(sqrt(n)) for n >= 0 (0 for n <= 0): a float64 estimate, corrected in integers."""
    if n <= wp.int64(0):
        return wp.int64(0)
    m = wp.int64(wp.sqrt(wp.float64(n)))
    while m * m > n:
        m -= wp.int64(1)
    while (m + wp.int64(1)) * (m + wp.int64(1)) <= n:
        m += wp.int64(1)
    return m


@wp.func
def midpoint_last(r: wp.int64) -> wp.int64:
    """The last x that the midpoint circle of radius r >= 1 visits (``while y >= x``): the largest x with
    y(x) >= x, i.e. with (2x - 1)^2 < 4 (r^2 - x^2), or 8x^2 - 4x + 1 < 4r^2."""
    four_r2 = wp.int64(4) * r * r
    x = wp.int64((wp.float64(1.0) + wp.sqrt(wp.float64(8) * wp.float64(r) * wp.float64(r))) / wp.float64(4.0))
    while x > wp.int64(0) and wp.int64(8) * x * x - wp.int64(4) * x + wp.int64(1) >= four_r2:
        x -= wp.int64(1)
    while wp.int64(8) * (x + wp.int64(1)) * (x + wp.int64(1)) - wp.int64(4) * (x + wp.int64(1)) + wp.int64(1) < four_r2:
        x += wp.int64(1)
    return x


@wp.func
def midpoint_profile(r: wp.int64, last: wp.int64, b: wp.int64) -> wp.int64:
    """The run half-width + 1 that the paper's ``disk(r)`` draws in its row |dy| = b (-1: none), or, with the
    sphere's radius, the radius of the widest disk its outer loop draws at height |dz| = b.

    The midpoint recurrence with p = 5/4 - r keeps p = (x+1)^2 + (y-1/2)^2 - r^2 exactly (4p is odd, never 0),
    so while y >= x its y is y(x) = max{y : (2y-1)^2 < 4(r^2 - x^2)} (y steps by at most 1 there). ``line(x, y)``
    and ``line(y, x)`` then give row b the half-width y(b) - 1 for b <= last, and max{x <= last : y(x) = b} - 1
    beyond, where max{x : y(x) >= b} is the largest x with 4x^2 < 4r^2 - (2b-1)^2. Both grow with r, so the widest
    disk of a height covers the others. ``tests/test_porosity.py`` checks this against the literal recurrence.
    """
    if r < wp.int64(1) or b > r:
        return wp.int64(-1)
    if b <= last:
        m = wp.int64(4) * (r * r - b * b)
        return (isqrt64(m - wp.int64(1)) + wp.int64(1)) / wp.int64(2)
    q = wp.int64(2) * b - wp.int64(1)
    m = wp.int64(4) * r * r - q * q
    if m <= wp.int64(0):
        return wp.int64(-1)
    return wp.min(isqrt64(m - wp.int64(1)) / wp.int64(2), last)


@wp.kernel
def midpoint_mark(
    centers: wp.array[wp.vec3i],
    radii: wp.array[wp.int32],
    sub: wp.vec3i,
    words: wp.int32,
    # outputs
    bits: wp.array[wp.uint32],
):
    """Algorithm 1 (traversal sphere), one thread per sphere, on sphere centres and radii in sub-cell units.

    Marks exactly the sub-cells of the paper's nested midpoint circles (``disk`` of ``line`` runs), evaluated
    row by row in closed form (:func:`midpoint_profile`) over the rows that lie in the sub-grid, so that a
    sphere far larger than the box costs only the box's rows.
    """
    c = centers[wp.tid()]
    r = wp.int64(radii[wp.tid()])
    cx = wp.int64(c[0])
    cy = wp.int64(c[1])
    cz = wp.int64(c[2])
    last = midpoint_last(r)
    z0 = wp.max(-r, -cz)
    z1 = wp.min(r, wp.int64(sub[2]) - wp.int64(1) - cz)
    for dz32 in range(wp.int32(z0), wp.int32(z1) + 1):
        dz = wp.int64(dz32)
        rho = midpoint_profile(r, last, wp.abs(dz))
        if rho < wp.int64(1):
            continue
        last_rho = midpoint_last(rho)
        y0 = wp.max(-rho, -cy)
        y1 = wp.min(rho, wp.int64(sub[1]) - wp.int64(1) - cy)
        if y0 > y1:
            continue
        # Rows cy +- b for b = |dy| over the box's rows; the profile is followed incrementally along b (it only
        # falls), from one square root at the first b of each branch.
        b_lo = wp.int64(0)
        if y0 > wp.int64(0):
            b_lo = y0
        elif y1 < wp.int64(0):
            b_lo = -y1
        b_hi = wp.max(-y0, y1)
        k = wp.int32(cz + dz)
        y = wp.int64(-1)
        x = wp.int64(-1)
        four_rho2 = wp.int64(4) * rho * rho
        for b32 in range(wp.int32(b_lo), wp.int32(b_hi) + 1):
            b = wp.int64(b32)
            width = wp.int64(-1)
            if b <= last_rho:
                if y < wp.int64(0):
                    y = midpoint_profile(rho, last_rho, b)
                q = wp.int64(2) * y - wp.int64(1)
                while q * q >= four_rho2 - wp.int64(4) * b * b:
                    y -= wp.int64(1)
                    q = wp.int64(2) * y - wp.int64(1)
                width = y
            else:
                if x < wp.int64(0):
                    x = midpoint_profile(rho, last_rho, b)
                q = wp.int64(2) * b - wp.int64(1)
                while x >= wp.int64(0) and wp.int64(4) * x * x >= four_rho2 - q * q:
                    x -= wp.int64(1)
                width = wp.min(x, last_rho)
            half = width - wp.int64(1)
            if half < wp.int64(0):
                continue
            i0 = wp.int32(wp.max(cx - half, wp.int64(0)))
            i1 = wp.int32(wp.min(cx + half, wp.int64(sub[0]) - wp.int64(1)))
            if i0 > i1:
                continue
            if b <= y1:
                set_run(bits, (k * sub[1] + wp.int32(cy + b)) * words, i0, i1)
            if b > wp.int64(0) and -b >= y0:
                set_run(bits, (k * sub[1] + wp.int32(cy - b)) * words, i0, i1)


@wp.kernel
def midpoint_grid_mark(
    grid: wp.uint64,
    centers: wp.array[wp.vec3i],
    radii: wp.array[wp.int32],
    sub: wp.vec3i,
    words: wp.int32,
    search: wp.float32,
    # outputs
    bits: wp.array[wp.uint32],
):
    """Algorithm 2 (traversal small-grid), one thread per bitmap word: each of its 32 sub-cells is solid when a
    sphere centre within the search cube has (i-x)^2 + (j-y)^2 + (k-z)^2 - r^2 < 0. The paper's dense
    cells_ball array is replaced by a hash grid over the centres: the indexing its section 4 leaves to future
    work, with the same answer."""
    t = wp.tid()
    row = t / words
    w = t - row * words
    k = row / sub[1]
    j = row - k * sub[1]
    word = wp.uint32(0)
    for b in range(32):
        i = w * 32 + b
        if i < sub[0]:
            q = wp.hash_grid_query(grid, wp.vec3(float(i), float(j), float(k)), search)
            n = int(0)
            while wp.hash_grid_query_next(q, n):
                c = centers[n]
                dx = i - c[0]
                dy = j - c[1]
                dz = k - c[2]
                rn = wp.int64(radii[n])
                d2 = wp.int64(dx) * wp.int64(dx) + wp.int64(dy) * wp.int64(dy) + wp.int64(dz) * wp.int64(dz)
                if d2 - rn * rn < wp.int64(0):
                    word = word | (wp.uint32(1) << wp.uint32(b))
    bits[t] = word


@wp.kernel
def bitmap_count(
    bits: wp.array[wp.uint32],
    sub: wp.vec3i,
    words: wp.int32,
    s: wp.vec3i,
    # outputs
    counts: wp.array3d[wp.int64],
):
    """One thread per (cell i, cell j, sub-row k): popcount of the cell's x-range over its s_y sub-rows, added to
    the cell's int64 count (a cell may hold more than 2**31 sub-cells)."""
    ci, cj, k = wp.tid()
    i0 = ci * s[0]
    i1 = i0 + s[0] - 1
    total = wp.int64(0)
    for jj in range(cj * s[1], cj * s[1] + s[1]):
        row = (k * sub[1] + jj) * words
        for w in range(i0 >> 5, (i1 >> 5) + 1):
            lo = wp.max(i0 - (w << 5), 0)
            hi = wp.min(i1 - (w << 5), 31)
            mask = FULL_WORD
            if hi - lo < 31:
                mask = ((wp.uint32(1) << wp.uint32(hi - lo + 1)) - wp.uint32(1)) << wp.uint32(lo)
            total += wp.int64(wp.bit_count(bits[row + w] & mask))
    if total > wp.int64(0):
        wp.atomic_add(counts, ci, cj, k / s[2], total)
