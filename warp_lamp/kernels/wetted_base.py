"""Wetted-surface kernels' shared parts: constants, the voxel box (``WetBox``), bit and row helpers.

The pipeline and its conventions are described in :mod:`warp_lamp.kernels.wetted`. No kernels here: each stage's
module compiles what it uses of these."""

import warp as wp

from warp_lamp.kernels.walls import LampWalls, plane_value

# No kernels here, but the same options as the stages that call these functions (the project's CPU = CUDA rule).
wp.set_module_options({"enable_backward": False, "fuse_fp": False, "max_unroll": 1})

# No unrolling: the exact classification nests small constant loops (corners, pairs, axes) around deep inlined
# calls, and unrolled they made one kernel so large that compiling the module for sm_90 took 570 s on the H100's
# host (NVRTC through ``wp.compile_aot_module`` on the 2-core dev machine: 502 s unrolled, 57 s not). Unrolling
# changes no result (the mode's dumps are bitwise equal); its effect on the GPU's run time is not yet measured.
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
#: A queue of exact tests shorter than its threads is spread over them, at most this many threads apart (one test to
#: a warp): in slot order a short queue sat in a few blocks, 32 diverging tests to a warp, while most SMs idled.
QUEUE_SPREAD = 32
#: ... and only from this stride up. On an H200 the specimen's queue from scratch (stride 2) lost 9% of its
#: classification spread (a warp's neighbouring voxels gather the same spheres; apart they lose it), while its queue
#: with the skin at rest (stride 3: the voxels kept dry are out of it) gained 18% (`bench/NOTES.md`).
QUEUE_SPREAD_FROM = 3
GatherIds = wp.types.vector(length=GATHER, dtype=wp.int32)
#: Near spheres (after pruning) for which the exact test keeps a mask of the reached lattice points near x that a
#: candidate on each could have as a corner; with more, or more than 64 such points, every candidate is tried.
MASK_SPHERES = 32
#: Near spheres (after pruning) from which the exact test builds the masks (below, every candidate is tried: the
#: masks' point scan costs more than the few pairs and triples it could skip).
MASK_FROM = 6
ReachMasks = wp.types.vector(length=MASK_SPHERES, dtype=wp.uint64)
#: Reached lattice points a point's exact test lists (one bit each in ``ReachMasks``).
REACH_POINTS = 64
ReachPoints = wp.types.vector(length=REACH_POINTS, dtype=wp.int32)
#: Rows of lattice points (along x) the exact test reads for them at most; past it, every candidate is tried.
REACH_ROWS = 256
#: A triple is skipped by the masks only when its centres are this far from collinear (det >= this * a11 * a22):
#: then its computed points lie on the three inflated spheres to far less than the masks' slack.
CONDITIONED = wp.constant(wp.float64(1.0e-3))
#: Spheres the skin's dry certificate lists around a voxel; with more it certifies nothing (the voxel is tested).
CERT_LIST = 48
CertIds = wp.types.vector(length=CERT_LIST, dtype=wp.int32)
#: A witness's segment clearance per corner of its cube.
Vec8d = wp.types.vector(length=8, dtype=wp.float64)
#: The skin's state (``WettedSurface._skin_state``, int32): reset in this update (1) or not, primed (a reference
#: taken), dry decisions kept and certified in this update, resets since construction ...
SKIN_RESET = wp.constant(0)
SKIN_PRIMED = wp.constant(1)
SKIN_KEPT = wp.constant(2)
SKIN_CERTIFIED = wp.constant(3)
SKIN_RESETS = wp.constant(4)
#: ... wet decisions kept by their witness in this update, witness keys taken since the table was last wiped, and
#: whether this update wipes it (more than three quarters full).
SKIN_WITNESSED = wp.constant(5)
SKIN_FILLED = wp.constant(6)
SKIN_WIPE = wp.constant(7)
#: ... and the particle count of the reference.
SKIN_COUNT = wp.constant(8)
#: ... crossings whose owner was kept in this update, owner keys taken since the owner table was last wiped, and
#: whether this update wipes it (three quarters full; a new reference wipes it too).
SKIN_CROSS_KEPT = wp.constant(9)
SKIN_CROSS_FILLED = wp.constant(10)
SKIN_CROSS_WIPE = wp.constant(11)
#: Voxels kept wet by their witness's margin alone, without a search (a subset of ``SKIN_WITNESSED``).
SKIN_HELD = wp.constant(12)
#: Whether the update before this one took a new reference: two in a row (particles outrunning the skin every update,
#: as chips do in a cut) and this one keeps, certifies and measures nothing, running as from scratch.
SKIN_LAST = wp.constant(13)
N_SKIN = 14
#: Slots a witness key is looked for or placed in (open addressing, linear probing) before giving up.
WITNESS_PROBES = wp.constant(16)
#: The certificate's rounding allowances (relative, on squared lengths): a covering ball must hold a point by this
#: much, a point within rho of the voxel is one within rho^2 (1 + CERT_NEAR); they dwarf float64 rounding.
CERT_IN = wp.constant(wp.float64(1.0e-6))
CERT_NEAR = wp.constant(wp.float64(1.0e-6))
#: Near-degenerate geometry the certificate declines (it certifies nothing there): tangent balls, a voxel on a
#: circle's axis, nearly collinear centres, a circle nearly tangent to a third sphere.
CERT_TINY = wp.constant(wp.float64(1.0e-12))
#: Relative slack of the pruning tests below: they may only drop what exact arithmetic rules out with room to spare.
SLACK = wp.constant(wp.float64(1.0e-9))
#: A witness's margin is trusted only beyond the distance it must cover (the candidate's own move plus the skin)
#: by this fraction of it and KEEP_ABS of the search's length scale (r_max + rho + diagonal): both dwarf float64
#: rounding in the distances compared.
KEEP_REL = wp.constant(wp.float64(1.0e-6))
KEEP_ABS = wp.constant(wp.float64(1.0e-9))
#: A witness's margin is measured out to this many skins (its search reaches no farther).
KEEP_CAP = wp.constant(wp.float64(4.0))
#: ``WitMargin.epoch`` of a witness whose margin this update measures (``wet_skin_margins``); -1: none.
MARGIN_PENDING = wp.constant(-2)
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
    mask_from: wp.int32  # the exact test masks candidates by reached points from this many near ones on (MASK_FROM)
    gather: wp.int32  # spheres the exact test gathers for its candidates' searches, <= GATHER (tests lower it)
    skip: wp.int32  # 0; benchmarks only (wrong answers, for timing the exact test's parts): SKIP_* bits
    lamp_mask: wp.int32  # bit 2a: low lamp of axis a on; bit 2a+1: high lamp
    offset: wp.vec3i  # first ray of each lamp grid in the per-ray arrays
    face_offset: wp.vec3i  # first face of each lamp grid in the optional per-face owner array
    pad: wp.int32  # wall runs along x are exact from -pad to n_x - 1 + pad (past every index a kernel asks about)


@wp.struct
class WitMargin:
    """A wet voxel's witness measured for the skin: how far every other sphere keeps from its candidate.

    ``z`` is the candidate probe centre [frame m] when measured; ``m`` [m] the least clearance, over every sphere
    but the candidate's own (by index), of its inflated ball from z and from the segment z to corner ``corner``
    (``dx + 2 dy + 4 dz``) of the voxel-centre cube at ``lo``, capped (-1: none measured); ``epoch`` the skin's
    reference it was measured under (``SKIN_RESETS`` after that update)."""

    z: wp.vec3d
    m: wp.float64
    lo: wp.vec3i
    corner: wp.int32
    epoch: wp.int32


@wp.func
def no_margin(epoch: wp.int32) -> WitMargin:
    """A witness with no margin measured (m = -1, no corner) under reference ``epoch``."""
    out = WitMargin()
    out.m = wp.float64(-1.0)
    out.corner = -1
    out.epoch = epoch
    return out


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
def lowest_bit(t: wp.uint32) -> wp.int32:
    return wp.bit_count((t & (~t + wp.uint32(1))) - wp.uint32(1))


@wp.func
def voxel_centre(i: wp.int32, h: wp.float64) -> wp.float64:
    """Voxel centre coordinate (i + 1/2) h (also for i beyond the box), exactly as every kernel evaluates it."""
    return (wp.float64(i) + wp.float64(0.5)) * h


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
def word_coords(box: WetBox, idx: wp.int32) -> wp.vec3i:
    """(word along x, row y, layer z) of word ``idx`` of a bitmap."""
    jk = idx / box.nwx
    return wp.vec3i(idx % box.nwx, jk % box.n[1], jk / box.n[1])


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
def wall_normal(pl: wp.vec4) -> wp.vec3d:
    return wp.vec3d(wp.float64(pl[0]), wp.float64(pl[1]), wp.float64(pl[2]))


@wp.func
def wall_face_point(x: wp.vec3d, pl: wp.vec4, rho: wp.float64) -> wp.vec3d:
    """x projected onto the wall's offset plane ``n . z - d = rho``."""
    n = wall_normal(pl)
    return x - n * ((plane_value(pl, x) - rho) / dot3(n, n))


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
def witness_slot(v: wp.int32, capacity: wp.int32) -> wp.int32:
    """The first slot of voxel v's key in a table of ``capacity`` (a power of two) slots."""
    u = wp.uint32(v)
    u = u ^ (u >> wp.uint32(16))
    u = u * wp.uint32(0x45D9F3B)
    u = u ^ (u >> wp.uint32(16))
    return wp.int32(u & wp.uint32(capacity - 1))


@wp.func
def table_find(key: wp.int32, keys: wp.array[wp.int32]) -> wp.int32:
    """The slot holding ``key`` in an open-addressed table (``keys``: -1 free; linear probing from
    ``witness_slot``, at most ``WITNESS_PROBES`` slots), or -1."""
    cap = keys.shape[0]
    s = witness_slot(key, cap)
    for _p in range(WITNESS_PROBES):
        k = keys[s]
        if k == key:
            return s
        if k == -1:
            return -1
        s = (s + 1) & (cap - 1)
    return -1


@wp.func
def table_claim(
    key: wp.int32, claim: wp.bool, keys: wp.array[wp.int32], skin: wp.array[wp.int32], filled: wp.int32
) -> wp.int32:
    """``table_find``'s slot for ``key``, or with ``claim`` a free one taken for it (``skin[filled]`` counts the
    slots taken); -1 when ``key`` has none and is not to claim one, or when a full probe run finds no slot."""
    cap = keys.shape[0]
    s = witness_slot(key, cap)
    for _p in range(WITNESS_PROBES):
        k = keys[s]
        if k == key:
            return s
        if k == -1:
            if not claim:
                return -1
            old = wp.atomic_cas(keys, s, -1, key)
            if old == -1 or old == key:
                if old == -1:
                    wp.atomic_add(skin, filled, 1)
                return s
        s = (s + 1) & (cap - 1)
    return -1


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
