"""Kernels of the distributed lamp and porosity (``warp_lamp.distributed``): keys between local and global ids, the
scatter of reduced keys to a rank's own particles, the merge of the area criterion's depth slots, and fixed-point
porosity sums.

A rank runs the lamp's own depth pass (``kernels/lamp.py``) on its particles sorted by global id, so that the local
index order is the global id order and "ties to the lowest index" means the same on every rank and on one device
holding all particles. Its keys are then rewritten with global ids in the low 32 bits (``dist_keys_to_global``),
combined across ranks by an all-reduce MIN, and each rank scatters counts for the cells whose reduced key is one of
its own keys (``dist_scatter``): equal keys mean equal (depth, global id), so no map from global ids back to local
indices is needed.

With a reach (``ReachWindow``), a rank seeds and scatters only the cells its particles can reach (one rectangle of
cells per grid, agreed at setup with a margin), and offers to the reduction only the cells that two or more ranks'
rectangles share (``dist_pack``, through a list of those cells): a cell only one rank can reach has that rank's
key as its reduced key. ``dist_seed_window`` counts the particles whose footprint leaves the rectangle, after which
the reach must be agreed again.

``flip`` (1) xors the top bit of every key before and after the reduction: for collectives that reduce int64 but
not uint64 (torch.distributed), it turns unsigned key order into signed order, and maps EMPTY_KEY to INT64_MAX,
still the identity of MIN.
"""

import warp as wp

from warp_lamp.kernels.footprint import RAY_OVERLAP, cell_span
from warp_lamp.kernels.grid import LampGridParams, grid_cell, grid_to_frame
from warp_lamp.kernels.keys import EMPTY_KEY, key_owner
from warp_lamp.kernels.lamp import (
    LampParticles,
    clear_particle_counts,
    frame_sphere,
    inactive,
    seed_key,
    walled_loads,
)
from warp_lamp.kernels.porosity import PI, box_cell_volume
from warp_lamp.kernels.walls import LampWalls

wp.set_module_options({"enable_backward": False, "fuse_fp": False})

TOP_BIT = wp.constant(wp.uint64(0x8000000000000000))
HIGH_WORD = wp.constant(wp.uint64(0xFFFFFFFF00000000))

#: Slots of ``dist_check_ids``' statistics.
IDS_NEGATIVE = wp.constant(0)
IDS_REPEATED = wp.constant(1)
IDS_MOVED = wp.constant(2)
IDS_MAX = wp.constant(3)
N_IDS_STATS = 4

#: Porosity per-cell volume of ``porosity_box_fixed`` (as ``kernels/porosity.py``'s BOX_EXACT / BOX_CUBE).
FIXED_EXACT = wp.constant(0)
FIXED_CUBE = wp.constant(1)
FIXED_CENTROID = wp.constant(2)


@wp.func
def global_key(key: wp.uint64, gids: wp.array[wp.int32]) -> wp.uint64:
    """A key whose low word is a local index, with the low word replaced by that particle's global id."""
    if key == EMPTY_KEY:
        return EMPTY_KEY
    return (key & HIGH_WORD) | wp.uint64(wp.uint32(gids[key_owner(key)]))


@wp.func
def flipped(key: wp.uint64, flip: wp.int32) -> wp.uint64:
    if flip != 0:
        return key ^ TOP_BIT
    return key


@wp.kernel
def dist_iota(
    ids: wp.array[wp.int32],
    n: wp.int32,
    # outputs
    sort_keys: wp.array[wp.int32],
    sort_values: wp.array[wp.int32],
):
    """Radix-sort input: the caller's ids as keys, their positions 0 .. n - 1 as values."""
    i = wp.tid()
    if i < n:
        sort_keys[i] = ids[i]
        sort_values[i] = i


@wp.kernel
def dist_check_ids(
    sorted_ids: wp.array[wp.int32],
    perm: wp.array[wp.int32],
    # outputs
    stats: wp.array[wp.int32],
):
    """Over ids sorted ascending (with their caller positions ``perm``): how many are negative, how many repeat
    the previous one, how many moved (the caller's order was not ascending), and the largest."""
    i = wp.tid()
    g = sorted_ids[i]
    if g < 0:
        wp.atomic_add(stats, IDS_NEGATIVE, 1)
    if i > 0:
        if sorted_ids[i - 1] == g:
            wp.atomic_add(stats, IDS_REPEATED, 1)
    if perm[i] != i:
        wp.atomic_add(stats, IDS_MOVED, 1)
    wp.atomic_max(stats, IDS_MAX, g)


@wp.kernel
def dist_gather_particles(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    active: wp.array[wp.int32],
    perm: wp.array[wp.int32],
    # outputs
    out_positions: wp.array[wp.vec3],
    out_radii: wp.array[wp.float32],
    out_active: wp.array[wp.int32],
):
    """The caller's particles in global-id order: row i is the caller's row perm[i] (the same float32 bits)."""
    i = wp.tid()
    p = perm[i]
    out_positions[i] = positions[p]
    out_radii[i] = radii[p]
    if active.shape[0] > 0:
        out_active[i] = active[p]


@wp.kernel
def dist_keys_to_global(
    keys: wp.array[wp.uint64],
    gids: wp.array[wp.int32],
    flip: wp.int32,
    # outputs
    out: wp.array[wp.uint64],
):
    """out = the keys with global ids (top bit flipped where ``flip``): what the rank offers to the reduction."""
    t = wp.tid()
    out[t] = flipped(global_key(keys[t], gids), flip)


@wp.kernel
def dist_scatter(
    grid: LampGridParams,
    keys: wp.array[wp.uint64],
    gids: wp.array[wp.int32],
    caller: wp.array[wp.int32],
    flip: wp.int32,
    reduced: wp.array[wp.uint64],
    # outputs
    counts: wp.array[wp.int64],
):
    """``lamp_scatter`` on the reduced keys, for the rank's own particles: where a cell's reduced key equals the
    rank's own key (in global ids), its owner is the rank's particle key_owner(own key), whose caller row is
    caller[that] (the identity where ``caller`` is empty); +1 for the low lamp, -1 for the high lamp."""
    c = wp.tid()
    a = grid_cell(grid, c)[0]
    for side in range(2):
        g = flipped(reduced[2 * c + side], flip)
        if g != EMPTY_KEY:
            mine = keys[2 * c + side]
            if global_key(mine, gids) == g:
                i = key_owner(mine)
                if caller.shape[0] > 0:
                    i = caller[i]
                if side == 0:
                    wp.atomic_add(counts, 3 * i + a, wp.int64(1))
                else:
                    wp.atomic_add(counts, 3 * i + a, wp.int64(-1))


@wp.kernel
def dist_unflip(
    # outputs
    keys: wp.array[wp.uint64],
):
    """Undo the top-bit flip in place after a reduction as int64, so that the reduced keys read as the lamp's own."""
    t = wp.tid()
    keys[t] = keys[t] ^ TOP_BIT


@wp.kernel
def dist_scatter_walls(
    grid: LampGridParams,
    keys: wp.array[wp.uint64],
    gids: wp.array[wp.int32],
    caller: wp.array[wp.int32],
    reduced: wp.array[wp.uint64],
    walls: LampWalls,
    lamp_mask: wp.int32,
    # outputs
    counts: wp.array[wp.int64],
    wall_counts: wp.array[wp.int64],
):
    """``lamp_scatter_walls`` on the reduced keys (global ids, not flipped): ``walled_loads`` decides each ray from
    the reduced keys and the reduced wall gaps, the same on every rank; a particle's +1 / -1 goes to the rank whose
    own key is the reduced key (as ``dist_scatter``), a wall's to every rank's wall counts (each rank holds the
    whole grid's)."""
    c = wp.tid()
    a = grid_cell(grid, c)[0]
    for side in range(2):
        who = walled_loads(grid, reduced, walls, c, side, lamp_mask)
        sign = wp.int64(1 - 2 * side)
        if who[0] >= 0:
            mine = keys[2 * c + side]
            if global_key(mine, gids) == reduced[2 * c + side]:
                i = key_owner(mine)
                if caller.shape[0] > 0:
                    i = caller[i]
                wp.atomic_add(counts, 3 * i + a, sign)
        elif who[0] <= -2:
            wp.atomic_add(wall_counts, 3 * (-2 - who[0]) + a, sign)
        if who[1] >= 0:
            wp.atomic_add(wall_counts, 3 * who[1] + a, -sign)


@wp.kernel
def dist_merge_offer(
    local: wp.array[wp.uint64],
    merged: wp.array[wp.uint64],
    depth_slots: wp.int32,
    k: wp.int32,
    flip: wp.int32,
    # outputs
    offer: wp.array[wp.uint64],
):
    """Round k of the merge of the area criterion's D-slot lists, one thread per (sample, lamp): the smallest of
    the rank's own keys (global ids, ascending in slots) above the merged key of slot k - 1 (all of them for
    k = 0); EMPTY_KEY when there is none or the merged list ended. The MIN over ranks is the merged key of slot k:
    a rank holding the k-th smallest key of the union has at most k keys below it, so it kept it among its D."""
    t = wp.tid()
    base = t * depth_slots
    out = EMPTY_KEY
    if k == 0:
        out = local[base]
    else:
        prev = merged[base + k - 1]
        if prev != EMPTY_KEY:
            for slot in range(depth_slots):
                key = local[base + slot]
                if key > prev and key < out:
                    out = key
    offer[t] = flipped(out, flip)


@wp.kernel
def dist_merge_take(
    offer: wp.array[wp.uint64],
    depth_slots: wp.int32,
    k: wp.int32,
    flip: wp.int32,
    # outputs
    merged: wp.array[wp.uint64],
):
    """Store round k's reduced keys as slot k of the merged lists."""
    t = wp.tid()
    merged[t * depth_slots + k] = flipped(offer[t], flip)


@wp.kernel
def dist_table_fill(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    gids: wp.array[wp.int32],
    # outputs
    table_positions: wp.array[wp.vec3],
    table_radii: wp.array[wp.float32],
):
    """Write the rank's particles into a zeroed table indexed by global id (the area criterion's geometry, summed
    across ranks as integer bit patterns: x + 0 is x exactly)."""
    i = wp.tid()
    g = gids[i]
    table_positions[g] = positions[i]
    table_radii[g] = radii[i]


@wp.kernel
def dist_counts_gather(
    table_counts: wp.array[wp.int64],
    gids: wp.array[wp.int32],
    caller: wp.array[wp.int32],
    # outputs
    counts: wp.array[wp.int64],
):
    """The rank's counts from the table of all particles' counts (indexed by global id), in the caller's rows."""
    i = wp.tid()
    row = i
    if caller.shape[0] > 0:
        row = caller[i]
    g = gids[i]
    for a in range(3):
        counts[3 * row + a] = table_counts[3 * g + a]


@wp.kernel
def dist_negate_upper(
    # outputs
    bounds: wp.array[wp.float32],
):
    """bounds[3:6] = -bounds[3:6]: the follow grid's box maxima become minima, so one MIN reduces all six."""
    d = wp.tid()
    bounds[3 + d] = -bounds[3 + d]


@wp.kernel
def dist_or_gathered(
    gathered: wp.array[wp.uint32],
    ranks: wp.int32,
    # outputs
    bits: wp.array[wp.uint32],
):
    """bits[w] = OR over ranks of gathered[r * len(bits) + w]: a bitwise OR for collectives without one (NCCL)."""
    w = wp.tid()
    n = bits.shape[0]
    word = wp.uint32(0)
    for r in range(ranks):
        word = word | gathered[r * n + w]
    bits[w] = word


@wp.func
def add_units(
    solid: wp.array3d[wp.int64], cell: wp.vec3i, v: wp.float64, scale: wp.float64, overflow: wp.array[wp.int32]
):
    """Add v [m^3] to a cell as round(v scale) fixed-point units: an integer sum, the same in every order and every
    split of the spheres. An add that would pass 2^63 (or a single volume of 2^63 units) is counted in
    ``overflow`` and left out."""
    u = wp.floor(v * scale + wp.float64(0.5))
    if not (u < wp.float64(9.2e18)):
        wp.atomic_add(overflow, 0, 1)
        return
    units = wp.int64(u)
    if units > wp.int64(0):
        old = wp.atomic_add(solid, cell[0], cell[1], cell[2], units)
        if old > wp.int64(9223372036854775807) - units:
            wp.atomic_add(overflow, 0, 1)


@wp.kernel
def porosity_fixed(
    centers: wp.array[wp.vec3d],
    radii: wp.array[wp.float64],
    h: wp.vec3d,
    shape: wp.vec3i,
    method: wp.int32,
    scale: wp.float64,
    # outputs
    solid: wp.array3d[wp.int64],
    overflow: wp.array[wp.int32],
):
    """The sum methods of ``kernels/porosity.py`` (``porosity_centroid``, ``porosity_box``), each sphere-cell volume
    computed by the same expressions, then added as int64 units of 1/scale m^3 (``add_units``) instead of float64:
    the float sum's result depends on the order of the adds, the integer sum's does not."""
    s = wp.tid()
    c = centers[s]
    r = radii[s]
    if method == FIXED_CENTROID:
        idx = wp.vec3i(0)
        for d in range(3):
            f = wp.floor(c[d] / h[d])
            if f < wp.float64(0.0) or f >= wp.float64(shape[d]):
                return
            idx[d] = wp.int32(f)
        add_units(solid, idx, wp.float64(4.0) / wp.float64(3.0) * PI * r * r * r, scale, overflow)
        return
    xs = cell_span(c[0] - r, c[0] + r, h[0], shape[0], RAY_OVERLAP)
    ys = cell_span(c[1] - r, c[1] + r, h[1], shape[1], RAY_OVERLAP)
    zs = cell_span(c[2] - r, c[2] + r, h[2], shape[2], RAY_OVERLAP)
    zero = wp.float64(0.0)
    for i in range(xs[0], xs[1] + 1):
        for j in range(ys[0], ys[1] + 1):
            for k in range(zs[0], zs[1] + 1):
                cell = wp.vec3i(i, j, k)
                v = box_cell_volume(c, r, cell, h, method == FIXED_EXACT)
                if v > zero:
                    add_units(solid, cell, v, scale, overflow)


@wp.struct
class ReachWindow:
    """One rectangle of cells per grid: cells (i, j) of grid a with i0[a] <= i < i0[a] + ni[a] and j0[a] <= j <
    j0[a] + nj[a], numbered row by row from first[a] (window numbering, three grids together: n_cells)."""

    i0: wp.vec3i
    j0: wp.vec3i
    ni: wp.vec3i
    nj: wp.vec3i
    first: wp.vec3i
    n_cells: wp.int32
    # Per grid, bounds in frame coordinates relative to the grid's corner [m] inside which a particle's extent
    # (u - r, u + r, v - r, v + r) cannot reach a cell outside the window (two cells of slack: more than any ray
    # mode's span and its rounding tolerance); -inf / +inf where the window holds the grid's edge.
    lo_u: wp.vec3
    hi_u: wp.vec3
    lo_v: wp.vec3
    hi_v: wp.vec3


@wp.func
def window_cell(grid: LampGridParams, win: ReachWindow, t: wp.int32) -> wp.vec3i:
    """(axis a, flat cell, 0) of window cell t."""
    a = int(0)
    if t >= win.first[2]:
        a = 2
    elif t >= win.first[1]:
        a = 1
    local = t - win.first[a]
    jj = local / win.ni[a]
    ii = local - jj * win.ni[a]
    c = grid.offset[a] + (win.j0[a] + jj) * grid.n_u[a] + win.i0[a] + ii
    return wp.vec3i(a, c, 0)


@wp.func
def footprint_span(grid: LampGridParams, center: wp.vec3, r: wp.float32, a: wp.int32, ray: wp.int32) -> wp.vec4i:
    """(first i, last i, first j, last j) of the cells of grid a that the depth pass may visit for a sphere (its
    rows as the pass's, its columns those of the whole disk: a superset of every row's); first > last if none."""
    pu = center[(a + 1) % 3] - grid.corner_u[a]
    pv = center[(a + 2) % 3] - grid.corner_v[a]
    cols = cell_span(pu - r, pu + r, grid.h_u[a], grid.n_u[a], ray)
    rows = cell_span(pv - r, pv + r, grid.h_v[a], grid.n_v[a], ray)
    return wp.vec4i(cols[0], cols[1], rows[0], rows[1])


@wp.kernel
def dist_reach(
    grid: LampGridParams,
    particles: LampParticles,
    ray: wp.int32,
    lamp_mask: wp.int32,
    # outputs
    box: wp.array[wp.int32],
):
    """The cells the rank's particles reach, per grid whose lamps are on: box[4 a : 4 a + 4] = (min i, max i, min j,
    max j) over the particles' footprints (start from (big, -1, big, -1))."""
    p = wp.tid()
    sphere = frame_sphere(grid, particles, p)
    if not sphere.casts:
        return
    for a in range(3):
        if ((lamp_mask >> (2 * a)) & 3) != 0:
            s = footprint_span(grid, sphere.center, sphere.radius, a, ray)
            if s[0] <= s[1] and s[2] <= s[3]:
                wp.atomic_min(box, 4 * a, s[0])
                wp.atomic_max(box, 4 * a + 1, s[1])
                wp.atomic_min(box, 4 * a + 2, s[2])
                wp.atomic_max(box, 4 * a + 3, s[3])


@wp.func
def escapes_window(
    grid: LampGridParams, win: ReachWindow, particles: LampParticles, p: wp.int32, ray: wp.int32, lamp_mask: wp.int32
) -> wp.bool:
    """Whether particle p's footprint on a grid whose lamps are on leaves the window (an invalid or inactive
    particle offers nothing, so it never escapes)."""
    sphere = frame_sphere(grid, particles, p)
    if not sphere.casts:
        return False
    out = False
    for a in range(3):
        if ((lamp_mask >> (2 * a)) & 3) != 0:
            s = footprint_span(grid, sphere.center, sphere.radius, a, ray)
            if s[0] <= s[1] and s[2] <= s[3]:
                if s[0] < win.i0[a] or s[1] >= win.i0[a] + win.ni[a]:
                    out = True
                if s[2] < win.j0[a] or s[3] >= win.j0[a] + win.nj[a]:
                    out = True
    return out


@wp.kernel
def dist_seed_window(
    grid: LampGridParams,
    win: ReachWindow,
    particles: LampParticles,
    criterion: wp.int32,
    # outputs
    keys: wp.array[wp.uint64],
    counts: wp.array[wp.int64],
    diag: wp.array[wp.int32],
):
    """``lamp_seed`` on the window's cells only (thread t: window cell t); thread t also clears particle t's
    counts and diagnostic t."""
    t = wp.tid()
    clear_particle_counts(t, particles.n, counts, diag)
    if t >= win.n_cells:
        return
    wc = window_cell(grid, win, t)
    c = wc[1]
    cell = grid_cell(grid, c)
    for side in range(2):
        keys[2 * c + side] = seed_key(grid, particles, cell, side, keys[2 * c + side], criterion)


@wp.kernel
def dist_escapes(
    grid: LampGridParams,
    win: ReachWindow,
    particles: LampParticles,
    ray: wp.int32,
    lamp_mask: wp.int32,
    # outputs
    escapes: wp.array[wp.int32],
):
    """Counts particle p in ``escapes`` if its footprint left the window. A particle well inside the window's bounds
    is passed by comparisons alone; only those near its edge take the exact test (its footprint spans: twelve
    divisions, which cost 0.5 ms at 27M particles where the loads cost 0.1)."""
    p = wp.tid()
    if p >= particles.n or inactive(particles, p):
        return
    c = grid_to_frame(grid, particles.positions[p])
    r = particles.radii[p]
    inside = True
    for a in range(3):
        if ((lamp_mask >> (2 * a)) & 3) != 0:
            pu = c[(a + 1) % 3] - grid.corner_u[a]
            pv = c[(a + 2) % 3] - grid.corner_v[a]
            # NaN fails every comparison: such a particle goes to the exact test, which ignores it.
            in_u = pu - r >= win.lo_u[a] and pu + r <= win.hi_u[a]
            if not (in_u and pv - r >= win.lo_v[a] and pv + r <= win.hi_v[a]):
                inside = False
    if inside:
        return
    if escapes_window(grid, win, particles, p, ray, lamp_mask):
        wp.atomic_add(escapes, 0, 1)


@wp.kernel
def dist_pack(
    keys: wp.array[wp.uint64],
    gids: wp.array[wp.int32],
    cells: wp.array[wp.int32],
    flip: wp.int32,
    # outputs
    shared: wp.array[wp.uint64],
):
    """shared[2 k + side] = the rank's key of cell cells[k] with its global id (flipped where ``flip``): the rank's
    offer for the cells that two or more ranks reach (EMPTY where its particles reach no such cell)."""
    k = wp.tid()
    c = cells[k]
    for side in range(2):
        shared[2 * k + side] = flipped(global_key(keys[2 * c + side], gids), flip)


@wp.kernel
def dist_scatter_window(
    grid: LampGridParams,
    win: ReachWindow,
    keys: wp.array[wp.uint64],
    gids: wp.array[wp.int32],
    caller: wp.array[wp.int32],
    slot_of: wp.array[wp.int32],
    shared: wp.array[wp.uint64],
    # outputs
    counts: wp.array[wp.int64],
):
    """``dist_scatter`` over the window's cells: a shared cell (slot_of >= 0) is the rank's where the reduced key
    equals its own key in global ids; any other cell of the window only this rank reaches, so its own key wins."""
    t = wp.tid()
    wc = window_cell(grid, win, t)
    a = wc[0]
    c = wc[1]
    if keys[2 * c] == EMPTY_KEY and keys[2 * c + 1] == EMPTY_KEY:
        return  # unlit by this rank: no slot to read
    slot = slot_of[c]
    for side in range(2):
        mine = keys[2 * c + side]
        if mine != EMPTY_KEY:
            won = True
            if slot >= 0:
                won = global_key(mine, gids) == shared[2 * slot + side]
            if won:
                i = key_owner(mine)
                if caller.shape[0] > 0:
                    i = caller[i]
                if side == 0:
                    wp.atomic_add(counts, 3 * i + a, wp.int64(1))
                else:
                    wp.atomic_add(counts, 3 * i + a, wp.int64(-1))
