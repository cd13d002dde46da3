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

import warp as wp

from warp_lamp.kernels.walls import LampWalls, plane_value

# No unrolling: the exact classification nests small constant loops (corners, pairs, axes) around deep inlined
# calls, and unrolled they made one kernel so large that compiling the module for sm_90 took 570 s on the H100's
# host (NVRTC through ``wp.compile_aot_module`` on the 2-core dev machine: 502 s unrolled, 57 s not). Unrolling
# changes no result (the mode's dumps are bitwise equal); its effect on the GPU's run time is not yet measured.
wp.set_module_options({"enable_backward": False, "fuse_fp": False, "max_unroll": 1})

ONES = wp.constant(wp.uint32(0xFFFFFFFF))
#: Larger than any distance the search can meet [m].
FAR = wp.constant(wp.float64(1.0e300))

DIAG_INVALID = wp.constant(0)
DIAG_OUTSIDE = wp.constant(1)
DIAG_UNATTRIBUTED = wp.constant(2)
DIAG_ROUNDS = wp.constant(3)
DIAG_NONCONVERGED = wp.constant(4)
DIAG_TIGHT = wp.constant(5)
DIAG_UNCERTAIN = wp.constant(6)
DIAG_RESCUED = wp.constant(7)
DIAG_THIN = wp.constant(8)
DIAG_GAPS = wp.constant(9)
N_DIAG = 10
#: ``candidate_check``'s answer for a valid candidate.
CANDIDATE_OK = wp.constant(-2)
#: Spheres a point's exact test keeps in a local list (a uint64 mask marks them); with more it walks the bins.
NEAR_LIST = 64
NearList = wp.types.vector(length=NEAR_LIST, dtype=wp.int32)
#: Near spheres from which the exact test prunes those whose cap another ball covers: from any number (measured on
#: the CPU, specimen and slot block at rho = d/4 ... d: pruning always was as fast as from 8 or 12, 1.5-7x faster
#: than never); tests raise it past NEAR_LIST to check the unpruned search.
PRUNE_FROM = 0
#: Inflated balls holding a point deepest that the exact test keeps as the first covers of the near spheres' caps.
DEEP = 8
DeepIds = wp.types.vector(length=DEEP, dtype=wp.int32)
DeepDepths = wp.types.vector(length=DEEP, dtype=wp.float64)
#: ``WetBox.skip`` bits, for benchmarks only (they make answers wrong): the exact test skips vertex candidates (1),
#: edge candidates and their vertices (2), face candidates (4), stops before its pruning (8) or after it (16).
SKIP_VERTICES, SKIP_EDGES, SKIP_FACES, SKIP_PRUNING, SKIP_CANDIDATES = 1, 2, 4, 8, 16
#: Spheres a point's exact test gathers once, for all its candidates' blocker and segment searches: those within
#: r + 2 rho + diagonal of the point, in bin-walk order; with more it walks the bins for every candidate.
GATHER = 128
GatherIds = wp.types.vector(length=GATHER, dtype=wp.int32)
#: Relative slack of the pruning tests below: they may only drop what exact arithmetic rules out with room to spare.
SLACK = wp.constant(wp.float64(1.0e-9))
#: Beyond any voxel index a kernel asks about: the end of a wall run that is open on that side.
RUN_FAR = wp.constant(1 << 28)
#: Wall w among a candidate's defining spheres (sphere indices are >= 0, -1 is none): ``WALL_TAG - w``.
WALL_TAG = wp.constant(-2)
#: Wall w in the per-face owners (-2: no crossing loaded, -1: none found): ``WALL_OWNER - w``.
WALL_OWNER = wp.constant(-3)
#: Slack of the walls' gate (their float32 normals are unit to about 1e-7).
WALL_SLACK = wp.constant(wp.float64(1.0e-6))


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
    diag: wp.float64  # voxel diagonal sqrt(hx^2 + hy^2 + hz^2) [m]
    near_list: wp.int32  # spheres the exact test keeps in its local list, <= NEAR_LIST (tests lower it)
    prune_from: wp.int32  # the exact test prunes covered spheres from this many near ones on (tests vary it)
    gather: wp.int32  # spheres the exact test gathers for its candidates' searches, <= GATHER (tests lower it)
    skip: wp.int32  # 0; benchmarks only (wrong answers, for timing the exact test's parts): SKIP_* bits
    lamp_mask: wp.int32  # bit 2a: low lamp of axis a on; bit 2a+1: high lamp
    offset: wp.vec3i  # first ray of each lamp grid in the per-ray arrays
    face_offset: wp.vec3i  # first face of each lamp grid in the optional per-face owner array
    pad: wp.int32  # wall runs along x are exact from -pad to n_x - 1 + pad (past every index a kernel asks about)


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
def voxel_centre(i: wp.int32, h: wp.float64) -> wp.float64:
    """Voxel centre coordinate (i + 1/2) h (also for i beyond the box), exactly as every kernel evaluates it."""
    return (wp.float64(i) + wp.float64(0.5)) * h


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
def outside_ok(walls: LampWalls, thr: wp.float64, ijk: wp.vec3i, box: WetBox) -> wp.bool:
    """The voxel centre ijk (any index, also beyond the box) has ``g >= thr`` for every wall: the same test as
    ``wall_row_run``'s, point by point."""
    p = wp.vec3d(voxel_centre(ijk[0], box.h[0]), voxel_centre(ijk[1], box.h[1]), voxel_centre(ijk[2], box.h[2]))
    for w in range(walls.n):
        if not (plane_value(walls.frame[w], p) >= thr):
            return False
    return True


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


# --- connectivity -----------------------------------------------------------------------------------------


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


# --- dilation ---------------------------------------------------------------------------------------------


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
def buried(i: wp.int32, positions: wp.array[wp.vec3], radii: wp.array[wp.float32], walls: LampWalls) -> wp.bool:
    """Sphere i lies wholly inside a wall (``g(c) + r < 0``): part of the wall, never a crossing's owner. It cannot
    hold the probe off (the wall holds it farther) nor make a thin chord between fluid samples (g is affine)."""
    p = positions[i]
    c = wp.vec3d(wp.float64(p[0]), wp.float64(p[1]), wp.float64(p[2]))
    for w in range(walls.n):
        if plane_value(walls.frame[w], c) + wp.float64(radii[i]) < wp.float64(0.0):
            return True
    return False


@wp.func
def nearest_in_cube(
    p: wp.vec3d,
    reach: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    box: WetBox,
    walls: LampWalls,
) -> wp.int32:
    """Among binned spheres with centres in the bins that the cube p +- reach touches, less those buried in a wall:
    the smallest |p - c| - r, ties to the lowest index; -1 if there are none."""
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
                        if walls.n == 0 or not buried(i, positions, radii, walls):
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
    walls: LampWalls,
) -> wp.int32:
    """The sphere nearest to crossing point p of a lamp-a row (smallest |p - c| - r, ties to the lowest index; a
    sphere buried in a wall is not one).

    First within one voxel edge: a sphere at distance d1 <= h from p has every sphere that could tie or beat it
    centred within h + r_max of p, all searched, so d1's sphere is the answer. Otherwise (a membrane spanning a
    gap) within the proven bound B_a, beyond which no nearest sphere can lie.
    """
    near = box.h[a]
    reach = (near + rmax) * wp.float64(1.000000001)
    pid = nearest_in_cube(p, reach, positions, radii, heads, next_in_bin, box, walls)
    if pid >= 0:
        if sphere_distance(p, pid, positions, radii) <= near:
            return pid
    return nearest_in_cube(p, box.bound[a] + rmax, positions, radii, heads, next_in_bin, box, walls)


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
    walls: LampWalls,
    counts: wp.array[wp.int64],
    hits: wp.array[wp.int32],
    rays: wp.array[wp.int32],
    diag: wp.array[wp.int32],
    owners: wp.array[wp.int32],
    wall_counts: wp.array[wp.int64],
):
    """A crossing at p on a row along axis a: fluid to dry going +a (enters = 1, the low lamp's +1) or dry to
    fluid (the high lamp's -1), to the nearest sphere, ``|p - c| - r`` (ties to the lowest index). With walls: the
    wall cutting axis a with the smallest signed distance ``g(p)`` (ties to the lower wall) takes the crossing if
    that is smaller than the sphere's distance (ties to the sphere) or no sphere lies within the attribution bound:
    the dry fillet between a body and its platen loads the platen where the platen is nearer. A wall whose normal
    has no a-component never takes an axis-a crossing, so on an axis no wall cuts the particles' counts still sum
    to zero. Integer counts, so the order of the atomics cannot change
    the result."""
    lamp = 2 * a
    sign = int(1)
    if enters != 0:
        wp.atomic_add(rays, box.offset[a] + ray, 1)
    else:
        lamp = 2 * a + 1
        sign = -1
    if ((box.lamp_mask >> lamp) & 1) == 0:
        return
    pid = nearest_sphere(p, a, wp.float64(rmax[0]), positions, radii, heads, next_in_bin, box, walls)
    if walls.n > 0:
        ds = FAR
        if pid >= 0:
            ds = sphere_distance(p, pid, positions, radii)
            if not (ds <= box.bound[a]):
                pid = -1
        wall = int(-1)
        best = wp.float64(0.0)
        for w in range(walls.n):
            pl = walls.frame[w]
            if pl[a] != wp.float32(0.0):
                g = plane_value(pl, p)
                if wall < 0 or g < best:
                    best = g
                    wall = w
        if pid >= 0:
            if not (best < ds):
                wall = -1
        if wall >= 0:
            if owners.shape[0] > 0:
                owners[box.face_offset[a] + ray * (box.n[a] + 1) + face] = WALL_OWNER - wall
            wp.atomic_add(wall_counts, 3 * wall + a, wp.int64(sign))
            return
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
    walls: LampWalls,
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
    wall_counts: wp.array[wp.int64],
):
    """Crossings on the faces of all three axes in one launch (threads from ``first[a]`` on are axis a's): one
    thread per ``bits`` bits of a face word, so that a thread makes at most ``bits`` nearest-sphere searches (the
    host picks 1 for small grids on CUDA, where latency rules, 32 on the CPU).

    Axis 0: face words q = (nwx + 1) row + w, faces f = 32 w + b of row (j, k) (ray j + ny k). Axis 1: q = w + nwx
    (jf + (ny + 1) k), faces jf = 0..ny of the rays of voxels x = 32 w + b (ray k + nz x). Axis 2: q = w + nwx
    (j + ny kf), faces kf = 0..nz (ray x + nx j). Beyond the box is fluid: everywhere without walls, with walls
    within rho of the points that keep rho from every wall (``walls_fluid``, the virtual fluid).
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
        if walls.n == 0:
            if w > 0:
                prev = fluid[row * nwx + w - 1] >> wp.uint32(31)
            if w < nwx:
                after = fluid[row * nwx + w]
        else:
            # The samples just past the row's ends are the virtual fluid (``walls_fluid``); the faces of this word
            # reach at most position n_x, so the other padding bits do not matter.
            after = wp.uint32(0)
            if w < nwx:
                after = fluid[row * nwx + w] & row_mask(box, w)
            top = box.n[0] - 32 * w
            if top >= 0 and top < 32:
                if walls_fluid(virtual_point(box.n[0], j, k, box), walls, box.rho):
                    after = after | (wp.uint32(1) << wp.uint32(top))
            if w > 0:
                prev = (fluid[row * nwx + w - 1] & row_mask(box, w - 1)) >> wp.uint32(31)
            elif not walls_fluid(virtual_point(-1, j, k, box), walls, box.rho):
                prev = wp.uint32(0)
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
            elif walls.n > 0:
                before = virtual_word(walls, w, wp.vec3i(0, -1, k), box)
            if face < box.n[1]:
                after = fluid[word_at(box, w, face, k)]
            elif walls.n > 0:
                after = virtual_word(walls, w, wp.vec3i(0, box.n[1], k), box)
        else:
            j = rest % box.n[1]
            face = rest / box.n[1]
            if face > 0:
                before = fluid[word_at(box, w, j, face - 1)]
            elif walls.n > 0:
                before = virtual_word(walls, w, wp.vec3i(0, j, -1), box)
            if face < box.n[2]:
                after = fluid[word_at(box, w, j, face)]
            elif walls.n > 0:
                after = virtual_word(walls, w, wp.vec3i(0, j, box.n[2]), box)
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
            walls,
            counts,
            hits,
            rays,
            diag,
            owners,
            wall_counts,
        )


# --- exact classification of the uncertain band -------------------------------------------------------------
#
# A point x is fluid when a reachable probe centre z (allowed: |z - c_q| >= r_q + rho for every sphere) lies
# within rho of it. The nearest allowed point to x is a critical point of the union of inflated balls: a face
# point (x projected radially onto an inflated sphere), an edge point (the nearest point to x on the circle where
# two inflated spheres meet) or a vertex (where three meet), or x itself. Those are the candidates; a candidate
# counts when it is within rho of x, outside every other inflated ball, and reachable: a reached corner of the
# voxel-centre cube holding it joins it by a straight segment that stays allowed. Every expression below is
# float64 arithmetic and sqrt on float32 inputs, in the order the reference evaluates it.


@wp.struct
class BinSpan:
    lo: wp.vec3i
    hi: wp.vec3i


@wp.struct
class Chord:
    """A sphere's thin chord on a row: ``ok`` 0 when there is none; ``m0`` the sample before it (the chord lies
    between voxel centres m0 and m0 + 1 along the row); ``lo``/``hi`` its ends along the row's axis [m]."""

    ok: wp.int32
    m0: wp.int32
    lo: wp.float64
    hi: wp.float64


@wp.func
def dot3(a: wp.vec3d, b: wp.vec3d) -> wp.float64:
    return (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2]


@wp.func
def cross3(a: wp.vec3d, b: wp.vec3d) -> wp.vec3d:
    return wp.vec3d(a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@wp.func
def centre_of(i: wp.int32, positions: wp.array[wp.vec3]) -> wp.vec3d:
    p = positions[i]
    return wp.vec3d(wp.float64(p[0]), wp.float64(p[1]), wp.float64(p[2]))


@wp.func
def bin_span(p: wp.vec3d, reach: wp.float64, box: WetBox) -> BinSpan:
    """The bins that the cube p +- reach touches (clamped: far spheres sit in the edge bins)."""
    out = BinSpan()
    for a in range(3):
        top = wp.float64(box.bin_n[a] - 1)
        out.lo[a] = wp.int32(wp.clamp(wp.floor((p[a] - reach) / box.bin_edge), wp.float64(0.0), top))
        out.hi[a] = wp.int32(wp.clamp(wp.floor((p[a] + reach) / box.bin_edge), wp.float64(0.0), top))
    return out


@wp.func
def bin_head(bx: wp.int32, by: wp.int32, bz: wp.int32, box: WetBox, heads: wp.array[wp.int32]) -> wp.int32:
    return heads[(bz * box.bin_n[1] + by) * box.bin_n[0] + bx]


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
                    if not defining(q, i, j, k, positions, radii):
                        if inside_inflated(z, q, positions, radii, box):
                            return q
                    q = next_in_bin[q]
    return -1


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
    span = bin_span(x, reach, box)
    for bz in range(span.lo[2], span.hi[2] + 1):
        for by in range(span.lo[1], span.hi[1] + 1):
            for bx in range(span.lo[0], span.hi[0] + 1):
                q = bin_head(bx, by, bz, box, heads)
                while q >= 0:
                    if not defining(q, i, j, k, positions, radii):
                        big = wp.float64(radii[q]) + box.rho
                        w = y - centre_of(q, positions)
                        t = wp.float64(0.0)
                        if dd > wp.float64(0.0):
                            t = wp.clamp(-dot3(w, d) / dd, wp.float64(0.0), wp.float64(1.0))
                        p = w + d * t
                        if dot3(p, p) < big * big:
                            return True
                    q = next_in_bin[q]
    return False


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
    but its own, on whose offset plane it lies."""
    if hint >= 0:
        if not defining(hint, i, j, k, positions, radii):
            if inside_inflated(z, hint, positions, radii, box):
                return hint
    if not walls_allow(z, i, j, k, walls, box.rho):
        return -1
    near = (rmax + wp.float64(2.0) * box.rho) * (wp.float64(1.0) + SLACK)
    blocker = blocked_point(x, z, i, j, k, near, positions, radii, heads, next_in_bin, box)
    if blocker >= 0:
        return blocker
    far = (rmax + wp.float64(2.0) * box.rho + box.diag) * (wp.float64(1.0) + SLACK)
    lo = wp.vec3i(0)
    for a in range(3):
        f = wp.clamp(wp.floor(z[a] / box.h[a] - wp.float64(0.5)), wp.float64(-2.0), wp.float64(box.n[a] + 1))
        lo[a] = wp.int32(f)
    for corner in range(8):
        ix = lo[0] + (corner & 1)
        iy = lo[1] + ((corner >> 1) & 1)
        iz = lo[2] + ((corner >> 2) & 1)
        if reached_at(ix, iy, iz, reach, box, walls):
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
    gathered: GatherIds,
    ng: wp.int32,
) -> wp.int32:
    """``candidate_check`` for z within rho of x, its blocker and segment searches over the spheres ``gather_near``
    collected around x (``ng`` of them; -1: too many, so the bins are walked). The same answer and the same blocker:
    the list holds, in the bins' order, every sphere of the bins that the walks visit that can hold z (centre within
    r + 2 rho of x) or cut a segment from z to a corner of its voxel-centre cube (within r + 2 rho + diagonal) and
    only the spheres beyond, which can do neither. A corner clamped to the box's surroundings may lie farther from
    z: then the segments walk the bins."""
    if ng < 0:
        return candidate_check(x, z, i, j, k, hint, rmax, positions, radii, heads, next_in_bin, reach, box, walls)
    if hint >= 0:
        if not defining(hint, i, j, k, positions, radii):
            if inside_inflated(z, hint, positions, radii, box):
                return hint
    if not walls_allow(z, i, j, k, walls, box.rho):
        return -1
    for t in range(ng):
        q = gathered[t]
        if not defining(q, i, j, k, positions, radii):
            if inside_inflated(z, q, positions, radii, box):
                return q
    far = (rmax + wp.float64(2.0) * box.rho + box.diag) * (wp.float64(1.0) + SLACK)
    lo = wp.vec3i(0)
    clamped = int(0)
    for a in range(3):
        u = wp.floor(z[a] / box.h[a] - wp.float64(0.5))
        f = wp.clamp(u, wp.float64(-2.0), wp.float64(box.n[a] + 1))
        if f != u:
            clamped = 1
        lo[a] = wp.int32(f)
    for corner in range(8):
        ix = lo[0] + (corner & 1)
        iy = lo[1] + ((corner >> 1) & 1)
        iz = lo[2] + ((corner >> 2) & 1)
        if reached_at(ix, iy, iz, reach, box, walls):
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
                    cut = int(0)
                    for t in range(ng):
                        q = gathered[t]
                        if not defining(q, i, j, k, positions, radii):
                            big = wp.float64(radii[q]) + box.rho
                            w = y - centre_of(q, positions)
                            s = wp.float64(0.0)
                            if dd > wp.float64(0.0):
                                s = wp.clamp(-dot3(w, d) / dd, wp.float64(0.0), wp.float64(1.0))
                            p = w + d * s
                            if dot3(p, p) < big * big:
                                cut = 1
                                break
                    if cut == 0:
                        return CANDIDATE_OK
    return -1


@wp.struct
class Gathered:
    """``gather_near``'s answer: ``ids[:n]`` the spheres, the first ``n_near`` from the bins of ``span`` (-1 in n:
    more than ``box.gather``)."""

    ids: GatherIds
    n: wp.int32
    n_near: wp.int32


@wp.func
def gather_near(
    x: wp.vec3d,
    span: BinSpan,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    box: WetBox,
) -> Gathered:
    """The spheres whose centres lie within (r + 2 rho + diagonal)(1 + slack) of x, from the bins within
    (rmax + 2 rho + diagonal)(1 + slack) of x: first those of the bins ``span`` (the candidates' blocker search, in
    its walk order), then the others. Every sphere that can hold a candidate within rho of x or cut a segment from
    it to a corner of its voxel-centre cube is among them."""
    out = Gathered()
    out.n = 0
    out.n_near = 0
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
                    if inner == (part == 0) and out.n >= 0:
                        q = bin_head(bx, by, bz, box, heads)
                        while q >= 0 and out.n >= 0:
                            lim = (wp.float64(radii[q]) + wp.float64(2.0) * box.rho + box.diag) * (
                                wp.float64(1.0) + SLACK
                            )
                            v = x - centre_of(q, positions)
                            if dot3(v, v) <= lim * lim:
                                if out.n < box.gather:
                                    out.ids[out.n] = q
                                    out.n += 1
                                else:
                                    out.n = -1
                            q = next_in_bin[q]
        if part == 0:
            out.n_near = out.n
    return out


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
    ci = centre_of(i, positions)
    big_i = wp.float64(radii[i]) + rho
    big_j = wp.float64(radii[j]) + rho
    v = x - ci
    d2 = dot3(v, v)
    e = centre_of(j, positions) - ci
    l2 = dot3(e, e)
    if d2 == wp.float64(0.0) or l2 == wp.float64(0.0):
        return False
    d = wp.sqrt(d2)
    el = wp.sqrt(l2)
    ca = (big_i * big_i + d2 - rho * rho) / (wp.float64(2.0) * big_i * d)
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


# --- walls in the exact test ----------------------------------------------------------------------------------
#
# A wall inflated by rho is the half-space g < rho (g = n . x - d, ``plane_value``): its boundary, the offset plane
# g = rho, is one more surface of the union whose critical points are the candidates. Faces: x projected onto the
# offset plane; edges: the circle where it meets an inflated sphere, the line where two offset planes meet; vertices:
# where it meets two inflated spheres, or a sphere and another offset plane, and where three offset planes meet.
# A candidate's own walls are tagged ``WALL_TAG - w`` among its defining spheres.


@wp.func
def wall_normal(pl: wp.vec4) -> wp.vec3d:
    return wp.vec3d(wp.float64(pl[0]), wp.float64(pl[1]), wp.float64(pl[2]))


@wp.func
def wall_near(x: wp.vec3d, pl: wp.vec4, rho: wp.float64) -> wp.bool:
    """The wall's offset plane passes within rho of x (with slack: the normal is unit to float32 rounding), so it
    can carry a candidate within rho of x (a pruning; the distance test decides)."""
    return wp.abs(plane_value(pl, x) - rho) <= rho * (wp.float64(1.0) + WALL_SLACK)


@wp.func
def wall_face_point(x: wp.vec3d, pl: wp.vec4, rho: wp.float64) -> wp.vec3d:
    """x projected onto the wall's offset plane ``n . z - d = rho``."""
    n = wall_normal(pl)
    return x - n * ((plane_value(pl, x) - rho) / dot3(n, n))


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
def wall_line_point(x: wp.vec3d, p1: wp.vec4, p2: wp.vec4, rho: wp.float64) -> wp.vec4d:
    """The point nearest to x on the line where two walls' offset planes meet, and 1 in the last component (0 when
    the walls are parallel): ``z = x + al n1 + be n2`` with ``n_k . z - d_k = rho``."""
    out = wp.vec4d(0.0)
    n1 = wall_normal(p1)
    n2 = wall_normal(p2)
    a11 = dot3(n1, n1)
    a12 = dot3(n1, n2)
    a22 = dot3(n2, n2)
    det = a11 * a22 - a12 * a12
    if not (det > wp.float64(0.0)):
        return out
    e1 = rho - plane_value(p1, x)
    e2 = rho - plane_value(p2, x)
    al = (e1 * a22 - e2 * a12) / det
    be = (e2 * a11 - e1 * a12) / det
    z = x + n1 * al + n2 * be
    return wp.vec4d(z[0], z[1], z[2], wp.float64(1.0))


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
def walls_corner(p1: wp.vec4, p2: wp.vec4, p3: wp.vec4, rho: wp.float64) -> wp.vec4d:
    """The point where three walls' offset planes meet (Cramer's rule), and 1 in the last component (0 when two of
    them are parallel)."""
    out = wp.vec4d(0.0)
    n1 = wall_normal(p1)
    n2 = wall_normal(p2)
    n3 = wall_normal(p3)
    c23 = cross3(n2, n3)
    det = dot3(n1, c23)
    if det == wp.float64(0.0) or not wp.isfinite(det):
        return out
    z = (
        c23 * (wp.float64(p1[3]) + rho)
        + cross3(n3, n1) * (wp.float64(p2[3]) + rho)
        + cross3(n1, n2) * (wp.float64(p3[3]) + rho)
    ) / det
    return wp.vec4d(z[0], z[1], z[2], wp.float64(1.0))


@wp.func
def walls_allow(z: wp.vec3d, i: wp.int32, j: wp.int32, k: wp.int32, walls: LampWalls, rho: wp.float64) -> wp.bool:
    """z keeps rho from every wall but its own (tags i, j, k): ``g >= rho``."""
    for w in range(walls.n):
        tag = WALL_TAG - w
        if i != tag and j != tag and k != tag:
            if plane_value(walls.frame[w], z) < rho:
                return False
    return True


@wp.func
def walls_fluid(x: wp.vec3d, walls: LampWalls, rho: wp.float64) -> wp.bool:
    """The virtual fluid beyond the box: x lies within rho of the convex set C of points that keep rho from every
    wall (``g >= rho``), spheres aside. Exact: x in C, or the nearest point of C, on a face, an edge or a vertex
    of C (a wall's face point, two walls' line point, three walls' corner) that lies in C and within rho. Without
    walls, everywhere; with one wall, where ``g >= 0`` (to the rounding of its unit normal); where walls meet, less
    their fillet of radius rho, as the voxels along an axis that no wall cuts see it."""
    rho2 = rho * rho
    inside = bool(True)
    for w in range(walls.n):
        g = plane_value(walls.frame[w], x)
        if g < wp.float64(0.0):
            return False
        if g < rho:
            inside = False
    if inside:
        return True
    for w in range(walls.n):
        p1 = walls.frame[w]
        z = wall_face_point(x, p1, rho)
        e = x - z
        if dot3(e, e) <= rho2 and walls_allow(z, WALL_TAG - w, -1, -1, walls, rho):
            return True
        for v in range(w + 1, walls.n):
            p2 = walls.frame[v]
            lp = wall_line_point(x, p1, p2, rho)
            if lp[3] != wp.float64(0.0):
                z = wp.vec3d(lp[0], lp[1], lp[2])
                e = x - z
                if dot3(e, e) <= rho2 and walls_allow(z, WALL_TAG - w, WALL_TAG - v, -1, walls, rho):
                    return True
            for u in range(v + 1, walls.n):
                cp = walls_corner(p1, p2, walls.frame[u], rho)
                if cp[3] != wp.float64(0.0):
                    z = wp.vec3d(cp[0], cp[1], cp[2])
                    e = x - z
                    if dot3(e, e) <= rho2 and walls_allow(z, WALL_TAG - w, WALL_TAG - v, WALL_TAG - u, walls, rho):
                        return True
    return False


@wp.func
def virtual_point(i: wp.int32, j: wp.int32, k: wp.int32, box: WetBox) -> wp.vec3d:
    """The voxel centre (i, j, k), also beyond the box."""
    return wp.vec3d(voxel_centre(i, box.h[0]), voxel_centre(j, box.h[1]), voxel_centre(k, box.h[2]))


@wp.func
def virtual_word(walls: LampWalls, w: wp.int32, at: wp.vec3i, box: WetBox) -> wp.uint32:
    """Word w of the virtual samples on the row (at[1], at[2]) beyond the box (x = 32 w + b): the virtual fluid
    (``walls_fluid``), at the voxels of the word."""
    out = wp.uint32(0)
    m = row_mask(box, w)
    for b in range(32):
        if ((m >> wp.uint32(b)) & wp.uint32(1)) != wp.uint32(0):
            if walls_fluid(virtual_point(32 * w + b, at[1], at[2], box), walls, box.rho):
                out = out | (wp.uint32(1) << wp.uint32(b))
    return out


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
    """Whether x, outside every sphere, is fluid by exact distances: some candidate probe centre within rho of it is
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
    g = gather_near(x, span, rmax, positions, radii, heads, next_in_bin, box)
    if lattice == 0:
        for wi in range(walls.n):
            if plane_value(walls.frame[wi], x) < wp.float64(0.0):
                return False
        sspan = bin_span(x, rmax * (wp.float64(1.0) + SLACK), box)
        for bz in range(sspan.lo[2], sspan.hi[2] + 1):
            for by in range(sspan.lo[1], sspan.hi[1] + 1):
                for bx in range(sspan.lo[0], sspan.hi[0] + 1):
                    q = bin_head(bx, by, bz, box, heads)
                    while q >= 0:
                        r = wp.float64(radii[q])
                        v = x - centre_of(q, positions)
                        if dot3(v, v) < r * r:
                            return False
                        q = next_in_bin[q]
        if (
            candidate_check_list(
                x, x, -1, -1, -1, -1, rmax, positions, radii, heads, next_in_bin, reach, box, walls, g.ids, g.n
            )
            == CANDIDATE_OK
        ):
            return True
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
    if g.n >= 0:
        for t in range(g.n_near):
            i = g.ids[t]
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
        if g.n >= 0:
            for t in range(g.n_near):
                i = g.ids[t]
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
                return True
            return wall_search(
                x, ids, 0, 0, span, rmax, positions, radii, heads, next_in_bin, exposed, reach, box, walls
            )
    if (box.skip & 8) != 0:
        return False
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
        return False
    # Faces: the commonest answer, so first.
    for a in range(cnt * wp.where((box.skip & 4) != 0, 0, 1)):
        i = ids[a]
        c = centre_of(i, positions)
        v = x - c
        d2 = dot3(v, v)
        if d2 > wp.float64(0.0):
            z = c + v * ((wp.float64(radii[i]) + rho) / wp.sqrt(d2))
            w = x - z
            if dot3(w, w) <= rho2:
                res = candidate_check_list(
                    x, z, i, -1, -1, hint, rmax, positions, radii, heads, next_in_bin, reach, box, walls, g.ids, g.n
                )
                if res == CANDIDATE_OK:
                    return True
                if res >= 0:
                    hint = res
    # Edges, and the vertices on every circle that passes within rho of x.
    for a in range(cnt):
        i = ids[a]
        ci = centre_of(i, positions)
        big_i = wp.float64(radii[i]) + rho
        for b in range(a + 1, cnt * wp.where((box.skip & 2) != 0, 0, 1)):
            j = ids[b]
            cj = centre_of(j, positions)
            big_j = wp.float64(radii[j]) + rho
            cp = circle_point(x, ci, big_i, cj, big_j)
            if cp[3] != wp.float64(0.0):
                z = wp.vec3d(cp[0], cp[1], cp[2])
                w = x - z
                e2 = dot3(w, w)
                if e2 <= rho2:
                    res = candidate_check_list(
                        x, z, i, j, -1, hint, rmax, positions, radii, heads, next_in_bin, reach, box, walls, g.ids, g.n
                    )
                    if res == CANDIDATE_OK:
                        return True
                    if res >= 0:
                        hint = res
                if e2 <= rho2 * (wp.float64(1.0) + SLACK) and (box.skip & 1) == 0:
                    for e in range(b + 1, cnt):
                        k = ids[e]
                        vp = vertex_points(ci, big_i, cj, big_j, centre_of(k, positions), wp.float64(radii[k]) + rho)
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
                                        g.ids,
                                        g.n,
                                    )
                                    if res == CANDIDATE_OK:
                                        return True
                                    if res >= 0:
                                        hint = res
    return wall_search(x, ids, cnt, 1, span, rmax, positions, radii, heads, next_in_bin, exposed, reach, box, walls)


@wp.kernel
def wet_expose(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    active: wp.array[wp.int32],
    box: WetBox,
    reach: wp.array[wp.uint32],
    # outputs
    exposed: wp.array[wp.int32],
):
    """One thread per sphere: 1 when a reached voxel (or the outside) lies within (r + rho + diagonal)(1 + slack)
    of its centre. A reachable candidate on the sphere's inflated surface has a reached cube corner within one
    diagonal, so a sphere that is not exposed carries none (a necessary condition: pruning, not a decision)."""
    pid = wp.tid()
    exposed[pid] = 0
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
    for k in range(ks[0], ks[1] + 1):
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
    # outputs
    fluid: wp.array[wp.uint32],
    diag: wp.array[wp.int32],
    queue: wp.array[wp.int32],
    queued: wp.array[wp.int32],
):
    """One thread per ``bits`` bits of a word (32 on the CPU; fewer on CUDA): every voxel of the band (within rho +
    diagonal of a reached voxel) that the dilation by rho left dry and that is not solid gets the exact test. With
    ``capacity`` > 0 the first ``capacity`` such voxels go to ``queue`` (their word * 32 + bit, in no set order;
    ``queued[0]``, zeroed before, counts them all) for ``wet_classify_queued``, and the thread tests the rest
    itself. A thread sets only its own bits of ``fluid``."""
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
    r_max = wp.float64(rmax[0])
    add = wp.uint32(0)
    tested = int(0)
    wet = int(0)
    while unc != wp.uint32(0):
        b = lowest_bit(unc)
        unc = unc & (unc - wp.uint32(1))
        tested += 1
        if capacity > 0:
            slot = wp.atomic_add(queued, 0, 1)
            if slot < capacity:
                queue[slot] = idx * 32 + b
                continue
        x = voxel_point(wjk, b, box)
        if probe_reaches(x, 1, r_max, positions, radii, heads, next_in_bin, exposed, reach, box, walls):
            add = add | (wp.uint32(1) << wp.uint32(b))
            wet += 1
    if add != wp.uint32(0):
        if bits == 32:
            fluid[idx] = fluid[idx] | add
        else:
            wp.atomic_or(fluid, idx, add)
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
    queued: wp.array[wp.int32],
    # outputs
    fluid: wp.array[wp.uint32],
    diag: wp.array[wp.int32],
):
    """One thread per queued voxel (``wet_classify``), launched for the queue's capacity: the exact tests packed
    into as few threads as there are tests, where ``wet_classify``'s threads are mostly idle."""
    slot = wp.tid()
    if slot >= queued[0]:
        return
    v = queue[slot]
    idx = v / 32
    b = v - idx * 32
    wjk = word_coords(box, idx)
    x = voxel_point(wjk, b, box)
    if probe_reaches(x, 1, wp.float64(rmax[0]), positions, radii, heads, next_in_bin, exposed, reach, box, walls):
        wp.atomic_or(fluid, idx, wp.uint32(1) << wp.uint32(b))
        wp.atomic_add(diag, DIAG_RESCUED, 1)


# --- thin chords ----------------------------------------------------------------------------------------------


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
    ijk = wp.vec3i(0)
    ijk[a] = m
    ijk[(a + 1) % 3] = iu
    ijk[(a + 2) % 3] = iv
    if m < 0 or m >= box.n[a]:
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
    # outputs
    counts: wp.array[wp.int64],
    hits: wp.array[wp.int32],
    rays: wp.array[wp.int32],
    diag: wp.array[wp.int32],
    thin_faces: wp.array[wp.int32],
):
    """One thread per (sphere, axis): the sphere's thin chords on the rows of that axis whose samples on both sides
    are fluid. The thin chords between the same two samples, ordered by start, merge where they overlap or touch
    or where the gap between them is dry (``probe_reaches`` at its midpoint); the thread of the first chord of each
    merged interval loads its entry (the low lamp's +1, to that sphere) and its exit (the high lamp's -1, to the
    sphere whose chord reaches furthest, ties to the lower index). Integer counts: the order is immaterial."""
    t = wp.tid()
    s = t / 3
    a = t - 3 * s
    if active.shape[0] > 0:
        if active[s] == 0:
            return
    p = positions[s]
    r32 = radii[s]
    if not (wp.isfinite(p[0]) and wp.isfinite(p[1]) and wp.isfinite(p[2]) and wp.isfinite(r32) and r32 > 0.0):
        return
    c = centre_of(s, positions)
    r = wp.float64(r32)
    u = (a + 1) % 3
    v = (a + 2) % 3
    r_max = wp.float64(rmax[0])
    us = span_from(c[u], r, box.h[u], box.n[u])
    vs = span_from(c[v], r, box.h[v], box.n[v])
    r2 = r * r
    ha2 = box.h[a] * box.h[a]
    for iv in range(vs[0], vs[1] + 1):
        dv = centre_offset(iv, box.h[v], c[v])
        for iu in range(us[0], us[1] + 1):
            du = centre_offset(iu, box.h[u], c[u])
            # thin_chord's first test, cheaply (two terms add in either order, exactly): most rows end here.
            t2 = du * du + dv * dv
            if not (t2 < r2) or r2 - t2 >= ha2:
                continue
            me = thin_chord(s, a, iu, iv, positions, radii, box)
            if me.ok == 0:
                continue
            m0 = me.m0
            if not (
                fluid_sample(a, m0, iu, iv, fluid, box, walls) and fluid_sample(a, m0 + 1, iu, iv, fluid, box, walls)
            ):
                continue
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
                    continue
                wp.atomic_add(diag, DIAG_GAPS, 1)
                gap = row_point(a, (top + me.lo) * wp.float64(0.5), iu, iv, box)
                if not probe_reaches(gap, 0, r_max, positions, radii, heads, next_in_bin, exposed, reach, box, walls):
                    continue
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
                        if probe_reaches(
                            gap, 0, r_max, positions, radii, heads, next_in_bin, exposed, reach, box, walls
                        ):
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
