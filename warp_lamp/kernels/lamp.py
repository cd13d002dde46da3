"""Shining-lamp kernels: seed, depth pass (one thread per sphere), count scatter (one thread per cell), forces.

Each cell holds two keys (``kernels/keys.py``): [2 c] for the low lamp (at minus infinity, shining toward +a) and
[2 c + 1] for the high lamp. Both are resolved with atomic_min: the high lamp keys negated exit depths, so that
one identity (EMPTY_KEY) and one tie rule (lowest index wins) serve both sides. The grid arrives as one
``LampGridParams`` (``kernels/grid.py``).
"""

import warp as wp

from warp_lamp.kernels.footprint import cell_offset, cell_span, lamp_reach
from warp_lamp.kernels.grid import BLOCK, LampGridParams, grid_block, grid_cell
from warp_lamp.kernels.keys import EMPTY_KEY, LOW_WORD, key_owner, pack_key

# fuse_fp off: CUDA must not contract a*b+c into an FMA, or its depths and hit tests differ from the CPU's in
# the last bit and CPU and GPU owners stop being bitwise equal.
wp.set_module_options({"enable_backward": False, "fuse_fp": False, "optimization_level": 3})

#: Threads per block of the depth pass: 128 beat 256 by 7-9% on an H200 once the row filter issues its loads
#: in chunks (bench/NOTES.md v4).
DEPTH_BLOCK_DIM = 128

#: Most keys a sample keeps per lamp (``depth_slots``): the first D spheres along its ray.
MAX_SLOTS = 4
SlotKeys = wp.types.vector(length=MAX_SLOTS, dtype=wp.uint64)

#: Slots of the diagnostics counter array.
DIAG_INVALID = wp.constant(0)
DIAG_OUTSIDE = wp.constant(1)
N_DIAG = 2


@wp.struct
class LampParticles:
    """The particles an update reads: centres [m] (world or frame coordinates, see ``LampGridParams.origin``),
    radii [m], an optional activity mask (empty: all active), and their number."""

    positions: wp.array[wp.vec3]
    radii: wp.array[wp.float32]
    active: wp.array[wp.int32]
    n: wp.int32


@wp.struct
class FrameSphere:
    """A particle in frame coordinates, and whether it casts light (active, finite, radius > 0)."""

    center: wp.vec3
    radius: wp.float32
    casts: wp.bool


@wp.func
def inactive(particles: LampParticles, particle: wp.int32) -> wp.bool:
    """Masked out by the caller (as opposed to invalid)."""
    if particles.active.shape[0] > 0:
        if particles.active[particle] == 0:
            return True
    return False


@wp.func
def frame_sphere(grid: LampGridParams, particles: LampParticles, particle: wp.int32) -> FrameSphere:
    """Particle ``particle`` moved into the frame; ``casts`` is false for an index past n, an inactive particle, or a
    non-finite position or radius, or a radius <= 0."""
    out = FrameSphere()
    out.casts = False
    if particle >= particles.n:
        return out
    if inactive(particles, particle):
        return out
    p = particles.positions[particle] - grid.origin
    r = particles.radii[particle]
    # NaN fails every comparison, so `not (r > 0)` also catches a NaN radius.
    if not (wp.isfinite(p[0]) and wp.isfinite(p[1]) and wp.isfinite(p[2]) and wp.isfinite(r) and r > 0.0):
        return out
    out.center = p
    out.radius = r
    out.casts = True
    return out


@wp.func
def offer(keys: wp.array[wp.uint64], slot: wp.int32, key: wp.uint64):
    # Read before the atomic: a losing candidate costs a load instead of an L2 atomic round trip.
    if key < keys[slot]:
        wp.atomic_min(keys, slot, key)


@wp.func
def offer_slots(keys: wp.array[wp.uint64], base: wp.int32, depth_slots: wp.int32, key: wp.uint64):
    """Keep the ``depth_slots`` smallest distinct keys offered to keys[base ... base + D - 1], in ascending order.

    Read the last slot first: an offer that cannot enter costs a load. Otherwise a chain of atomic_min: the loser of
    each exchange moves down to the next slot. A slot's value only decreases, so each slot ends as the minimum of
    what was pushed into it, which makes the result the D smallest keys in order, under any interleaving. An
    exchange that finds its own key already there stops: an offer the seed already placed, or a duplicate that
    a concurrent push has not yet passed, is not kept twice.
    """
    if key >= keys[base + depth_slots - 1]:
        return
    k = key
    for slot in range(depth_slots):
        old = wp.atomic_min(keys, base + slot, k)
        if old == k:
            return
        k = wp.max(old, k)
        if k == EMPTY_KEY:
            return


@wp.func
def row_live(keys: wp.array[wp.uint64], row: wp.int32, c0: wp.int32, c1: wp.int32, lo: wp.uint64, hi: wp.uint64):
    """Bit 0: some low key of cells c0..c1 is >= lo; bit 1: some high key is >= hi.

    Four cells per step, all eight loads issued before the first compare: with almost no atomics left, the
    depth pass waits on L2 latency, and a warp that used each load in its own iteration stalled once per cell
    (measured: 26% off the warm depth pass, bench/NOTES.md v4). Indices past c1 re-read c1.
    """
    live = int(0)
    i = c0
    while i <= c1:
        s0 = row + 2 * i
        s1 = row + 2 * wp.min(i + 1, c1)
        s2 = row + 2 * wp.min(i + 2, c1)
        s3 = row + 2 * wp.min(i + 3, c1)
        l0 = keys[s0]
        h0 = keys[s0 + 1]
        l1 = keys[s1]
        h1 = keys[s1 + 1]
        l2 = keys[s2]
        h2 = keys[s2 + 1]
        l3 = keys[s3]
        h3 = keys[s3 + 1]
        if wp.max(wp.max(l0, l1), wp.max(l2, l3)) >= lo:
            live = live | 1
        if wp.max(wp.max(h0, h1), wp.max(h2, h3)) >= hi:
            live = live | 2
        i += 4
    return live


@wp.kernel
def lamp_clear(
    n_particles: wp.int32,
    # outputs
    counts: wp.array[wp.int32],
    diag: wp.array[wp.int32],
):
    t = wp.tid()
    if t < n_particles:
        counts[3 * t] = 0
        counts[3 * t + 1] = 0
        counts[3 * t + 2] = 0
    if t < diag.shape[0]:
        diag[t] = 0


@wp.func
def owner_key(
    grid: LampGridParams, particles: LampParticles, cell: wp.vec3i, side: wp.int32, owner: wp.int32, criterion: wp.int32
) -> wp.uint64:
    """The key that particle ``owner`` offers to lamp ``side`` of ``cell`` (a, i, j) at the current positions, or
    EMPTY_KEY where it no longer lights the cell: the depth pass's own decision, through the same functions."""
    sphere = frame_sphere(grid, particles, owner)
    if not sphere.casts:
        return EMPTY_KEY
    a = cell[0]
    r = sphere.radius
    dv = cell_offset(cell[2], grid.h_v[a], sphere.center[(a + 2) % 3] - grid.corner_v[a], criterion)
    du = cell_offset(cell[1], grid.h_u[a], sphere.center[(a + 1) % 3] - grid.corner_u[a], criterion)
    rem = r * r - dv * dv
    if rem < 0.0 or du * du > rem:
        return EMPTY_KEY
    reach = lamp_reach(rem, du, criterion)
    if side == 0:
        return pack_key(sphere.center[a] - reach, owner)
    return pack_key(-(sphere.center[a] + reach), owner)


@wp.kernel
def lamp_seed(
    grid: LampGridParams,
    particles: LampParticles,
    criterion: wp.int32,
    depth_slots: wp.int32,
    # outputs
    keys: wp.array[wp.uint64],
):
    """One thread per cell replaces each lamp's kept keys with their owners' keys at the current positions (EMPTY
    where an owner no longer lights the cell), re-sorted.

    The seed keys are offers the depth pass makes anyway, so the final result is unchanged; but they are nearly
    always the winners already, so the depth pass then finds almost every cell decided and issues almost no
    atomics. This replaces clearing the keys.
    """
    c = wp.tid()
    cell = grid_cell(grid, c)
    for side in range(2):
        base = (2 * c + side) * depth_slots
        kept = SlotKeys()
        for slot in range(depth_slots):
            key = keys[base + slot]
            if key != EMPTY_KEY:
                key = owner_key(grid, particles, cell, side, key_owner(key), criterion)
            # Insertion into the ascending prefix: the owners are distinct, so their keys are too.
            k = slot
            while k > 0:
                if kept[k - 1] <= key:
                    break
                kept[k] = kept[k - 1]
                k -= 1
            kept[k] = key
        for slot in range(depth_slots):
            keys[base + slot] = kept[slot]


@wp.kernel
def lamp_forget(
    # outputs
    keys: wp.array[wp.uint64],
):
    keys[wp.tid()] = EMPTY_KEY


@wp.kernel
def lamp_depth_rows(
    grid: LampGridParams,
    particles: LampParticles,
    criterion: wp.int32,
    lamp_mask: wp.int32,
    # outputs
    keys: wp.array[wp.uint64],
    diag: wp.array[wp.int32],
):
    """v4 of the depth pass (bench/NOTES.md), kept as the benchmark's baseline while issue 11's blocks replace it:
    one thread per sphere offers (depth, id) keys to the low and high lamp of every cell its projected disk covers,
    on the three grids, with atomic_min (one slot per lamp), skipping rows whose stored keys all beat it."""
    particle = wp.tid()
    sphere = frame_sphere(grid, particles, particle)
    if not sphere.casts:
        if not inactive(particles, particle):
            wp.atomic_add(diag, DIAG_INVALID, 1)
        return
    r = sphere.radius
    r2 = r * r
    outside = int(0)
    for a in range(3):
        lamp_bits = (lamp_mask >> (2 * a)) & 3
        if lamp_bits == 0:
            continue
        pu = sphere.center[(a + 1) % 3] - grid.corner_u[a]
        pv = sphere.center[(a + 2) % 3] - grid.corner_v[a]
        pd = sphere.center[a]
        hu = grid.h_u[a]
        hv = grid.h_v[a]
        nu = grid.n_u[a]
        nv = grid.n_v[a]
        if pu - r < 0.0 or pv - r < 0.0 or pu + r > hu * float(nu) or pv + r > hv * float(nv):
            outside = 1
        rows = cell_span(pv - r, pv + r, hv, nv, criterion)
        for j in range(rows[0], rows[1] + 1):
            # The hit test du^2 <= r^2 - dv^2 is monotone in |du| along the row, so the row's hits are one run
            # of cells and the span from w = sqrt(rem) brackets it.
            dv = cell_offset(j, hv, pv, criterion)
            rem = r2 - dv * dv
            if rem < 0.0:
                continue
            w = wp.sqrt(rem)
            cols = cell_span(pu - w, pu + w, hu, nu, criterion)
            row = 2 * (grid.offset[a] + j * nu)
            # Row filter: no depth this sphere offers in the row can beat pd - w (low) or pd + w (high), exactly
            # in float32 (sqrt and subtraction are monotone). Where every stored key already beats that bound,
            # the row is done with loads alone, no sqrt or key packing; ties keep the row alive.
            reach = lamp_reach(rem, 0.0, criterion)
            live = row_live(keys, row, cols[0], cols[1], pack_key(pd - reach, 0), pack_key(-(pd + reach), 0))
            live = live & lamp_bits
            if live == 0:
                continue
            for i in range(cols[0], cols[1] + 1):
                du = cell_offset(i, hu, pu, criterion)
                if du * du <= rem:
                    depth = lamp_reach(rem, du, criterion)
                    slot = row + 2 * i
                    if (live & 1) != 0:
                        offer(keys, slot, pack_key(pd - depth, particle))
                    if (live & 2) != 0:
                        offer(keys, slot + 1, pack_key(-(pd + depth), particle))
    if outside != 0:
        wp.atomic_add(diag, DIAG_OUTSIDE, 1)


@wp.func
def lamp_outside(grid: LampGridParams, sphere: FrameSphere, lamp_mask: wp.int32) -> wp.bool:
    """Whether the sphere's projected disk pokes outside a grid whose lamps are on."""
    r = sphere.radius
    for a in range(3):
        if ((lamp_mask >> (2 * a)) & 3) != 0:
            pu = sphere.center[(a + 1) % 3] - grid.corner_u[a]
            pv = sphere.center[(a + 2) % 3] - grid.corner_v[a]
            if pu - r < 0.0 or pv - r < 0.0:
                return True
            if pu + r > grid.h_u[a] * float(grid.n_u[a]) or pv + r > grid.h_v[a] * float(grid.n_v[a]):
                return True
    return False


@wp.kernel
def lamp_blocks(
    grid: LampGridParams,
    keys: wp.array[wp.uint64],
    depth_slots: wp.int32,
    # outputs
    blocks: wp.array[wp.uint64],
):
    """One thread per 4 x 4 block of cells summarises each lamp's keys after the seed: the largest depth bits of
    its cells' last kept keys (slot D - 1) in the high word, a 16-bit mask of cells whose last slot is empty in the
    low word. Keys only fall during the depth pass, so the summary stays an upper bound: a sphere whose best
    depth over its cells in the block loses to it, and covers no empty cell there, can skip the block."""
    b = wp.tid()
    blk = grid_block(grid, b)
    a = blk[0]
    for side in range(2):
        worst = wp.uint64(0)
        empty = int(0)
        for jj in range(BLOCK):
            j = BLOCK * blk[2] + jj
            for ii in range(BLOCK):
                i = BLOCK * blk[1] + ii
                if i < grid.n_u[a] and j < grid.n_v[a]:
                    c = grid.offset[a] + j * grid.n_u[a] + i
                    k = keys[(2 * c + side) * depth_slots + depth_slots - 1]
                    if k == EMPTY_KEY:
                        empty = empty | (1 << (BLOCK * jj + ii))
                    else:
                        worst = wp.max(worst, k >> wp.uint64(32))
        blocks[2 * b + side] = (worst << wp.uint64(32)) | wp.uint64(empty)


@wp.kernel
def lamp_depth(
    grid: LampGridParams,
    particles: LampParticles,
    criterion: wp.int32,
    lamp_mask: wp.int32,
    split: wp.int32,
    depth_slots: wp.int32,
    blocks: wp.array[wp.uint64],
    # outputs
    keys: wp.array[wp.uint64],
    diag: wp.array[wp.int32],
):
    """The depth pass: every sphere offers (depth, id) keys to the low and high lamp of every cell its projected
    disk covers, on the three grids, with atomic_min, so the order of offers cannot change the result.

    Work goes in 4 x 4 blocks of cells: ``split`` threads share each (sphere, axis) and take its blocks in turn
    (thread t: particle t % n, axis and share from t / n, so a warp holds neighbouring particles). A block's hit
    mask comes from 4 row and 4 column offsets in registers; with ``blocks`` (the summaries of ``lamp_blocks``)
    a hidden sphere leaves a block after one load per lamp instead of one per cell.
    """
    t = wp.tid()
    n = particles.n
    particle = t % n
    share = t / n
    a = share / split
    g = share - a * split
    sphere = frame_sphere(grid, particles, particle)
    if not sphere.casts:
        if share == 0 and not inactive(particles, particle):
            wp.atomic_add(diag, DIAG_INVALID, 1)
        return
    if share == 0 and lamp_outside(grid, sphere, lamp_mask):
        wp.atomic_add(diag, DIAG_OUTSIDE, 1)
    lamp_bits = (lamp_mask >> (2 * a)) & 3
    if lamp_bits == 0:
        return
    r = sphere.radius
    r2 = r * r
    pu = sphere.center[(a + 1) % 3] - grid.corner_u[a]
    pv = sphere.center[(a + 2) % 3] - grid.corner_v[a]
    pd = sphere.center[a]
    hu = grid.h_u[a]
    hv = grid.h_v[a]
    nu = grid.n_u[a]
    rows = cell_span(pv - r, pv + r, hv, grid.n_v[a], criterion)
    cols = cell_span(pu - r, pu + r, hu, nu, criterion)
    if rows[0] > rows[1] or cols[0] > cols[1]:
        return
    bi0 = cols[0] / BLOCK
    bj0 = rows[0] / BLOCK
    nbi = cols[1] / BLOCK - bi0 + 1
    nb = nbi * (rows[1] / BLOCK - bj0 + 1)
    culling = blocks.shape[0] > 0
    for b in range(g, nb, split):
        bj = bj0 + b / nbi
        bi = bi0 + b - (b / nbi) * nbi
        rem = wp.vec4(-1.0)
        du = wp.vec4(0.0)
        du2 = wp.vec4(0.0)
        for k in range(BLOCK):
            j = BLOCK * bj + k
            if j >= rows[0] and j <= rows[1]:
                dv = cell_offset(j, hv, pv, criterion)
                rem[k] = r2 - dv * dv
            i = BLOCK * bi + k
            du[k] = cell_offset(i, hu, pu, criterion)
            du2[k] = du[k] * du[k]
            if i < cols[0] or i > cols[1]:
                du2[k] = 3.0e38
        mask = int(0)
        best = float(-1.0)
        for jj in range(BLOCK):
            for ii in range(BLOCK):
                if rem[jj] >= 0.0 and du2[ii] <= rem[jj]:
                    mask = mask | (1 << (BLOCK * jj + ii))
                    best = wp.max(best, rem[jj] - du2[ii])
        if mask == 0:
            continue
        live = lamp_bits
        if culling:
            # No cell of the block can take a depth below pd - reach (low) or above pd + reach (high): sqrt and
            # subtraction are monotone, and best is the largest rem - du^2 the cells compute themselves.
            reach = lamp_reach(best, 0.0, criterion)
            bidx = grid.block_offset[a] + bj * grid.nb_u[a] + bi
            low = blocks[2 * bidx]
            high = blocks[2 * bidx + 1]
            live = 0
            if (mask & wp.int32(low & LOW_WORD)) != 0 or (low >> wp.uint64(32)) >= (
                pack_key(pd - reach, 0) >> wp.uint64(32)
            ):
                live = 1
            if (mask & wp.int32(high & LOW_WORD)) != 0 or (high >> wp.uint64(32)) >= (
                pack_key(-(pd + reach), 0) >> wp.uint64(32)
            ):
                live = live | 2
            live = live & lamp_bits
            if live == 0:
                continue
        for jj in range(BLOCK):
            for ii in range(BLOCK):
                if (mask & (1 << (BLOCK * jj + ii))) != 0:
                    depth = lamp_reach(rem[jj], du[ii], criterion)
                    c = grid.offset[a] + (BLOCK * bj + jj) * nu + BLOCK * bi + ii
                    if (live & 1) != 0:
                        offer_slots(keys, 2 * c * depth_slots, depth_slots, pack_key(pd - depth, particle))
                    if (live & 2) != 0:
                        offer_slots(keys, (2 * c + 1) * depth_slots, depth_slots, pack_key(-(pd + depth), particle))


@wp.kernel
def lamp_scatter(
    grid: LampGridParams,
    keys: wp.array[wp.uint64],
    # outputs
    counts: wp.array[wp.int32],
):
    """Each lit cell adds +1 to its low owner's count on its axis and -1 to its high owner's: integers, so
    the sum over particles is exactly zero per axis pair and the result does not depend on thread order."""
    c = wp.tid()
    a = grid_cell(grid, c)[0]
    low = keys[2 * c]
    high = keys[2 * c + 1]
    if low != EMPTY_KEY:
        wp.atomic_add(counts, 3 * key_owner(low) + a, 1)
    if high != EMPTY_KEY:
        wp.atomic_add(counts, 3 * key_owner(high) + a, -1)


@wp.func
def veltkamp_round26(x: wp.float64) -> wp.float64:
    """x rounded to 26 significant bits (Veltkamp split), so that x times any count below 2**27 is exact."""
    t = x * wp.float64(134217729.0)
    return t - (t - x)


@wp.kernel
def lamp_add_forces(
    counts: wp.array[wp.int32],
    area: wp.vec3d,
    pressure_const: wp.vec3d,
    pressure_arr: wp.array[wp.float32],
    # outputs
    forces: wp.array[wp.vec3],
):
    """forces[i] += P_a A_a count[i, a]. P_a A_a is rounded to 26 bits so that the float64 product with any
    count is exact: float32 forces are then the correctly rounded values of lamp_forces' float64 forces."""
    i = wp.tid()
    p = pressure_const
    if pressure_arr.shape[0] == 1:
        p = wp.vec3d(wp.float64(pressure_arr[0]))
    elif pressure_arr.shape[0] >= 3:
        p = wp.vec3d(wp.float64(pressure_arr[0]), wp.float64(pressure_arr[1]), wp.float64(pressure_arr[2]))
    f = wp.vec3(0.0)
    for a in range(3):
        pa = veltkamp_round26(p[a] * area[a])
        f[a] = wp.float32(pa * wp.float64(counts[3 * i + a]))
    forces[i] = forces[i] + f
