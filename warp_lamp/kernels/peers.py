"""Kernels of the benchmark's peers and ceilings: a Warp BVH ray caster, and device probes.

The caster imports nothing from the lamp's kernels (keys, grid parameters, footprints, cell numbering): it is a
second implementation of criterion 1 that shares only the float32 arithmetic of the decision, which its kernel
states."""

import warp as wp

wp.set_module_options({"enable_backward": False, "fuse_fp": False})


@wp.kernel
def bvh_sphere_bounds(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    # outputs
    lowers: wp.array[wp.vec3],
    uppers: wp.array[wp.vec3],
):
    """Frame-coordinate boxes, padded by a relative 1e-6 so that a grazing ray is never lost to rounding in
    the BVH's slab test: the exact hit test below decides."""
    i = wp.tid()
    p = positions[i]
    r = radii[i]
    pad = r * 1.000001 + 1.0e-6 * wp.max(wp.abs(p[0]), wp.max(wp.abs(p[1]), wp.abs(p[2])))
    lowers[i] = p - wp.vec3(pad)
    uppers[i] = p + wp.vec3(pad)


@wp.kernel
def bvh_cast(
    bvh: wp.uint64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    a: wp.int32,
    n_u: wp.int32,
    corner_u: wp.float32,
    corner_v: wp.float32,
    h_u: wp.float32,
    h_v: wp.float32,
    start_lo: wp.float32,
    start_hi: wp.float32,
    # outputs
    owner: wp.array2d[wp.int32],
    depth: wp.array2d[wp.float32],
):
    """One thread per (ray, side) of the lamps along axis ``a`` (criterion 1): the nearest sphere along the ray
    through the centre of cell (i, j), ray t = j n_u + i, from the low side (0, along +a) or the high side (1,
    along -a); ``owner`` -1 where the ray meets nothing. Ties in depth go to the lower index.

    Positions are in the grid's frame (minus its origin: no rotation here). The hit test works in the grid's
    transverse coordinates, in the float32 order of operations that defines criterion 1's decision (``du`` from the
    cell centre ``(i + 1/2) h_u`` and the centre's offset from the grid corner, ``rem = r^2 - dv^2``, lit when
    ``du^2 <= rem``), so that owners compare bitwise with the lamp's even on a silhouette; the textbook
    |oc|^2 - (oc.d)^2 cancels catastrophically in float32 when the ray starts far from the body.
    """
    t, side = wp.tid()
    j = t / n_u
    i = t - j * n_u
    u = (float(i) + 0.5) * h_u
    v = (float(j) + 0.5) * h_v
    start = wp.vec3(0.0)
    d = wp.vec3(0.0)
    if side == 0:
        start[a] = start_lo
        d[a] = 1.0
    else:
        start[a] = start_hi
        d[a] = -1.0
    start[(a + 1) % 3] = u + corner_u
    start[(a + 2) % 3] = v + corner_v
    best = int(-1)
    best_depth = float(0.0)
    max_dist = float(1.0e30)
    q = wp.bvh_query_ray(bvh, start, d)
    k = int(0)
    while wp.bvh_query_next(q, k, max_dist):
        p = positions[k]
        r = radii[k]
        du = u - (p[(a + 1) % 3] - corner_u)
        dv = v - (p[(a + 2) % 3] - corner_v)
        rem = r * r - dv * dv
        du2 = du * du
        if rem >= 0.0 and du2 <= rem:
            half = wp.sqrt(rem - du2)
            # The coordinate the ray enters at (low side) or, negated, leaves at (high side): smaller is nearer.
            z = p[a] - half
            dist = z - start[a]
            if side == 1:
                z = -(p[a] + half)
                dist = start[a] - (p[a] + half)
            if best < 0 or z < best_depth or (z == best_depth and k < best):
                best = k
                best_depth = z
                # Boxes whose entry lies past the best hit cannot win; the margin keeps exact ties in play.
                max_dist = dist * 1.000001 + 1.0e-6
    owner[t, side] = best
    depth[t, side] = best_depth


@wp.kernel
def bvh_scatter(
    owner: wp.array2d[wp.int32],
    a: wp.int32,
    # outputs
    counts: wp.array[wp.int64],
):
    """Each lit ray of axis ``a`` adds +1 (low side) or -1 (high side) to its owner's count on that axis."""
    t = wp.tid()
    low = owner[t, 0]
    high = owner[t, 1]
    if low >= 0:
        wp.atomic_add(counts, 3 * low + a, wp.int64(1))
    if high >= 0:
        wp.atomic_add(counts, 3 * high + a, wp.int64(-1))


@wp.kernel
def probe_atomic_min(
    seed: wp.int32,
    iters: wp.int32,
    mask: wp.int32,
    # outputs
    table: wp.array[wp.uint64],
):
    """Random uint64 atomic_min into a table of mask + 1 entries: the device's scattered-atomic ceiling."""
    t = wp.tid()
    state = wp.rand_init(seed, t)
    for _ in range(iters):
        idx = wp.int32(wp.randi(state)) & mask
        wp.atomic_min(table, idx, wp.uint64(wp.randi(state)))
