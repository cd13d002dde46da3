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
4. Crossings along every x, y and z row, virtual fluid past both ends; each one goes to its nearest sphere.
"""

import warp as wp

wp.set_module_options({"enable_backward": False, "fuse_fp": False})

ONES = wp.constant(wp.uint32(0xFFFFFFFF))
#: Larger than any distance the search can meet [m].
FAR = wp.constant(wp.float64(1.0e300))

DIAG_INVALID = wp.constant(0)
DIAG_OUTSIDE = wp.constant(1)
DIAG_UNATTRIBUTED = wp.constant(2)
DIAG_ROUNDS = wp.constant(3)
DIAG_NONCONVERGED = wp.constant(4)
DIAG_TIGHT = wp.constant(5)
N_DIAG = 6


@wp.struct
class WetBox:
    """Voxel grid and probe, in frame coordinates."""

    n: wp.vec3i  # voxels per axis
    nwx: wp.int32  # 32-bit words per x row
    n_words: wp.int32  # words per bitmap
    h: wp.vec3d  # voxel edge per axis [m]
    rho: wp.float64  # probe radius [m]
    bound: wp.vec3d  # nearest-sphere distance bound per lamp axis, rounding margin included [m]
    bin_n: wp.vec3i  # bins of the nearest-sphere search per axis
    bin_edge: wp.float64  # bin edge [m]
    wy: wp.int32  # dilation half-width along y [voxels]
    wz: wp.int32  # dilation half-width along z [voxels]
    lamp_mask: wp.int32  # bit 2a: low lamp of axis a on; bit 2a+1: high lamp
    offset: wp.vec3i  # first ray of each lamp grid in the per-ray arrays
    face_offset: wp.vec3i  # first face of each lamp grid in the optional per-face owner array


# --- bit helpers ------------------------------------------------------------------------------------------


@wp.func
def low_mask(nbits: wp.int32) -> wp.uint32:
    """Bits [0, nbits) set; nbits is clamped to [0, 32]."""
    if nbits >= 32:
        return ONES
    if nbits <= 0:
        return wp.uint32(0)
    return (wp.uint32(1) << wp.uint32(nbits)) - wp.uint32(1)


@wp.func
def row_mask(box: WetBox, w: wp.int32) -> wp.uint32:
    """Bits of word w that are voxels of the box (not padding)."""
    return low_mask(box.n[0] - 32 * w)


@wp.func
def word_at(box: WetBox, w: wp.int32, j: wp.int32, k: wp.int32) -> wp.int32:
    return (k * box.n[1] + j) * box.nwx + w


@wp.func
def fill_up(a: wp.uint32, s: wp.uint32) -> wp.uint32:
    """Bits of a reachable from a seed bit of s at or below them through consecutive bits of a (Kogge-Stone)."""
    g = s & a
    p = a
    g = g | (p & (g << wp.uint32(1)))
    p = p & (p << wp.uint32(1))
    g = g | (p & (g << wp.uint32(2)))
    p = p & (p << wp.uint32(2))
    g = g | (p & (g << wp.uint32(4)))
    p = p & (p << wp.uint32(4))
    g = g | (p & (g << wp.uint32(8)))
    p = p & (p << wp.uint32(8))
    g = g | (p & (g << wp.uint32(16)))
    return g


@wp.func
def fill_down(a: wp.uint32, s: wp.uint32) -> wp.uint32:
    """As fill_up, toward bit 0."""
    g = s & a
    p = a
    g = g | (p & (g >> wp.uint32(1)))
    p = p & (p >> wp.uint32(1))
    g = g | (p & (g >> wp.uint32(2)))
    p = p & (p >> wp.uint32(2))
    g = g | (p & (g >> wp.uint32(4)))
    p = p & (p >> wp.uint32(4))
    g = g | (p & (g >> wp.uint32(8)))
    p = p & (p >> wp.uint32(8))
    g = g | (p & (g >> wp.uint32(16)))
    return g


@wp.func
def fill_runs(a: wp.uint32, s: wp.uint32) -> wp.uint32:
    """Every run of consecutive bits of a that holds a bit of s."""
    return fill_up(a, s) | fill_down(a, s)


@wp.func
def lowest_bit(t: wp.uint32) -> wp.int32:
    return wp.bit_count((t & (~t + wp.uint32(1))) - wp.uint32(1))


@wp.func
def floor_div32(x: wp.int32) -> wp.int32:
    if x >= 0:
        return x / 32
    return -((31 - x) / 32)


@wp.func
def ext_word(bits: wp.array[wp.uint32], row: wp.int32, q: wp.int32, box: WetBox) -> wp.uint32:
    """Word q of the row starting at word index ``row``, with every position outside the box set (the outside
    is reachable)."""
    if q < 0 or q >= box.nwx:
        return ONES
    return bits[row + q] | ~row_mask(box, q)


@wp.func
def shifted_word(bits: wp.array[wp.uint32], row: wp.int32, w: wp.int32, s: wp.int32, box: WetBox) -> wp.uint32:
    """32 bits whose bit b is the voxel at x = 32 w + b - s of the row (outside the box: set)."""
    x0 = 32 * w - s
    q = floor_div32(x0)
    o = x0 - 32 * q
    lo = ext_word(bits, row, q, box)
    if o == 0:
        return lo
    hi = ext_word(bits, row, q + 1, box)
    return (lo >> wp.uint32(o)) | (hi << wp.uint32(32 - o))


# --- clear and rasterize ----------------------------------------------------------------------------------


@wp.kernel
def wet_clear(
    n_particles: wp.int32,
    # outputs
    counts: wp.array[wp.int64],
    hits: wp.array[wp.int32],
    diag: wp.array[wp.int32],
    rmax: wp.array[wp.float32],
    cond: wp.array[wp.int32],
):
    t = wp.tid()
    if t < n_particles:
        counts[3 * t] = wp.int64(0)
        counts[3 * t + 1] = wp.int64(0)
        counts[3 * t + 2] = wp.int64(0)
        hits[t] = 0
    if t < diag.shape[0]:
        diag[t] = 0
    if t == 0:
        rmax[0] = 0.0
        cond[0] = 1


@wp.func
def span_from(c: wp.float64, reach: wp.float64, h: wp.float64, n: wp.int32) -> wp.vec2i:
    """Voxel indices whose centres (i + 1/2) h may lie within reach of c, padded by one, clamped in float (a
    far sphere cannot overflow the int conversion); first > last when none."""
    nf = wp.float64(n)
    a = wp.floor((c - reach) / h - wp.float64(0.5)) - wp.float64(1.0)
    b = wp.ceil((c + reach) / h - wp.float64(0.5)) + wp.float64(1.0)
    a = wp.clamp(a, wp.float64(0.0), nf)
    b = wp.clamp(b, wp.float64(-1.0), nf - wp.float64(1.0))
    return wp.vec2i(wp.int32(a), wp.int32(b))


@wp.func
def centre_offset(i: wp.int32, h: wp.float64, c: wp.float64) -> wp.float64:
    """Voxel centre minus sphere centre along one axis, exactly as the reference evaluates it."""
    return (wp.float64(i) + wp.float64(0.5)) * h - c


@wp.kernel
def wet_rasterize(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    active: wp.array[wp.int32],
    box: WetBox,
    slices: wp.int32,
    # outputs
    blocked: wp.array[wp.uint32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    rmax: wp.array[wp.float32],
    diag: wp.array[wp.int32],
):
    """``slices`` threads per sphere, each marking every slices-th z layer of the voxels its probe-inflated
    ball covers (more threads for a small body, whose few spheres would each walk ~100 rows alone); the first
    slice also bins the sphere and counts bad particles.

    A voxel is blocked when ``(dx dx + dy dy) + dz dz < (r + rho)^2`` in float64, so the probe may stand where the
    distance is exactly r + rho. Each row's run is found from a sqrt estimate and then trimmed by that exact test,
    which is monotone in |dx| (every float64 step is), so the run is contiguous and exact.
    """
    t = wp.tid()
    pid = t / slices
    part = t - pid * slices
    if active.shape[0] > 0:
        if active[pid] == 0:
            return
    p = positions[pid]
    r32 = radii[pid]
    # NaN fails every comparison, so `not (r > 0)` also catches a NaN radius.
    if not (wp.isfinite(p[0]) and wp.isfinite(p[1]) and wp.isfinite(p[2]) and wp.isfinite(r32) and r32 > 0.0):
        if part == 0:
            wp.atomic_add(diag, DIAG_INVALID, 1)
        return
    c = wp.vec3d(wp.float64(p[0]), wp.float64(p[1]), wp.float64(p[2]))
    r = wp.float64(r32)
    big = r + box.rho
    out = int(0)
    tight = int(0)
    near = int(1)
    for a in range(3):
        size = wp.float64(box.n[a]) * box.h[a]
        if c[a] - r < wp.float64(0.0) or c[a] + r > size:
            out = 1
        # The virtual voxel centres outside the box count as allowed; they are, unless a probe-inflated ball
        # reaches the first layer of them.
        half = wp.float64(0.5) * box.h[a]
        if c[a] - big < -half or c[a] + big > size + half:
            tight = 1
        # Only a sphere within r + bound of the box can be the nearest sphere of a crossing in it.
        reach = r + wp.max(box.bound[0], wp.max(box.bound[1], box.bound[2]))
        if c[a] < -reach or c[a] > size + reach:
            near = 0
    if part == 0:
        if out != 0:
            wp.atomic_add(diag, DIAG_OUTSIDE, 1)
        if tight != 0:
            wp.atomic_add(diag, DIAG_TIGHT, 1)
        if near != 0:
            cell = wp.vec3i(0)
            for a in range(3):
                b = wp.floor(c[a] / box.bin_edge)
                cell[a] = wp.int32(wp.clamp(b, wp.float64(0.0), wp.float64(box.bin_n[a] - 1)))
            bin_id = (cell[2] * box.bin_n[1] + cell[1]) * box.bin_n[0] + cell[0]
            next_in_bin[pid] = wp.atomic_exch(heads, bin_id, pid)
            wp.atomic_max(rmax, 0, r32)

    big2 = big * big
    hx = box.h[0]
    nx = box.n[0]
    ks = span_from(c[2], big, box.h[2], box.n[2])
    js = span_from(c[1], big, box.h[1], box.n[1])
    for k in range(ks[0] + part, ks[1] + 1, slices):
        dz = centre_offset(k, box.h[2], c[2])
        for j in range(js[0], js[1] + 1):
            dy = centre_offset(j, box.h[1], c[1])
            # Exact skip: (dx dx + dy dy) + dz dz >= dy dy + dz dz for every dx (rounding is monotone).
            if dy * dy + dz * dz >= big2:
                continue
            rem = big2 - dy * dy - dz * dz
            half = wp.sqrt(wp.max(rem, wp.float64(0.0)))
            xs = span_from(c[0], half, hx, nx)
            i0 = xs[0]
            i1 = xs[1]
            while i0 <= i1:
                dx = centre_offset(i0, hx, c[0])
                if (dx * dx + dy * dy) + dz * dz < big2:
                    break
                i0 += 1
            while i1 >= i0:
                dx = centre_offset(i1, hx, c[0])
                if (dx * dx + dy * dy) + dz * dz < big2:
                    break
                i1 -= 1
            if i0 > i1:
                continue
            row = word_at(box, 0, j, k)
            w0 = i0 / 32
            w1 = i1 / 32
            for w in range(w0, w1 + 1):
                m = low_mask(i1 + 1 - 32 * w) & ~low_mask(i0 - 32 * w)
                # Read first: inside a body most bits are set already, and a load is cheaper than an atomic.
                if (blocked[row + w] & m) != m:
                    wp.atomic_or(blocked, row + w, m)


# --- connectivity -----------------------------------------------------------------------------------------


@wp.kernel
def wet_sweep_x(
    box: WetBox,
    blocked: wp.array[wp.uint32],
    cond: wp.array[wp.int32],
    # outputs
    reach: wp.array[wp.uint32],
):
    """One thread per x row: runs of allowed voxels joined to a reached voxel or to the outside, both ways."""
    if cond[0] == 0:
        return
    row = wp.tid() * box.nwx
    nwx = box.nwx
    carry = wp.uint32(1)  # the outside before x = 0 is reachable
    for w in range(nwx):
        a = ~blocked[row + w] & row_mask(box, w)
        u = fill_up(a, reach[row + w] | (carry & a))
        reach[row + w] = u
        carry = u >> wp.uint32(31)
    top = box.n[0] - 1 - 32 * (nwx - 1)
    carry = wp.uint32(1) << wp.uint32(top)  # the outside after x = nx - 1
    w = nwx - 1
    while w >= 0:
        a = ~blocked[row + w] & row_mask(box, w)
        d = fill_down(a, reach[row + w] | (carry & a))
        reach[row + w] = d
        carry = (d & wp.uint32(1)) << wp.uint32(31)
        w -= 1


@wp.func
def column_of(box: WetBox, axis: wp.int32, col: wp.int32) -> wp.vec3i:
    """(first word, stride, length) of word column ``col`` along y (axis 1, col = w + nwx k) or z (axis 2,
    col = w + nwx j)."""
    w = col % box.nwx
    other = col / box.nwx
    if axis == 1:
        return wp.vec3i(word_at(box, w, 0, other), box.nwx, box.n[1])
    return wp.vec3i(word_at(box, w, other, 0), box.nwx * box.n[1], box.n[2])


@wp.func
def word_coords(box: WetBox, idx: wp.int32) -> wp.vec3i:
    """(word along x, row y, layer z) of word ``idx`` of a bitmap."""
    jk = idx / box.nwx
    return wp.vec3i(idx % box.nwx, jk % box.n[1], jk / box.n[1])


@wp.func
def segment_of(box: WetBox, axis: wp.int32, seg: wp.int32, n_seg: wp.int32, t: wp.int32) -> wp.vec4i:
    """Thread t of a segmented column scan: its column's first word and stride (``column_of``), and its segment's
    rows [j0, j1)."""
    col = t / n_seg
    g = column_of(box, axis, col)
    j0 = (t - col * n_seg) * seg
    return wp.vec4i(g[0], g[1], j0, wp.min(j0 + seg, g[2]))


@wp.kernel
def wet_scan_summary(
    box: WetBox,
    axis: wp.int32,
    seg: wp.int32,
    n_seg: wp.int32,
    blocked: wp.array[wp.uint32],
    reach: wp.array[wp.uint32],
    cond: wp.array[wp.int32],
    # outputs
    seg_pass: wp.array[wp.uint32],
    seg_up: wp.array[wp.uint32],
    seg_down: wp.array[wp.uint32],
):
    """One thread per (column, segment): the segment as one step of the recurrence c' = S | (c & A), each way.

    Per bit lane the propagation along a column is the linear recurrence c_j = S_j | (c_{j-1} & A_j) (S the
    reached, A the allowed voxels); a run of rows composes to c_out = G | (c_in & P) with P = AND of A, so a
    column is a scan: summaries of segments of ``seg`` rows in parallel, a sequential pass over the ``n_seg``
    segments, then the rows (about sqrt(n) each, so that no thread walks more than ~2 sqrt(n) words each way).
    """
    if cond[0] == 0:
        return
    t = wp.tid()
    g = segment_of(box, axis, seg, n_seg, t)
    m = row_mask(box, (t / n_seg) % box.nwx)
    through = m
    up = wp.uint32(0)
    for j in range(g[2], g[3]):
        idx = g[0] + j * g[1]
        a = ~blocked[idx] & m
        through = through & a
        up = reach[idx] | (up & a)
    down = wp.uint32(0)
    j = g[3] - 1
    while j >= g[2]:
        idx = g[0] + j * g[1]
        down = reach[idx] | (down & ~blocked[idx] & m)
        j -= 1
    seg_pass[t] = through
    seg_up[t] = up
    seg_down[t] = down


@wp.kernel
def wet_scan_carry(
    box: WetBox,
    n_seg: wp.int32,
    seg_pass: wp.array[wp.uint32],
    cond: wp.array[wp.int32],
    # outputs
    seg_up: wp.array[wp.uint32],
    seg_down: wp.array[wp.uint32],
):
    """One thread per column: replace each segment's summaries by the carries into it, from below (seg_up) and
    from above (seg_down); the outside past both ends of the column is reachable."""
    if cond[0] == 0:
        return
    col = wp.tid()
    base = col * n_seg
    m = row_mask(box, col % box.nwx)
    c = m
    for s in range(n_seg):
        g = seg_up[base + s]
        seg_up[base + s] = c
        c = g | (c & seg_pass[base + s])
    c = m
    s = n_seg - 1
    while s >= 0:
        g = seg_down[base + s]
        seg_down[base + s] = c
        c = g | (c & seg_pass[base + s])
        s -= 1


@wp.kernel
def wet_scan_apply(
    box: WetBox,
    axis: wp.int32,
    seg: wp.int32,
    n_seg: wp.int32,
    blocked: wp.array[wp.uint32],
    seg_up: wp.array[wp.uint32],
    seg_down: wp.array[wp.uint32],
    cond: wp.array[wp.int32],
    # outputs
    reach: wp.array[wp.uint32],
):
    """One thread per (column, segment): run the segment's rows up from its carry, then down from the other
    carry, filling each word's runs along x on the way down (everything added is joined to a seed)."""
    if cond[0] == 0:
        return
    t = wp.tid()
    g = segment_of(box, axis, seg, n_seg, t)
    m = row_mask(box, (t / n_seg) % box.nwx)
    c = seg_up[t]
    for j in range(g[2], g[3]):
        idx = g[0] + j * g[1]
        c = reach[idx] | (c & ~blocked[idx] & m)
        reach[idx] = c
    d = seg_down[t]
    j = g[3] - 1
    while j >= g[2]:
        idx = g[0] + j * g[1]
        a = ~blocked[idx] & m
        d = fill_runs(a, reach[idx] | (d & a))
        reach[idx] = d
        j -= 1


@wp.kernel
def wet_frontier(
    box: WetBox,
    blocked: wp.array[wp.uint32],
    reach: wp.array[wp.uint32],
    cond: wp.array[wp.int32],
    # outputs
    frontier: wp.array[wp.int32],
):
    """One thread per word: flag an allowed, unreached voxel with a reached (or outside) 6-neighbour."""
    if cond[0] == 0:
        return
    idx = wp.tid()
    nwx = box.nwx
    wjk = word_coords(box, idx)
    w = wjk[0]
    j = wjk[1]
    k = wjk[2]
    r = reach[idx]
    cand = ~blocked[idx] & row_mask(box, w) & ~r
    if cand == wp.uint32(0):
        return
    row = idx - w
    nb = shifted_word(reach, row, w, 1, box) | shifted_word(reach, row, w, -1, box)
    if j == 0 or j == box.n[1] - 1 or k == 0 or k == box.n[2] - 1:
        nb = ONES
    else:
        nb = nb | reach[idx - nwx] | reach[idx + nwx] | reach[idx - nwx * box.n[1]] | reach[idx + nwx * box.n[1]]
    if (cand & nb) != wp.uint32(0):
        frontier[0] = 1


@wp.kernel
def wet_round_end(
    max_rounds: wp.int32,
    # outputs
    frontier: wp.array[wp.int32],
    cond: wp.array[wp.int32],
    diag: wp.array[wp.int32],
    nonconverged_total: wp.array[wp.int32],
):
    """Single thread: continue while a frontier is left, stop at max_rounds and count the solve as cut short."""
    if cond[0] == 0:
        return
    rounds = diag[DIAG_ROUNDS] + 1
    diag[DIAG_ROUNDS] = rounds
    more = frontier[0]
    frontier[0] = 0
    if more != 0 and rounds >= max_rounds:
        diag[DIAG_NONCONVERGED] = 1
        nonconverged_total[0] = nonconverged_total[0] + 1
        more = 0
    cond[0] = more


# --- dilation ---------------------------------------------------------------------------------------------


@wp.kernel
def wet_dilate_y(
    box: WetBox,
    reach: wp.array[wp.uint32],
    table: wp.array[wp.int32],
    # outputs
    planes: wp.array[wp.uint32],
):
    """One thread per word: plane m gets the voxels with a reached voxel at some (dx, dy, m) of the offset set.

    ``table[|dy| (wz + 1) + m]`` is the largest |dx| with (dx, dy, m) in the set, or -1; it does not grow with
    m, so walking m downward only ever widens the x reach of a row.
    """
    idx = wp.tid()
    wjk = word_coords(box, idx)
    w = wjk[0]
    j = wjk[1]
    k = wjk[2]
    nw = box.n_words
    wz = box.wz
    for m in range(wz + 1):
        planes[m * nw + idx] = wp.uint32(0)
    for jj in range(-box.wy, box.wy + 1):
        row_j = j + jj
        aj = wp.abs(jj)
        if row_j < 0 or row_j >= box.n[1]:
            for m in range(wz + 1):
                if table[aj * (wz + 1) + m] >= 0:
                    planes[m * nw + idx] = ONES
            continue
        row = word_at(box, 0, row_j, k)
        running = shifted_word(reach, row, w, 0, box)
        dcur = int(0)
        m = wz
        while m >= 0:
            d = table[aj * (wz + 1) + m]
            if d >= 0:
                while dcur < d:
                    dcur += 1
                    running = running | shifted_word(reach, row, w, dcur, box) | shifted_word(reach, row, w, -dcur, box)
                planes[m * nw + idx] = planes[m * nw + idx] | running
            m -= 1


@wp.kernel
def wet_dilate_z(
    box: WetBox,
    planes: wp.array[wp.uint32],
    # outputs
    fluid: wp.array[wp.uint32],
):
    """One thread per word: fluid = OR over |dz| <= wz of plane |dz| at z + dz (outside the box: fluid)."""
    idx = wp.tid()
    wjk = word_coords(box, idx)
    w = wjk[0]
    j = wjk[1]
    k = wjk[2]
    acc = wp.uint32(0)
    for kk in range(-box.wz, box.wz + 1):
        kz = k + kk
        if kz < 0 or kz >= box.n[2]:
            acc = ONES
        else:
            acc = acc | planes[wp.abs(kk) * box.n_words + word_at(box, w, j, kz)]
    fluid[idx] = acc


# --- crossings --------------------------------------------------------------------------------------------


@wp.func
def sphere_distance(p: wp.vec3d, i: wp.int32, positions: wp.array[wp.vec3], radii: wp.array[wp.float32]):
    """|p - c| - r in float64, exactly as the reference evaluates it."""
    c = positions[i]
    dx = p[0] - wp.float64(c[0])
    dy = p[1] - wp.float64(c[1])
    dz = p[2] - wp.float64(c[2])
    return wp.sqrt((dx * dx + dy * dy) + dz * dz) - wp.float64(radii[i])


@wp.func
def nearest_in_cube(
    p: wp.vec3d,
    reach: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    box: WetBox,
) -> wp.int32:
    """Among binned spheres with centres in the bins that the cube p +- reach touches: the smallest |p - c| - r,
    ties to the lowest index; -1 if there are none."""
    lo = wp.vec3i(0)
    hi = wp.vec3i(0)
    for a in range(3):
        top = wp.float64(box.bin_n[a] - 1)
        lo[a] = wp.int32(wp.clamp(wp.floor((p[a] - reach) / box.bin_edge), wp.float64(0.0), top))
        hi[a] = wp.int32(wp.clamp(wp.floor((p[a] + reach) / box.bin_edge), wp.float64(0.0), top))
    best = FAR
    best_id = int(-1)
    for bz in range(lo[2], hi[2] + 1):
        for by in range(lo[1], hi[1] + 1):
            for bx in range(lo[0], hi[0] + 1):
                i = heads[(bz * box.bin_n[1] + by) * box.bin_n[0] + bx]
                while i >= 0:
                    d = sphere_distance(p, i, positions, radii)
                    if d < best or (d == best and i < best_id):
                        best = d
                        best_id = i
                    i = next_in_bin[i]
    return best_id


@wp.func
def nearest_sphere(
    p: wp.vec3d,
    a: wp.int32,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    box: WetBox,
) -> wp.int32:
    """The sphere nearest to crossing point p of a lamp-a row (smallest |p - c| - r, ties to the lowest index).

    First within one voxel edge: a sphere at distance d1 <= h from p has every sphere that could tie or beat it
    centred within h + r_max of p, all searched, so d1's sphere is the answer. Otherwise (a membrane spanning a
    gap) within the proven bound B_a, beyond which no nearest sphere can lie.
    """
    near = box.h[a]
    reach = (near + rmax) * wp.float64(1.000000001)
    pid = nearest_in_cube(p, reach, positions, radii, heads, next_in_bin, box)
    if pid >= 0:
        if sphere_distance(p, pid, positions, radii) <= near:
            return pid
    return nearest_in_cube(p, box.bound[a] + rmax, positions, radii, heads, next_in_bin, box)


@wp.func
def load_crossing(
    p: wp.vec3d,
    a: wp.int32,
    enters: wp.int32,
    ray: wp.int32,
    face: wp.int32,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    rmax: wp.array[wp.float32],
    box: WetBox,
    counts: wp.array[wp.int64],
    hits: wp.array[wp.int32],
    rays: wp.array[wp.int32],
    diag: wp.array[wp.int32],
    owners: wp.array[wp.int32],
):
    """A crossing at p on a row along axis a: fluid to dry going +a (enters = 1, the low lamp's +1) or dry to
    fluid (the high lamp's -1). Integer counts, so the order of the atomics cannot change the result."""
    lamp = 2 * a
    sign = int(1)
    if enters != 0:
        wp.atomic_add(rays, box.offset[a] + ray, 1)
    else:
        lamp = 2 * a + 1
        sign = -1
    if ((box.lamp_mask >> lamp) & 1) == 0:
        return
    pid = nearest_sphere(p, a, wp.float64(rmax[0]), positions, radii, heads, next_in_bin, box)
    if owners.shape[0] > 0:
        owners[box.face_offset[a] + ray * (box.n[a] + 1) + face] = pid
    if pid < 0:
        wp.atomic_add(diag, DIAG_UNATTRIBUTED, 1)
        return
    wp.atomic_add(counts, 3 * pid + a, wp.int64(sign))
    wp.atomic_add(hits, pid, 1)


@wp.kernel
def wet_cross(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    box: WetBox,
    first: wp.vec3i,
    bits: wp.int32,
    fluid: wp.array[wp.uint32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    rmax: wp.array[wp.float32],
    # outputs
    counts: wp.array[wp.int64],
    hits: wp.array[wp.int32],
    rays: wp.array[wp.int32],
    diag: wp.array[wp.int32],
    owners: wp.array[wp.int32],
):
    """Crossings on the faces of all three axes in one launch (threads from ``first[a]`` on are axis a's): one
    thread per ``bits`` bits of a face word, so that a thread makes at most ``bits`` nearest-sphere searches (the
    host picks 1 for small grids on CUDA, where latency rules, 32 on the CPU).

    Axis 0: face words q = (nwx + 1) row + w, faces f = 32 w + b of row (j, k) (ray j + ny k). Axis 1: q = w + nwx
    (jf + (ny + 1) k), faces jf = 0..ny of the rays of voxels x = 32 w + b (ray k + nz x). Axis 2: q = w + nwx
    (j + ny kf), faces kf = 0..nz (ray x + nx j). Beyond the box on every side is fluid.
    """
    t = wp.tid()
    axis = int(0)
    if t >= first[2]:
        axis = 2
    elif t >= first[1]:
        axis = 1
    t = t - first[axis]
    splits = 32 / bits
    q = t / splits
    sub = t - q * splits
    nwx = box.nwx
    before = ONES
    after = ONES
    valid = wp.uint32(0)
    j = int(0)
    k = int(0)
    w = int(0)
    face = int(0)
    if axis == 0:
        w = q % (nwx + 1)
        row = q / (nwx + 1)
        j = row % box.n[1]
        k = row / box.n[1]
        prev = wp.uint32(1)
        if w > 0:
            prev = fluid[row * nwx + w - 1] >> wp.uint32(31)
        if w < nwx:
            after = fluid[row * nwx + w]
        before = (after << wp.uint32(1)) | prev
        valid = low_mask(box.n[0] + 1 - 32 * w)
    else:
        w = q % nwx
        rest = q / nwx
        if axis == 1:
            face = rest % (box.n[1] + 1)
            k = rest / (box.n[1] + 1)
            if face > 0:
                before = fluid[word_at(box, w, face - 1, k)]
            if face < box.n[1]:
                after = fluid[word_at(box, w, face, k)]
        else:
            j = rest % box.n[1]
            face = rest / box.n[1]
            if face > 0:
                before = fluid[word_at(box, w, j, face - 1)]
            if face < box.n[2]:
                after = fluid[word_at(box, w, j, face)]
        valid = row_mask(box, w)
    tr = (before ^ after) & valid & (low_mask(bits) << wp.uint32(sub * bits))
    while tr != wp.uint32(0):
        b = lowest_bit(tr)
        tr = tr & (tr - wp.uint32(1))
        enters = int(1)
        if ((after >> wp.uint32(b)) & wp.uint32(1)) != wp.uint32(0):
            enters = 0
        x = 32 * w + b
        p = wp.vec3d(
            (wp.float64(x) + wp.float64(0.5)) * box.h[0],
            (wp.float64(j) + wp.float64(0.5)) * box.h[1],
            (wp.float64(k) + wp.float64(0.5)) * box.h[2],
        )
        ray = int(0)
        if axis == 0:
            face = x
            p[0] = wp.float64(x) * box.h[0]
            ray = j + box.n[1] * k
        elif axis == 1:
            p[1] = wp.float64(face) * box.h[1]
            ray = k + box.n[2] * x
        else:
            p[2] = wp.float64(face) * box.h[2]
            ray = x + box.n[0] * j
        load_crossing(
            p,
            axis,
            enters,
            ray,
            face,
            positions,
            radii,
            heads,
            next_in_bin,
            rmax,
            box,
            counts,
            hits,
            rays,
            diag,
            owners,
        )
