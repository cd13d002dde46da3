"""Kernels of the benchmark's peers and ceilings: a Warp BVH ray caster, and device probes."""

import warp as wp

from warp_lamp.kernels.footprint import lamp_reach
from warp_lamp.kernels.grid import LampGridParams, grid_cell, grid_to_frame
from warp_lamp.kernels.keys import EMPTY_KEY, pack_key

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
    grid: LampGridParams,
    bvh: wp.uint64,
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    start_lo: wp.vec3,
    start_hi: wp.vec3,
    # outputs
    keys: wp.array[wp.uint64],
):
    """One thread per cell ray per lamp (criterion 1): nearest sphere along the ray, shrinking max_dist.

    The hit test works in the grid's transverse coordinates, exactly as the lamp does: the textbook
    |oc|^2 - (oc.d)^2 cancels catastrophically in float32 when the ray starts far from the body.
    """
    t = wp.tid()
    c = t / 2
    side = t - 2 * c
    cell = grid_cell(grid, c)
    a = cell[0]
    u = (float(cell[1]) + 0.5) * grid.h_u[a]
    v = (float(cell[2]) + 0.5) * grid.h_v[a]
    start = wp.vec3(0.0)
    d = wp.vec3(0.0)
    if side == 0:
        start[a] = start_lo[a]
        d[a] = 1.0
    else:
        start[a] = start_hi[a]
        d[a] = -1.0
    start[(a + 1) % 3] = u + grid.corner_u[a]
    start[(a + 2) % 3] = v + grid.corner_v[a]
    best = EMPTY_KEY
    max_dist = float(1.0e30)
    q = wp.bvh_query_ray(bvh, start, d)
    k = int(0)
    while wp.bvh_query_next(q, k, max_dist):
        p = grid_to_frame(grid, positions[k])
        r = radii[k]
        du = u - (p[(a + 1) % 3] - grid.corner_u[a])
        dv = v - (p[(a + 2) % 3] - grid.corner_v[a])
        rem = r * r - dv * dv
        du2 = du * du
        # The lamp's own test and depth, written the same way, so that owners compare bitwise.
        if rem >= 0.0 and du2 <= rem:
            s = lamp_reach(rem, du, 1)
            key = EMPTY_KEY
            dist = float(0.0)
            if side == 0:
                key = pack_key(p[a] - s, k)
                dist = p[a] - s - start[a]
            else:
                key = pack_key(-(p[a] + s), k)
                dist = start[a] - (p[a] + s)
            if key < best:
                best = key
                # Boxes whose entry lies past the best hit cannot win; the margin keeps exact ties in play.
                max_dist = dist * 1.000001 + 1.0e-6
    keys[t] = best


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
