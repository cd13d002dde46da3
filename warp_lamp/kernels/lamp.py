"""Shining-lamp kernels: seed, depth pass (one thread per sphere), count scatter (one thread per cell), forces.

Each cell holds two keys (``kernels/keys.py``): [2 c] for the low lamp (at minus infinity, shining toward +a) and
[2 c + 1] for the high lamp. Both are resolved with atomic_min: the high lamp keys negated exit depths, so that
one identity (EMPTY_KEY) and one tie rule (lowest index wins) serve both sides. The grid arrives as one
``LampGridParams`` (``kernels/grid.py``).
"""

import warp as wp

from warp_lamp.kernels.footprint import cell_offset, cell_span, lamp_reach
from warp_lamp.kernels.grid import LampGridParams, grid_cell, grid_to_frame
from warp_lamp.kernels.keys import EMPTY_KEY, key_depth, key_owner, pack_key
from warp_lamp.kernels.walls import LampWalls, cell_ray_base, plane_value, ray_fluid, wall_rests

# fuse_fp off: CUDA must not contract a*b+c into an FMA, or its depths and hit tests differ from the CPU's in
# the last bit and CPU and GPU owners stop being bitwise equal.
wp.set_module_options({"enable_backward": False, "fuse_fp": False, "optimization_level": 3})

#: Threads per block of the depth pass: 128 beat 256 by 7-9% on an H200 once the row filter issues its loads
#: in chunks (bench/NOTES.md v4).
DEPTH_BLOCK_DIM = 128

#: Most keys a sample keeps per lamp (``depth_slots``): the first D spheres along its ray.
MAX_SLOTS = 6
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
    p = grid_to_frame(grid, particles.positions[particle])
    r = particles.radii[particle]
    # NaN fails every comparison, so `not (r > 0)` also catches a NaN radius.
    if not (wp.isfinite(p[0]) and wp.isfinite(p[1]) and wp.isfinite(p[2]) and wp.isfinite(r) and r > 0.0):
        return out
    out.center = p
    out.radius = r
    out.casts = True
    return out


@wp.func
def key_slot(c: wp.int32, side: wp.int32, depth_slots: wp.int32) -> wp.int32:
    """Index of the first of the ``depth_slots`` keys that lamp ``side`` (0 low, 1 high) of cell c keeps."""
    return (2 * c + side) * depth_slots


@wp.func
def offer(keys: wp.array[wp.uint64], slot: wp.int32, key: wp.uint64):
    """Keep the smaller key at keys[slot]. Read first: a losing offer costs a load instead of an L2 atomic round
    trip; the atomic's result is not read, so it is a fire-and-forget reduction."""
    if key < keys[slot]:
        wp.atomic_min(keys, slot, key)


@wp.func
def offer_slots(keys: wp.array[wp.uint64], base: wp.int32, depth_slots: wp.int32, key: wp.uint64):
    """Keep the ``depth_slots`` smallest distinct keys offered to keys[base ... base + D - 1], in ascending order.

    Read the last slot first: an offer that cannot enter costs a load. Otherwise a chain of atomic_min: the loser
    of each exchange moves down to the next slot. A slot's value only decreases, so each slot ends as the minimum
    of what was pushed into it, which makes the result the D smallest keys in order, under any interleaving; an
    exchange that finds its own key already there stops, so an offer the seed placed, or a duplicate, is not kept
    twice.
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
def row_live(keys: wp.array[wp.uint64], c0: wp.int32, c1: wp.int32, lo: wp.uint64, hi: wp.uint64) -> wp.int32:
    """Bit 0: some low key of cells c0..c1 is >= lo; bit 1: some high key is >= hi (one key per lamp and cell).

    Four cells per step, all eight loads issued before the first compare: with almost no atomics left, the
    depth pass waits on L2 latency, and a warp that used each load in its own iteration stalled once per cell
    (measured: 26% off the warm depth pass, bench/NOTES.md v4). Indices past c1 re-read c1.
    """
    live = int(0)
    c = c0
    while c <= c1:
        s0 = 2 * c
        s1 = 2 * wp.min(c + 1, c1)
        s2 = 2 * wp.min(c + 2, c1)
        s3 = 2 * wp.min(c + 3, c1)
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
        c += 4
    return live


@wp.func
def row_live_slots(
    keys: wp.array[wp.uint64], c0: wp.int32, c1: wp.int32, depth_slots: wp.int32, lo: wp.uint64, hi: wp.uint64
) -> wp.int32:
    """``row_live`` for cells that keep ``depth_slots`` keys per lamp: tests the last kept key (slot D - 1), which
    an offer must beat to enter. Two cells per step."""
    last = depth_slots - 1
    live = int(0)
    c = c0
    while c <= c1:
        s0 = key_slot(c, 0, depth_slots) + last
        s1 = key_slot(wp.min(c + 1, c1), 0, depth_slots) + last
        l0 = keys[s0]
        h0 = keys[s0 + depth_slots]
        l1 = keys[s1]
        h1 = keys[s1 + depth_slots]
        if wp.max(l0, l1) >= lo:
            live = live | 1
        if wp.max(h0, h1) >= hi:
            live = live | 2
        c += 2
    return live


@wp.func
def owner_key(
    a: wp.int32,
    grid: LampGridParams,
    particles: LampParticles,
    i: wp.int32,
    j: wp.int32,
    side: wp.int32,
    owner: wp.int32,
    criterion: wp.int32,
) -> wp.uint64:
    """The key that particle ``owner`` offers to lamp ``side`` of cell (i, j) of grid a at the current positions,
    or EMPTY_KEY where it no longer lights the cell: the depth pass's own decision, through the same functions.
    Callers pass a literal axis (see ``lamp_depth``)."""
    sphere = frame_sphere(grid, particles, owner)
    if not sphere.casts:
        return EMPTY_KEY
    r = sphere.radius
    dv = cell_offset(j, grid.h_v[a], sphere.center[(a + 2) % 3] - grid.corner_v[a], criterion)
    du = cell_offset(i, grid.h_u[a], sphere.center[(a + 1) % 3] - grid.corner_u[a], criterion)
    rem = r * r - dv * dv
    if rem < 0.0 or du * du > rem:
        return EMPTY_KEY
    reach = lamp_reach(rem, du, criterion)
    if side == 0:
        return pack_key(sphere.center[a] - reach, owner)
    return pack_key(-(sphere.center[a] + reach), owner)


@wp.func
def seed_key(
    grid: LampGridParams, particles: LampParticles, cell: wp.vec3i, side: wp.int32, key: wp.uint64, criterion: wp.int32
) -> wp.uint64:
    """``owner_key`` for a kept key's owner, with the grid's axis dispatched as a literal."""
    if key == EMPTY_KEY:
        return EMPTY_KEY
    owner = key_owner(key)
    out = EMPTY_KEY
    for a in range(3):
        if cell[0] == a:
            out = owner_key(a, grid, particles, cell[1], cell[2], side, owner, criterion)
    return out


@wp.func
def clear_particle_counts(c: wp.int32, n: wp.int32, counts: wp.array[wp.int64], diag: wp.array[wp.int32]):
    """Thread c of a seed launch clears particle c's counts and diagnostic c (the seed replaces two launches)."""
    if c < n:
        counts[3 * c] = wp.int64(0)
        counts[3 * c + 1] = wp.int64(0)
        counts[3 * c + 2] = wp.int64(0)
    if c < diag.shape[0]:
        diag[c] = 0


@wp.kernel
def lamp_seed(
    grid: LampGridParams,
    particles: LampParticles,
    criterion: wp.int32,
    # outputs
    keys: wp.array[wp.uint64],
    counts: wp.array[wp.int64],
    diag: wp.array[wp.int32],
):
    """One thread per cell replaces each lamp's key with its owner's key at the current positions (EMPTY where the
    owner no longer lights the cell).

    The seed is an offer the depth pass makes anyway, so the final result is unchanged; but it is nearly always
    the winner already, so the depth pass then finds almost every cell decided and issues almost no atomics. This
    replaces clearing the keys. Threads past the cells also clear the particles' counts and the diagnostics: one
    launch instead of two.
    """
    c = wp.tid()
    clear_particle_counts(c, particles.n, counts, diag)
    if c >= grid.n_cells:
        return
    cell = grid_cell(grid, c)
    # Unrolled over the axis and written out rather than called, so that the indices stay literals (lamp_depth).
    for a in range(3):
        if cell[0] == a:
            for side in range(2):
                key = keys[2 * c + side]
                if key != EMPTY_KEY:
                    owner = key_owner(key)
                    sphere = frame_sphere(grid, particles, owner)
                    key = EMPTY_KEY
                    if sphere.casts:
                        r = sphere.radius
                        dv = cell_offset(cell[2], grid.h_v[a], sphere.center[(a + 2) % 3] - grid.corner_v[a], criterion)
                        du = cell_offset(cell[1], grid.h_u[a], sphere.center[(a + 1) % 3] - grid.corner_u[a], criterion)
                        rem = r * r - dv * dv
                        if rem >= 0.0 and du * du <= rem:
                            reach = lamp_reach(rem, du, criterion)
                            if side == 0:
                                key = pack_key(sphere.center[a] - reach, owner)
                            else:
                                key = pack_key(-(sphere.center[a] + reach), owner)
                    keys[2 * c + side] = key


@wp.kernel
def lamp_seed_slots(
    grid: LampGridParams,
    particles: LampParticles,
    criterion: wp.int32,
    depth_slots: wp.int32,
    # outputs
    keys: wp.array[wp.uint64],
    counts: wp.array[wp.int64],
    diag: wp.array[wp.int32],
):
    """``lamp_seed`` for samples that keep ``depth_slots`` > 1 keys per lamp: each kept key is re-evaluated, and the
    slots re-sorted (distinct owners give distinct keys; a repeated owner is kept once)."""
    c = wp.tid()
    clear_particle_counts(c, particles.n, counts, diag)
    if c >= grid.n_cells:
        return
    cell = grid_cell(grid, c)
    for side in range(2):
        base = key_slot(c, side, depth_slots)
        kept = SlotKeys()
        for slot in range(depth_slots):
            key = seed_key(grid, particles, cell, side, keys[base + slot], criterion)
            # An owner kept twice (only in slots the lamp did not write, e.g. cleared to zero) would be kept twice
            # again by the offers, which stop at an equal key: keep it once.
            for k in range(slot):
                if kept[k] == key:
                    key = EMPTY_KEY
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
def lamp_order_keys(
    grid: LampGridParams,
    particles: LampParticles,
    a: wp.int32,
    # outputs
    cell_keys: wp.array[wp.int32],
    ids: wp.array[wp.int32],
):
    """Sort keys for the depth pass's work order on grid a: the cell under each particle's centre (clamped to the
    grid), so that a warp's particles read the same rows; particles that cast no light go last."""
    p = wp.tid()
    ids[p] = p
    cell_keys[p] = grid.n_cells
    sphere = frame_sphere(grid, particles, p)
    if sphere.casts:
        u = (sphere.center[(a + 1) % 3] - grid.corner_u[a]) / grid.h_u[a]
        v = (sphere.center[(a + 2) % 3] - grid.corner_v[a]) / grid.h_v[a]
        i = wp.int32(wp.clamp(wp.floor(u), 0.0, float(grid.n_u[a] - 1)))
        j = wp.int32(wp.clamp(wp.floor(v), 0.0, float(grid.n_v[a] - 1)))
        cell_keys[p] = grid.offset[a] + j * grid.n_u[a] + i


def _depth_kernel(slots: int, shared: bool):
    """The depth pass, compiled for one key per lamp and cell (``slots`` 1: the criteria's lamps) or generic in
    ``depth_slots`` (``slots`` 0: the samples of the area estimator), and for one thread per sphere (``shared``
    False) or ``split`` threads per (sphere, axis). Each specialisation drops code that the others need: the GPU
    measured every unused branch in registers (bench/NOTES.md v5)."""

    @wp.kernel
    def lamp_depth(
        grid: LampGridParams,
        particles: LampParticles,
        criterion: wp.int32,
        lamp_mask: wp.int32,
        split: wp.int32,
        depth_slots: wp.int32,
        order: wp.array[wp.int32],
        hidden: wp.array[wp.int32],
        # outputs
        keys: wp.array[wp.uint64],
        diag: wp.array[wp.int32],
    ):
        """The depth pass: every sphere offers (depth, id) keys to the low and high lamp of every cell its projected
        disk covers, on the three grids, with atomic_min, so the order of offers cannot change the result.

        ``split`` 0: one thread per sphere walks the three axes (the v4 pass of bench/NOTES.md). ``split`` s >= 1:
        s threads share each (sphere, axis) and take its rows in turn; thread t works on the (t % n)-th particle of
        axis a's ``order`` (``lamp_order_keys``, sorted), or of the caller's order where ``order`` is empty, so that a
        warp holds particles that read the same rows.

        ``hidden`` (D slots only; empty: none): per particle, bit 2 a + side set where that lamp can never see it
        (``kernels/area.py`` ``area_hidden``): it offers nothing there, so its slots go to the next spheres.
        """
        t = wp.tid()
        n = particles.n
        share = int(0)
        axis = int(-1)
        first_row = int(0)
        row_step = int(1)
        particle = t
        if wp.static(shared):
            share = t / n
            particle = t - share * n
            axis = share / split
            first_row = share - axis * split
            row_step = split
            if order.shape[0] > 0:
                particle = order[axis * n + particle]
        sphere = frame_sphere(grid, particles, particle)
        if not sphere.casts:
            if share == 0 and not inactive(particles, particle):
                wp.atomic_add(diag, DIAG_INVALID, 1)
            return
        if share == 0 and lamp_outside(grid, sphere, lamp_mask):
            wp.atomic_add(diag, DIAG_OUTSIDE, 1)
        r = sphere.radius
        r2 = r * r
        skip = int(0)
        if wp.static(slots == 0):
            if hidden.shape[0] > 0:
                skip = hidden[particle]
        # A loop of constant length that Warp unrolls: every vector index below is then a literal, which the compiler
        # keeps in registers. With the axis as a runtime value they went to local memory and the pass took three
        # times as long (bench/NOTES.md v5).
        for a in range(3):
            lamp_bits = ((lamp_mask & ~skip) >> (2 * a)) & 3
            if (axis < 0 or axis == a) and lamp_bits != 0:
                pu = sphere.center[(a + 1) % 3] - grid.corner_u[a]
                pv = sphere.center[(a + 2) % 3] - grid.corner_v[a]
                pd = sphere.center[a]
                hu = grid.h_u[a]
                hv = grid.h_v[a]
                nu = grid.n_u[a]
                rows = cell_span(pv - r, pv + r, hv, grid.n_v[a], criterion)
                for j in range(rows[0] + first_row, rows[1] + 1, row_step):
                    # The hit test du^2 <= r^2 - dv^2 is monotone in |du| along the row, so the row's hits are one
                    # run of cells and the span from w = sqrt(rem) brackets it.
                    dv = cell_offset(j, hv, pv, criterion)
                    rem = r2 - dv * dv
                    if rem < 0.0:
                        continue
                    w = wp.sqrt(rem)
                    cols = cell_span(pu - w, pu + w, hu, nu, criterion)
                    first = grid.offset[a] + j * nu
                    # Row filter: no depth this sphere offers in the row can beat pd - w (low) or pd + w (high),
                    # exactly in float32 (sqrt and subtraction are monotone). Where every kept key already beats that
                    # bound, the row is done with loads alone, no sqrt or key packing; ties keep the row alive.
                    reach = lamp_reach(rem, 0.0, criterion)
                    low_bound = pack_key(pd - reach, 0)
                    high_bound = pack_key(-(pd + reach), 0)
                    live = int(0)
                    if wp.static(slots == 1):
                        live = row_live(keys, first + cols[0], first + cols[1], low_bound, high_bound)
                    else:
                        live = row_live_slots(
                            keys, first + cols[0], first + cols[1], depth_slots, low_bound, high_bound
                        )
                    live = live & lamp_bits
                    if live == 0:
                        continue
                    for i in range(cols[0], cols[1] + 1):
                        du = cell_offset(i, hu, pu, criterion)
                        if du * du <= rem:
                            depth = lamp_reach(rem, du, criterion)
                            c = first + i
                            low = pack_key(pd - depth, particle)
                            high = pack_key(-(pd + depth), particle)
                            if wp.static(slots == 1):
                                if (live & 1) != 0:
                                    offer(keys, 2 * c, low)
                                if (live & 2) != 0:
                                    offer(keys, 2 * c + 1, high)
                            else:
                                if (live & 1) != 0:
                                    offer_slots(keys, key_slot(c, 0, depth_slots), depth_slots, low)
                                if (live & 2) != 0:
                                    offer_slots(keys, key_slot(c, 1, depth_slots), depth_slots, high)

    return lamp_depth


lamp_depth_sphere = _depth_kernel(1, False)
lamp_depth = _depth_kernel(1, True)
lamp_depth_slots = _depth_kernel(0, True)


@wp.kernel
def lamp_scatter(
    grid: LampGridParams,
    keys: wp.array[wp.uint64],
    # outputs
    counts: wp.array[wp.int64],
):
    """Each lit cell adds +1 to its low owner's count on its axis and -1 to its high owner's: integers, so
    the sum over particles is exactly zero per axis pair and the result does not depend on thread order."""
    c = wp.tid()
    a = grid_cell(grid, c)[0]
    low = keys[2 * c]
    high = keys[2 * c + 1]
    if low != EMPTY_KEY:
        wp.atomic_add(counts, 3 * key_owner(low) + a, wp.int64(1))
    if high != EMPTY_KEY:
        wp.atomic_add(counts, 3 * key_owner(high) + a, wp.int64(-1))


@wp.func
def walled_loads(
    grid: LampGridParams, keys: wp.array[wp.uint64], walls: LampWalls, c: wp.int32, side: wp.int32, lamp_mask: wp.int32
) -> wp.vec2i:
    """Who lamp ``side`` of cell c loads when walls bound the fluid: (target, recoil). The target takes the lamp's
    count (+1 low, -1 high): a particle (>= 0), wall w (-2 - w) or nobody (-1); the recoil is the wall (>= 0, or
    -1) at the lamp's end of the fluid, which takes the opposite count.

    The ray's fluid is (lo, hi) (``ray_fluid``); its body the span [E, X] of the low and high keys (first entry, last
    exit; centres for criterion 0). Where the span meets the fluid, the low lamp's fluid (lo, E) pushes the first
    sphere (+1) and the wall at lo (-1) unless that end is sealed: E <= lo (the wall crosses the body) or the body
    rests on that wall (``wall_rests``). The high end likewise. A ray whose fluid holds no body is one column of
    fluid between its walls: the low lamp gives its +1 to the wall at hi, the high lamp its -1 to the wall at lo.
    Off lamps (``lamp_mask``) load nothing; the depth pass keeps both keys of an axis that has a lamp on."""
    out = wp.vec2i(-1, -1)
    cell = grid_cell(grid, c)
    a = cell[0]
    if ((lamp_mask >> (2 * a + side)) & 1) == 0:
        return out
    fl = ray_fluid(walls, a, cell_ray_base(grid, a, cell[1], cell[2]))
    if not fl.wet:
        return out
    low = keys[2 * c]
    high = keys[2 * c + 1]
    body = low != EMPTY_KEY and high != EMPTY_KEY
    if body:
        e = wp.float64(key_depth(low))
        x = -wp.float64(key_depth(high))
        if fl.lo_wall >= 0 and x <= fl.lo:
            body = False
        if fl.hi_wall >= 0 and e >= fl.hi:
            body = False
        if body:
            if side == 0:
                if fl.lo_wall >= 0:
                    if e <= fl.lo or wall_rests(walls, fl.lo_wall):
                        return out
                out[0] = key_owner(low)
                out[1] = fl.lo_wall
            else:
                if fl.hi_wall >= 0:
                    if x >= fl.hi or wall_rests(walls, fl.hi_wall):
                        return out
                out[0] = key_owner(high)
                out[1] = fl.hi_wall
            return out
    if side == 0:
        if fl.hi_wall >= 0:
            out[0] = -2 - fl.hi_wall
    else:
        if fl.lo_wall >= 0:
            out[0] = -2 - fl.lo_wall
    return out


@wp.kernel
def lamp_scatter_walls(
    grid: LampGridParams,
    keys: wp.array[wp.uint64],
    walls: LampWalls,
    lamp_mask: wp.int32,
    # outputs
    counts: wp.array[wp.int64],
    wall_counts: wp.array[wp.int64],
):
    """``lamp_scatter`` with walls that bound the fluid (``walled_loads``): a wall counts like a particle (3 counts
    per wall), as a lamp's target or as the recoil at the lamp's end of the fluid."""
    c = wp.tid()
    a = grid_cell(grid, c)[0]
    for side in range(2):
        who = walled_loads(grid, keys, walls, c, side, lamp_mask)
        sign = wp.int64(1 - 2 * side)
        if who[0] >= 0:
            wp.atomic_add(counts, 3 * who[0] + a, sign)
        elif who[0] <= -2:
            wp.atomic_add(wall_counts, 3 * (-2 - who[0]) + a, sign)
        if who[1] >= 0:
            wp.atomic_add(wall_counts, 3 * who[1] + a, -sign)


@wp.kernel
def lamp_walled_owners(
    grid: LampGridParams,
    keys: wp.array[wp.uint64],
    walls: LampWalls,
    lamp_mask: wp.int32,
    # outputs
    owners: wp.array[wp.int32],
    recoils: wp.array[wp.int32],
):
    """Diagnostics: the target and the recoil wall of both lamps of every cell (``walled_loads``; two per cell, as
    the keys)."""
    c = wp.tid()
    for side in range(2):
        who = walled_loads(grid, keys, walls, c, side, lamp_mask)
        owners[2 * c + side] = who[0]
        recoils[2 * c + side] = who[1]


@wp.kernel
def walls_contact(
    grid: LampGridParams,
    particles: LampParticles,
    walls: LampWalls,
    # outputs
    gap: wp.array[wp.float32],
):
    """Per wall, the smallest gap (n . c - d - r) / r over the particles that cast light, by atomic min (the walls'
    placement reset it): whether the body rests on the wall, is clear of it or is cut by it (``wall_rests``)."""
    i = wp.tid()
    sphere = frame_sphere(grid, particles, i)
    if not sphere.casts:
        return
    c = wp.vec3d(wp.float64(sphere.center[0]), wp.float64(sphere.center[1]), wp.float64(sphere.center[2]))
    r = wp.float64(sphere.radius)
    for w in range(walls.n):
        wp.atomic_min(gap, w, wp.float32((plane_value(walls.frame[w], c) - r) / r))


@wp.func
def quantum26(x: wp.float64) -> wp.float64:
    """The spacing 2^(e - 25) of the 26-significant-bit numbers around x (2^e <= |x| < 2^(e+1)); 0 for x = 0 or
    a subnormal x, where no rounding is done."""
    bits = wp.cast(wp.abs(x), wp.uint64)
    e = wp.int64(bits >> wp.uint64(52))
    if e <= wp.int64(25):
        return wp.float64(0.0)
    return wp.cast(wp.uint64(e - wp.int64(25)) << wp.uint64(52), wp.float64)


@wp.func
def round_to(x: wp.float64, q: wp.float64) -> wp.float64:
    """x rounded to the nearest multiple of the power of two q (ties to even): (x + 1.5 2^52 q) - 1.5 2^52 q."""
    if q == wp.float64(0.0):
        return x
    m = wp.float64(6755399441055744.0) * q
    return (x + m) - m


@wp.func
def force_factors(p: wp.vec3d, area: wp.vec3d, rotation: wp.mat33) -> wp.mat33d:
    """F[j, a]: the world force component j per unit count on axis a, P_a A_a R[j, a], each row rounded to the
    26-bit spacing of its largest entry: every entry of a row is then a multiple of one power of two, so a sum of
    count times F over particles is exact in float64 and the forces balance exactly in world coordinates. With
    the identity this is P_a A_a rounded to 26 bits, as ``warp_lamp.lamp.pressure_area``; ``area`` is the cell
    area over the units per cell and the number of frames averaged."""
    f = wp.mat33d()
    for j in range(3):
        big = wp.float64(0.0)
        for a in range(3):
            x = (p[a] * area[a]) * wp.float64(rotation[j, a])
            f[j, a] = x
            big = wp.max(big, wp.abs(x))
        q = quantum26(big)
        for a in range(3):
            f[j, a] = round_to(f[j, a], q)
    return f


@wp.kernel
def lamp_add_forces(
    counts: wp.array[wp.int64],
    area: wp.vec3d,
    rotation: wp.array[wp.mat33],
    pressure_const: wp.vec3d,
    pressure_arr: wp.array[wp.float32],
    # outputs
    forces: wp.array[wp.vec3],
):
    """forces[i] += sum_a F[:, a] count[i, a] (``force_factors``), in world coordinates: the float32 forces are the
    correctly rounded values of lamp_forces' float64 forces (with float32 R in place of float64 R)."""
    i = wp.tid()
    p = pressure_const
    if pressure_arr.shape[0] == 1:
        p = wp.vec3d(wp.float64(pressure_arr[0]))
    elif pressure_arr.shape[0] >= 3:
        p = wp.vec3d(wp.float64(pressure_arr[0]), wp.float64(pressure_arr[1]), wp.float64(pressure_arr[2]))
    f = force_factors(p, area, rotation[0])
    c0 = wp.float64(counts[3 * i])
    c1 = wp.float64(counts[3 * i + 1])
    c2 = wp.float64(counts[3 * i + 2])
    out = wp.vec3(0.0)
    for j in range(3):
        out[j] = wp.float32((f[j, 0] * c0 + f[j, 1] * c1) + f[j, 2] * c2)
    forces[i] = forces[i] + out


@wp.kernel
def lamp_follow_bounds(
    particles: LampParticles,
    base: wp.vec3,
    rotation: wp.array[wp.mat33],
    # outputs
    bounds: wp.array[wp.float32],
):
    """The body's box in the base frame, R^T (x - base) -+ r, by atomic min and max over the particles that cast
    light (the shift kernel leaves ``bounds`` reset for the next update)."""
    i = wp.tid()
    x = particles.positions[i]
    r = particles.radii[i]
    if inactive(particles, i):
        return
    if not (wp.isfinite(x[0]) and wp.isfinite(x[1]) and wp.isfinite(x[2]) and wp.isfinite(r) and r > 0.0):
        return
    q = x - base
    m = rotation[0]
    p = wp.vec3(
        m[0, 0] * q[0] + m[1, 0] * q[1] + m[2, 0] * q[2],
        m[0, 1] * q[0] + m[1, 1] * q[1] + m[2, 1] * q[2],
        m[0, 2] * q[0] + m[1, 2] * q[1] + m[2, 2] * q[2],
    )
    for d in range(3):
        wp.atomic_min(bounds, d, p[d] - r)
        wp.atomic_max(bounds, 3 + d, p[d] + r)


@wp.kernel
def lamp_follow_shift(
    base_world: wp.vec3d,
    cell: wp.vec3d,
    capacity: wp.vec3i,
    rotation: wp.array[wp.mat33],
    # outputs
    bounds: wp.array[wp.float32],
    shift: wp.array[wp.vec3i],
    origin: wp.array[wp.vec3],
):
    """One thread moves the grid by whole cells so that the body's box sits centred in the capacity box: shift k
    (cells per frame axis) and the frame origin base + R (k h) in world coordinates, in float64 before the cast.
    Whole cells keep the result a pure function of the positions. Keeps the last shift when no particle counted
    (an empty body), and resets the bounds for the next update."""
    k = shift[0]
    if bounds[0] <= bounds[3]:
        for d in range(3):
            centre = wp.float64(0.5) * (wp.float64(bounds[d]) + wp.float64(bounds[3 + d]))
            k[d] = wp.int32(wp.floor(centre / cell[d] - wp.float64(0.5) * wp.float64(capacity[d]) + wp.float64(0.5)))
    shift[0] = k
    m = rotation[0]
    step = wp.vec3d(wp.float64(k[0]) * cell[0], wp.float64(k[1]) * cell[1], wp.float64(k[2]) * cell[2])
    o = wp.vec3(0.0)
    for d in range(3):
        w = (wp.float64(m[d, 0]) * step[0] + wp.float64(m[d, 1]) * step[1]) + wp.float64(m[d, 2]) * step[2]
        o[d] = wp.float32(base_world[d] + w)
    origin[0] = o
    for d in range(3):
        bounds[d] = 3.0e38
        bounds[3 + d] = -3.0e38


@wp.kernel
def lamp_to_frame(
    grid: LampGridParams,
    particles: LampParticles,
    # outputs
    frame: wp.array[wp.vec3],
):
    """Particles' frame coordinates, for the modes that work on them directly (the wetted surface)."""
    i = wp.tid()
    frame[i] = grid_to_frame(grid, particles.positions[i])


@wp.func
def wall_in_frame(p: wp.vec4, o: wp.vec3d, r: wp.mat33) -> wp.vec4:
    """Plane (n, d) in world coordinates moved into the frame (origin o, rotation r), in float64 then float32."""
    nf = wp.vec3(0.0)
    for k in range(3):
        nf[k] = wp.float32(
            (wp.float64(r[0, k]) * wp.float64(p[0]) + wp.float64(r[1, k]) * wp.float64(p[1]))
            + wp.float64(r[2, k]) * wp.float64(p[2])
        )
    dot = (wp.float64(p[0]) * o[0] + wp.float64(p[1]) * o[1]) + wp.float64(p[2]) * o[2]
    return wp.vec4(nf[0], nf[1], nf[2], wp.float32(wp.float64(p[3]) - dot))


@wp.kernel
def walls_to_frame(
    origin: wp.array[wp.vec3],
    rotation: wp.array[wp.mat33],
    world: wp.array[wp.vec4],
    # outputs
    frame: wp.array[wp.vec4],
    gap: wp.array[wp.float32],
):
    """Each wall in the frame of the current pose: n_f = R^T n, d_f = d - n . o (float64, then float32), so that a
    simulator that moves the frame (or the walls) between replays moves the planes too; resets the wall's gap for
    ``walls_contact``."""
    w = wp.tid()
    o = origin[0]
    frame[w] = wall_in_frame(world[w], wp.vec3d(wp.float64(o[0]), wp.float64(o[1]), wp.float64(o[2])), rotation[0])
    gap[w] = 3.0e38


@wp.kernel
def walls_to_grid_frame(
    origin: wp.vec3d,
    rotation: wp.mat33d,
    world: wp.array[wp.vec4],
    given: wp.array[wp.vec4d],
    # outputs
    frame: wp.array[wp.vec4],
    gap: wp.array[wp.float32],
):
    """``walls_to_frame`` for positions the caller moved into the grid's frame in float64 (grid origin and rotation
    in float64): a wall still as given (``world`` the float32 rounding of ``given``) is moved from its float64
    plane, so that a wall far from the world origin keeps the positions' precision; a wall the caller rewrote
    in ``world`` is moved from there."""
    w = wp.tid()
    p = world[w]
    q = given[w]
    same = True
    for k in range(4):
        if wp.float32(q[k]) != p[k]:
            same = False
    if same:
        nf = wp.vec3(0.0)
        for k in range(3):
            nf[k] = wp.float32((rotation[0, k] * q[0] + rotation[1, k] * q[1]) + rotation[2, k] * q[2])
        dot = (q[0] * origin[0] + q[1] * origin[1]) + q[2] * origin[2]
        frame[w] = wp.vec4(nf[0], nf[1], nf[2], wp.float32(q[3] - dot))
    else:
        r = wp.mat33()
        for i in range(3):
            for j in range(3):
                r[i, j] = wp.float32(rotation[i, j])
        frame[w] = wall_in_frame(p, origin, r)
    gap[w] = 3.0e38
