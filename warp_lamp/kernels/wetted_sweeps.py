"""Wetted-surface kernels, the voxel sweeps: clear and rasterise, connectivity to the outside, dilation.

Steps 1-3 of the pipeline in :mod:`warp_lamp.kernels.wetted`."""

import warp as wp

from warp_lamp.kernels.walls import LampWalls, plane_value
from warp_lamp.kernels.wetted_base import (
    DIAG_INVALID,
    DIAG_NONCONVERGED,
    DIAG_OUTSIDE,
    DIAG_ROUNDS,
    DIAG_TIGHT,
    ONES,
    RUN_FAR,
    SKIN_RESET,
    WetBox,
    centre_offset,
    low_mask,
    row_mask,
    span_from,
    voxel_centre,
    word_at,
    word_coords,
)

# No unrolling (see kernels/wetted_base.py), no FMA contraction: every module of the wetted surface compiles
# with the same options, so a function evaluates alike in each.
wp.set_module_options({"enable_backward": False, "fuse_fp": False, "max_unroll": 1})


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
def floor_div32(x: wp.int32) -> wp.int32:
    if x >= 0:
        return x / 32
    return -((31 - x) / 32)


@wp.func
def run_bits(run: wp.vec2i, q: wp.int32) -> wp.uint32:
    """Bits b of word q whose position 32 q + b lies in the run [run[0], run[1]] (empty when run[0] > run[1])."""
    return low_mask(run[1] + 1 - 32 * q) & ~low_mask(run[0] - 32 * q)


@wp.func
def in_run(run: wp.vec2i, i: wp.int32) -> wp.bool:
    return run[0] <= i and i <= run[1]


@wp.func
def widen(run: wp.vec2i, d: wp.int32) -> wp.vec2i:
    """The run grown by d on both sides (an empty run stays empty)."""
    if run[0] > run[1]:
        return run
    return wp.vec2i(run[0] - d, run[1] + d)


@wp.func
def wall_row_run(walls: LampWalls, thr: wp.float64, j: wp.int32, k: wp.int32, box: WetBox) -> wp.vec2i:
    """The x indices i of the voxel row (j, k) (j, k and i may lie beyond the box) whose centre has ``g >= thr`` for
    every wall (``plane_value``, float64). Each wall's g is monotone along the row (every float64 step is), so this
    is one run: found from an estimate, then walked to its exact ends within [-pad, n_x - 1 + pad], and left open
    (``RUN_FAR``) past an end of that range that passes. No walls: everything."""
    lo = int(-RUN_FAR)
    hi = int(RUN_FAR)
    if walls.n == 0:
        return wp.vec2i(lo, hi)
    hx = box.h[0]
    y = voxel_centre(j, box.h[1])
    z = voxel_centre(k, box.h[2])
    first = -box.pad
    last = box.n[0] - 1 + box.pad
    for w in range(walls.n):
        pl = walls.frame[w]
        n0 = wp.float64(pl[0])
        if n0 == wp.float64(0.0):
            # g does not change along the row (n0 x is exactly 0).
            if not (plane_value(pl, wp.vec3d(voxel_centre(0, hx), y, z)) >= thr):
                return wp.vec2i(RUN_FAR, -RUN_FAR)
            continue
        t = ((thr + wp.float64(pl[3])) - (wp.float64(pl[1]) * y + wp.float64(pl[2]) * z)) / n0
        f = t / hx - wp.float64(0.5)
        i = first
        if wp.isfinite(f):
            i = wp.int32(wp.clamp(wp.floor(f), wp.float64(first), wp.float64(last)))
        if n0 > wp.float64(0.0):
            # g grows with i: the run starts at the first i that passes.
            while i > first and plane_value(pl, wp.vec3d(voxel_centre(i - 1, hx), y, z)) >= thr:
                i -= 1
            while i <= last and not (plane_value(pl, wp.vec3d(voxel_centre(i, hx), y, z)) >= thr):
                i += 1
            if i > first:
                lo = wp.max(lo, i)
        else:
            # g falls with i (or the plane is not finite, and nothing passes).
            while i < last and plane_value(pl, wp.vec3d(voxel_centre(i + 1, hx), y, z)) >= thr:
                i += 1
            while i >= first and not (plane_value(pl, wp.vec3d(voxel_centre(i, hx), y, z)) >= thr):
                i -= 1
            if i < last:
                hi = wp.min(hi, i)
    return wp.vec2i(lo, hi)


@wp.func
def ext_word(bits: wp.array[wp.uint32], row: wp.int32, q: wp.int32, box: WetBox, run: wp.vec2i) -> wp.uint32:
    """Word q of the row starting at word index ``row``, with the positions outside the box set where they lie in
    ``run`` (the row's outside that is reachable: everything without walls)."""
    if q < 0 or q >= box.nwx:
        return run_bits(run, q)
    return bits[row + q] | (~row_mask(box, q) & run_bits(run, q))


@wp.func
def shifted_word(
    bits: wp.array[wp.uint32], row: wp.int32, w: wp.int32, s: wp.int32, box: WetBox, run: wp.vec2i
) -> wp.uint32:
    """32 bits whose bit b is the voxel at x = 32 w + b - s of the row (outside the box: set within ``run``)."""
    x0 = 32 * w - s
    q = floor_div32(x0)
    o = x0 - 32 * q
    lo = ext_word(bits, row, q, box, run)
    if o == 0:
        return lo
    hi = ext_word(bits, row, q + 1, box, run)
    return (lo >> wp.uint32(o)) | (hi << wp.uint32(32 - o))


@wp.kernel
def wet_clear(
    n_particles: wp.int32,
    # outputs
    counts: wp.array[wp.int64],
    hits: wp.array[wp.int32],
    diag: wp.array[wp.int32],
    rmax: wp.array[wp.float32],
    cond: wp.array[wp.int32],
    wall_counts: wp.array[wp.int64],
):
    t = wp.tid()
    if t < wall_counts.shape[0]:
        wall_counts[t] = wp.int64(0)
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
def mark_run(
    bits: wp.array[wp.uint32],
    cx: wp.float64,
    rr2: wp.float64,
    dy: wp.float64,
    dz: wp.float64,
    j: wp.int32,
    k: wp.int32,
    box: WetBox,
):
    """Set the voxels of row (j, k) with ``(dx dx + dy dy) + dz dz < rr2``: a run found from a sqrt estimate and then
    trimmed by that exact test, which is monotone in |dx| (every float64 step is), so the run is contiguous and
    exact. One ``atomic_or`` per word, skipped where the bits are set already."""
    hx = box.h[0]
    rem = rr2 - dy * dy - dz * dz
    half = wp.sqrt(wp.max(rem, wp.float64(0.0)))
    xs = span_from(cx, half, hx, box.n[0])
    i0 = xs[0]
    i1 = xs[1]
    while i0 <= i1:
        dx = centre_offset(i0, hx, cx)
        if (dx * dx + dy * dy) + dz * dz < rr2:
            break
        i0 += 1
    while i1 >= i0:
        dx = centre_offset(i1, hx, cx)
        if (dx * dx + dy * dy) + dz * dz < rr2:
            break
        i1 -= 1
    if i0 <= i1:
        row = word_at(box, 0, j, k)
        for w in range(i0 / 32, i1 / 32 + 1):
            m = low_mask(i1 + 1 - 32 * w) & ~low_mask(i0 - 32 * w)
            # Read first: inside a body most bits are set already, and a load is cheaper than an atomic.
            if (bits[row + w] & m) != m:
                wp.atomic_or(bits, row + w, m)


@wp.kernel
def wet_rasterize(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    active: wp.array[wp.int32],
    box: WetBox,
    slices: wp.int32,
    # outputs
    blocked: wp.array[wp.uint32],
    solid: wp.array[wp.uint32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    rmax: wp.array[wp.float32],
    diag: wp.array[wp.int32],
):
    """``slices`` threads per sphere, each marking every slices-th z layer of the voxels its probe-inflated
    ball covers (more threads for a small body, whose few spheres would each walk ~100 rows alone); the first
    slice also bins the sphere and counts bad particles.

    A voxel is blocked when ``(dx dx + dy dy) + dz dz < (r + rho)^2`` in float64, so the probe may stand where the
    distance is exactly r + rho; it is solid (inside the sphere, never fluid) when the same sum is ``< r^2``.
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
    r2 = r * r
    ks = span_from(c[2], big, box.h[2], box.n[2])
    js = span_from(c[1], big, box.h[1], box.n[1])
    for k in range(ks[0] + part, ks[1] + 1, slices):
        dz = centre_offset(k, box.h[2], c[2])
        for j in range(js[0], js[1] + 1):
            dy = centre_offset(j, box.h[1], c[1])
            # Exact skip: (dx dx + dy dy) + dz dz >= dy dy + dz dz for every dx (rounding is monotone).
            if dy * dy + dz * dz >= big2:
                continue
            mark_run(blocked, c[0], big2, dy, dz, j, k, box)
            if dy * dy + dz * dz < r2:
                mark_run(solid, c[0], r2, dy, dz, j, k, box)


@wp.kernel
def wet_rasterize_walls(
    box: WetBox,
    walls: LampWalls,
    # outputs
    blocked: wp.array[wp.uint32],
    solid: wp.array[wp.uint32],
):
    """One thread per x row, after ``wet_rasterize``: the walls join the blocked map where ``g < rho`` (the probe
    centre keeps rho from every wall) and the solid map where ``g < 0`` (inside a wall: never fluid). Each is the
    complement of one run along the row (``wall_row_run``)."""
    t = wp.tid()
    j = t % box.n[1]
    k = t / box.n[1]
    allowed = wall_row_run(walls, box.rho, j, k, box)
    outside = wall_row_run(walls, wp.float64(0.0), j, k, box)
    row = word_at(box, 0, j, k)
    for w in range(box.nwx):
        m = row_mask(box, w)
        blocked[row + w] = blocked[row + w] | (m & ~run_bits(allowed, w))
        solid[row + w] = solid[row + w] | (m & ~run_bits(outside, w))


@wp.kernel
def wet_sweep_x(
    box: WetBox,
    walls: LampWalls,
    blocked: wp.array[wp.uint32],
    cond: wp.array[wp.int32],
    # outputs
    reach: wp.array[wp.uint32],
):
    """One thread per x row: runs of allowed voxels joined to a reached voxel or to the outside, both ways (the
    outside is reached where it keeps rho from every wall)."""
    if cond[0] == 0:
        return
    t = wp.tid()
    row = t * box.nwx
    nwx = box.nwx
    run = wall_row_run(walls, box.rho, t % box.n[1], t / box.n[1], box)
    carry = wp.uint32(0)
    if in_run(run, -1):
        carry = wp.uint32(1)  # the outside before x = 0
    for w in range(nwx):
        a = ~blocked[row + w] & row_mask(box, w)
        u = fill_up(a, reach[row + w] | (carry & a))
        reach[row + w] = u
        carry = u >> wp.uint32(31)
    top = box.n[0] - 1 - 32 * (nwx - 1)
    carry = wp.uint32(0)
    if in_run(run, box.n[0]):
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


@wp.func
def outside_row_bits(walls: LampWalls, axis: wp.int32, col: wp.int32, end: wp.int32, box: WetBox) -> wp.uint32:
    """The reached outside just past one end of word column ``col`` along y (axis 1) or z (axis 2): the word of
    the row at index -1 (end 0) or n (end 1) of that axis."""
    w = col % box.nwx
    other = col / box.nwx
    idx = -1
    if end != 0:
        idx = box.n[axis]
    run = wp.vec2i(0)
    if axis == 1:
        run = wall_row_run(walls, box.rho, idx, other, box)
    else:
        run = wall_row_run(walls, box.rho, other, idx, box)
    return run_bits(run, w)


@wp.kernel
def wet_scan_carry(
    box: WetBox,
    axis: wp.int32,
    walls: LampWalls,
    n_seg: wp.int32,
    seg_pass: wp.array[wp.uint32],
    cond: wp.array[wp.int32],
    # outputs
    seg_up: wp.array[wp.uint32],
    seg_down: wp.array[wp.uint32],
):
    """One thread per column: replace each segment's summaries by the carries into it, from below (seg_up) and
    from above (seg_down); the outside past both ends of the column is reachable (where it keeps rho from every
    wall)."""
    if cond[0] == 0:
        return
    col = wp.tid()
    base = col * n_seg
    m = row_mask(box, col % box.nwx)
    c = m & outside_row_bits(walls, axis, col, 0, box)
    for s in range(n_seg):
        g = seg_up[base + s]
        seg_up[base + s] = c
        c = g | (c & seg_pass[base + s])
    c = m & outside_row_bits(walls, axis, col, 1, box)
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
    walls: LampWalls,
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
    run = wall_row_run(walls, box.rho, j, k, box)
    nb = shifted_word(reach, row, w, 1, box, run) | shifted_word(reach, row, w, -1, box, run)
    # Neighbour rows beyond the box are the outside, reached where it keeps rho from every wall.
    if j == 0:
        nb = nb | run_bits(wall_row_run(walls, box.rho, -1, k, box), w)
    else:
        nb = nb | reach[idx - nwx]
    if j == box.n[1] - 1:
        nb = nb | run_bits(wall_row_run(walls, box.rho, box.n[1], k, box), w)
    else:
        nb = nb | reach[idx + nwx]
    if k == 0:
        nb = nb | run_bits(wall_row_run(walls, box.rho, j, -1, box), w)
    else:
        nb = nb | reach[idx - nwx * box.n[1]]
    if k == box.n[2] - 1:
        nb = nb | run_bits(wall_row_run(walls, box.rho, j, box.n[2], box), w)
    else:
        nb = nb | reach[idx + nwx * box.n[1]]
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


@wp.kernel
def wet_dilate_y(
    box: WetBox,
    walls: LampWalls,
    wy: wp.int32,
    wz: wp.int32,
    reach: wp.array[wp.uint32],
    table: wp.array[wp.int32],
    # outputs
    planes: wp.array[wp.uint32],
):
    """One thread per word: plane m gets the voxels with a reached voxel at some (dx, dy, m) of the offset set.

    ``table[|dy| (wz + 1) + m]`` (|dy| <= wy, m <= wz) is the largest |dx| with (dx, dy, m) in the set, or -1; it
    does not grow with m, so walking m downward only ever widens the x reach of a row. Beyond the box, the reached
    points are those that keep rho from every wall (all of them without walls): one run per row, so a row beyond
    the box dilated by d is that run widened by d.
    """
    idx = wp.tid()
    wjk = word_coords(box, idx)
    w = wjk[0]
    j = wjk[1]
    k = wjk[2]
    nw = box.n_words
    for m in range(wz + 1):
        planes[m * nw + idx] = wp.uint32(0)
    for jj in range(-wy, wy + 1):
        row_j = j + jj
        aj = wp.abs(jj)
        run = wall_row_run(walls, box.rho, row_j, k, box)
        if row_j < 0 or row_j >= box.n[1]:
            for m in range(wz + 1):
                d = table[aj * (wz + 1) + m]
                if d >= 0:
                    planes[m * nw + idx] = planes[m * nw + idx] | run_bits(widen(run, d), w)
            continue
        row = word_at(box, 0, row_j, k)
        running = shifted_word(reach, row, w, 0, box, run)
        dcur = int(0)
        m = wz
        while m >= 0:
            d = table[aj * (wz + 1) + m]
            if d >= 0:
                while dcur < d:
                    dcur += 1
                    running = (
                        running
                        | shifted_word(reach, row, w, dcur, box, run)
                        | shifted_word(reach, row, w, -dcur, box, run)
                    )
                planes[m * nw + idx] = planes[m * nw + idx] | running
            m -= 1


@wp.kernel
def wet_dilate_z(
    box: WetBox,
    walls: LampWalls,
    wy: wp.int32,
    wz: wp.int32,
    planes: wp.array[wp.uint32],
    table: wp.array[wp.int32],
    # outputs
    fluid: wp.array[wp.uint32],
):
    """One thread per word: the dilated set = OR over |dz| <= wz of plane |dz| at z + dz. A layer beyond the box is
    set (no walls), or, with walls, its plane is built here from the rows' runs beyond the box (``wet_dilate_y``)."""
    idx = wp.tid()
    wjk = word_coords(box, idx)
    w = wjk[0]
    j = wjk[1]
    k = wjk[2]
    acc = wp.uint32(0)
    for kk in range(-wz, wz + 1):
        kz = k + kk
        if kz < 0 or kz >= box.n[2]:
            if walls.n == 0:
                acc = ONES
            else:
                m = wp.abs(kk)
                for jj in range(-wy, wy + 1):
                    d = table[wp.abs(jj) * (wz + 1) + m]
                    if d >= 0:
                        acc = acc | run_bits(widen(wall_row_run(walls, box.rho, j + jj, kz, box), d), w)
        else:
            acc = acc | planes[wp.abs(kk) * box.n_words + word_at(box, w, j, kz)]
    fluid[idx] = acc


@wp.kernel
def wet_uncertain_words(
    band: wp.array[wp.uint32],
    fluid: wp.array[wp.uint32],
    solid: wp.array[wp.uint32],
    kept: wp.array[wp.uint32],
    skin: wp.array[wp.int32],
    box: WetBox,
    # outputs
    uncertain: wp.array[wp.uint32],
    counts: wp.array[wp.int32],
):
    """One thread per word: the voxels the exact test will queue (``wet_classify``'s: in the band, dry after the
    dilation, not solid, less those the skin keeps) and how many, so that a prefix sum of the counts places them in
    the queue in voxel order (neighbouring voxels in a warp's lanes)."""
    idx = wp.tid()
    wjk = word_coords(box, idx)
    unc = band[idx] & ~fluid[idx] & ~solid[idx] & row_mask(box, wjk[0])
    if kept.shape[0] > 0:
        if skin[SKIN_RESET] == 0:
            unc = unc & ~kept[idx]
    uncertain[idx] = unc
    counts[idx] = wp.bit_count(unc)
