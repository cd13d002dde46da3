"""Wetted-surface kernels, the crossings: every fluid/dry change along the lamp rows, loaded on its nearest
sphere or wall (step 5 of the pipeline in :mod:`warp_lamp.kernels.wetted`)."""

import warp as wp

from warp_lamp.kernels.walls import LampWalls, plane_value
from warp_lamp.kernels.wetted_base import (
    DIAG_UNATTRIBUTED,
    FAR,
    ONES,
    SKIN_CROSS_FILLED,
    SKIN_CROSS_KEPT,
    WALL_OWNER,
    WetBox,
    bin_head,
    bin_span,
    low_mask,
    lowest_bit,
    row_mask,
    table_claim,
    table_find,
    virtual_point,
    walls_fluid,
    word_at,
)

# No unrolling (see kernels/wetted_base.py), no FMA contraction: every module of the wetted surface compiles
# with the same options, so a function evaluates alike in each.
wp.set_module_options({"enable_backward": False, "fuse_fp": False, "max_unroll": 1})


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
    span = bin_span(p, reach, box)
    best = FAR
    best_id = int(-1)
    for bz in range(span.lo[2], span.hi[2] + 1):
        for by in range(span.lo[1], span.hi[1] + 1):
            for bx in range(span.lo[0], span.hi[0] + 1):
                i = bin_head(bx, by, bz, box, heads)
                while i >= 0:
                    d = sphere_distance(p, i, positions, radii)
                    if d < best or (d == best and i < best_id):
                        if walls.n == 0 or not buried(i, positions, radii, walls):
                            best = d
                            best_id = i
                    i = next_in_bin[i]
    return best_id


@wp.func
def nearest_two_in_cube(
    p: wp.vec3d,
    reach: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    box: WetBox,
) -> wp.vec3d:
    """``nearest_in_cube`` without walls, the same walk and rule, with the runner-up: (id, d1, d2), d2 the second
    smallest ``|p - c| - r`` among the searched spheres (FAR with fewer than two; d1 when tied)."""
    span = bin_span(p, reach, box)
    best = FAR
    second = FAR
    best_id = int(-1)
    for bz in range(span.lo[2], span.hi[2] + 1):
        for by in range(span.lo[1], span.hi[1] + 1):
            for bx in range(span.lo[0], span.hi[0] + 1):
                i = bin_head(bx, by, bz, box, heads)
                while i >= 0:
                    d = sphere_distance(p, i, positions, radii)
                    if d < best or (d == best and i < best_id):
                        second = best
                        best = d
                        best_id = i
                    elif d < second:
                        second = d
                    i = next_in_bin[i]
    return wp.vec3d(wp.float64(best_id), best, second)


@wp.func
def owner_find(key: wp.int32, keys: wp.array[wp.int32], owners: wp.array[wp.int32]) -> wp.int32:
    """The owner kept for crossing face ``key``, or -1."""
    s = table_find(key, keys)
    if s < 0:
        return -1
    return owners[s]


@wp.func
def owner_store(
    key: wp.int32, pid: wp.int32, keys: wp.array[wp.int32], owners: wp.array[wp.int32], skin: wp.array[wp.int32]
):
    """Keep ``pid`` (-1: none) as the owner of crossing face ``key``; a full probe run drops it."""
    s = table_claim(key, pid >= 0, keys, skin, SKIN_CROSS_FILLED)
    if s >= 0:
        owners[s] = pid


@wp.func
def nearest_beyond(
    p: wp.vec3d,
    a: wp.int32,
    pid: wp.int32,
    d1: wp.float64,
    rmax: wp.float64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    box: WetBox,
    walls: LampWalls,
) -> wp.int32:
    """The second search of a crossing whose first (within one voxel edge) found sphere ``pid`` at ``d1`` beyond it,
    or none (pid < 0). The answer is no farther than d1, so every sphere that could beat or tie it is centred within
    d1 + r_max of p: where d1 is under the bound B_a the cube shrinks to that (the same answer and tie; the slowest
    crossings walked the B_a + r_max cube's 27 to 64 bins), else the bound's cube as before."""
    reach = box.bound[a] + rmax
    if pid >= 0 and d1 < box.bound[a]:
        reach = (d1 + rmax) * wp.float64(1.000000001)
    return nearest_in_cube(p, reach, positions, radii, heads, next_in_bin, box, walls)


@wp.func
def nearest_kept(
    p: wp.vec3d,
    a: wp.int32,
    key: wp.int32,
    rmax: wp.float64,
    shrink: wp.float64,
    n_particles: wp.int32,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    box: WetBox,
    walls: LampWalls,
    cross_keys: wp.array[wp.int32],
    cross_owners: wp.array[wp.int32],
    skin: wp.array[wp.int32],
) -> wp.int32:
    """``nearest_sphere`` without walls, with the skin: the owner kept for this face since the last reference, or
    the search, whose answer is kept when it wins by more than twice the skin. Kept, it stays the answer: between
    the update that kept it and this one every sphere moved less than the skin (each less than half of it from the
    reference), so every ``|p - c| - r`` changed by less than it, and the owner is still strictly the nearest (the
    runner-up among the searched spheres, and those not searched, farther than one voxel edge, both trail it by more
    than twice the skin)."""
    kept = owner_find(key, cross_keys, cross_owners)
    if kept >= 0 and kept < n_particles:
        wp.atomic_add(skin, SKIN_CROSS_KEPT, 1)
        return kept
    near = box.h[a]
    reach = (near + rmax) * wp.float64(1.000000001)
    two = nearest_two_in_cube(p, reach, positions, radii, heads, next_in_bin, box)
    pid = wp.int32(two[0])
    if pid >= 0:
        if two[1] <= near:
            lead = wp.min(two[2], near) - two[1]
            if lead > wp.float64(2.0) * shrink * (wp.float64(1.0) + wp.float64(1.0e-6)) + wp.float64(1.0e-12) * near:
                owner_store(key, pid, cross_keys, cross_owners, skin)
            return pid
    return nearest_beyond(p, a, pid, two[1], rmax, positions, radii, heads, next_in_bin, box, walls)


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
    d1 = FAR
    if pid >= 0:
        d1 = sphere_distance(p, pid, positions, radii)
        if d1 <= near:
            return pid
    return nearest_beyond(p, a, pid, d1, rmax, positions, radii, heads, next_in_bin, box, walls)


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
    shrink: wp.float64,
    n_particles: wp.int32,
    counts: wp.array[wp.int64],
    hits: wp.array[wp.int32],
    rays: wp.array[wp.int32],
    diag: wp.array[wp.int32],
    owners: wp.array[wp.int32],
    wall_counts: wp.array[wp.int64],
    cross_keys: wp.array[wp.int32],
    cross_owners: wp.array[wp.int32],
    skin: wp.array[wp.int32],
):
    """A crossing at p on a row along axis a: fluid to dry going +a (enters = 1, the low lamp's +1) or dry to
    fluid (the high lamp's -1), to the nearest sphere, ``|p - c| - r`` (ties to the lowest index). With walls: the
    wall cutting axis a with the smallest signed distance ``g(p)`` (ties to the lower wall) takes the crossing if
    that is smaller than the sphere's distance (ties to the sphere) or no sphere lies within the attribution bound:
    the dry fillet between a body and its platen loads the platen where the platen is nearer. A wall whose normal
    has no a-component never takes an axis-a crossing, so on an axis no wall cuts the particles' counts still sum
    to zero. Integer counts, so the order of the atomics cannot change
    the result. With the skin (``cross_keys`` not empty) and no walls, the owner may be a kept one
    (``nearest_kept``)."""
    lamp = 2 * a
    sign = int(1)
    if enters != 0:
        wp.atomic_add(rays, box.offset[a] + ray, 1)
    else:
        lamp = 2 * a + 1
        sign = -1
    if ((box.lamp_mask >> lamp) & 1) == 0:
        return
    pid = int(-1)
    if cross_keys.shape[0] > 0 and walls.n == 0:
        key = box.face_offset[a] + ray * (box.n[a] + 1) + face
        pid = nearest_kept(
            p,
            a,
            key,
            wp.float64(rmax[0]),
            shrink,
            n_particles,
            positions,
            radii,
            heads,
            next_in_bin,
            box,
            walls,
            cross_keys,
            cross_owners,
            skin,
        )
    else:
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


@wp.func
def load_face(
    key: wp.int32,
    enters: wp.int32,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    rmax: wp.array[wp.float32],
    box: WetBox,
    walls: LampWalls,
    shrink: wp.float64,
    n_particles: wp.int32,
    counts: wp.array[wp.int64],
    hits: wp.array[wp.int32],
    rays: wp.array[wp.int32],
    diag: wp.array[wp.int32],
    owners: wp.array[wp.int32],
    wall_counts: wp.array[wp.int64],
    cross_keys: wp.array[wp.int32],
    cross_owners: wp.array[wp.int32],
    skin: wp.array[wp.int32],
):
    """``load_crossing`` of the crossing on face ``key`` (``face_offset[a] + ray (n_a + 1) + face``): the axis, the
    ray and the face from the key, and the crossing point, the face's centre: voxel centres across the axis, the
    face itself along it. The face-word threads and the listed crossings' threads both load through it."""
    axis = int(0)
    if key >= box.face_offset[2]:
        axis = 2
    elif key >= box.face_offset[1]:
        axis = 1
    rest = key - box.face_offset[axis]
    ray = rest / (box.n[axis] + 1)
    face = rest - ray * (box.n[axis] + 1)
    x = int(0)
    j = int(0)
    k = int(0)
    if axis == 0:
        x = face
        j = ray % box.n[1]
        k = ray / box.n[1]
    elif axis == 1:
        k = ray % box.n[2]
        x = ray / box.n[2]
    else:
        x = ray % box.n[0]
        j = ray / box.n[0]
    p = wp.vec3d(
        (wp.float64(x) + wp.float64(0.5)) * box.h[0],
        (wp.float64(j) + wp.float64(0.5)) * box.h[1],
        (wp.float64(k) + wp.float64(0.5)) * box.h[2],
    )
    p[axis] = wp.float64(face) * box.h[axis]
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
        shrink,
        n_particles,
        counts,
        hits,
        rays,
        diag,
        owners,
        wall_counts,
        cross_keys,
        cross_owners,
        skin,
    )


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
    shrink: wp.float64,
    n_particles: wp.int32,
    # outputs
    counts: wp.array[wp.int64],
    hits: wp.array[wp.int32],
    rays: wp.array[wp.int32],
    diag: wp.array[wp.int32],
    owners: wp.array[wp.int32],
    wall_counts: wp.array[wp.int64],
    cross_keys: wp.array[wp.int32],
    cross_owners: wp.array[wp.int32],
    skin: wp.array[wp.int32],
    cross_list: wp.array[wp.vec2i],
    cross_listed: wp.array[wp.int32],
):
    """Crossings on the faces of all three axes in one launch (threads from ``first[a]`` on are axis a's): one
    thread per ``bits`` bits of a face word. With a crossing list (``cross_list`` not empty; CUDA), each crossing
    found goes into it as (face key, enters) while there is room, for ``wet_cross_listed`` to load with one thread
    each, and only those past its capacity are loaded here; without one, each is loaded here (at most ``bits``
    nearest-sphere searches per thread: 32 on the CPU).

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
        ray = int(0)
        if axis == 0:
            face = x
            ray = j + box.n[1] * k
        elif axis == 1:
            ray = k + box.n[2] * x
        else:
            ray = x + box.n[0] * j
        key = box.face_offset[axis] + ray * (box.n[axis] + 1) + face
        if cross_list.shape[0] > 0:
            slot = wp.atomic_add(cross_listed, 0, 1)
            if slot < cross_list.shape[0]:
                cross_list[slot] = wp.vec2i(key, enters)
                continue
        load_face(
            key,
            enters,
            positions,
            radii,
            heads,
            next_in_bin,
            rmax,
            box,
            walls,
            shrink,
            n_particles,
            counts,
            hits,
            rays,
            diag,
            owners,
            wall_counts,
            cross_keys,
            cross_owners,
            skin,
        )


@wp.kernel
def wet_cross_listed(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    box: WetBox,
    walls: LampWalls,
    heads: wp.array[wp.int32],
    next_in_bin: wp.array[wp.int32],
    rmax: wp.array[wp.float32],
    shrink: wp.float64,
    n_particles: wp.int32,
    cross_list: wp.array[wp.vec2i],
    cross_listed: wp.array[wp.int32],
    # outputs
    counts: wp.array[wp.int64],
    hits: wp.array[wp.int32],
    rays: wp.array[wp.int32],
    diag: wp.array[wp.int32],
    owners: wp.array[wp.int32],
    wall_counts: wp.array[wp.int64],
    cross_keys: wp.array[wp.int32],
    cross_owners: wp.array[wp.int32],
    skin: wp.array[wp.int32],
):
    """One thread per listed crossing (``wet_cross``'s list): ``load_face`` of its key, as the face-word threads
    load what they do not list. The search threads are then as many as the crossings (about 1% of the faces)
    instead of one per face bit, most of which find nothing and hold a register-heavy block's place."""
    s = wp.tid()
    if s >= wp.min(cross_listed[0], cross_list.shape[0]):
        return
    item = cross_list[s]
    load_face(
        item[0],
        item[1],
        positions,
        radii,
        heads,
        next_in_bin,
        rmax,
        box,
        walls,
        shrink,
        n_particles,
        counts,
        hits,
        rays,
        diag,
        owners,
        wall_counts,
        cross_keys,
        cross_owners,
        skin,
    )


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
