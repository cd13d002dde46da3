"""A/B of depth-pass variants on the GPU (an experiment, not the library; bench/NOTES.md v4 has the results).
Each variant must reproduce the library's keys bitwise; times are (seed + depth) - seed, CUDA graph replays,
medians.

    python bench/experiments/depth_variants.py 100 200
"""

import sys

import numpy as np
import warp as wp

sys.path.insert(0, ".")
from warp_lamp.bench import _lattice_grid, _median_gpu_time
from warp_lamp.kernels import lamp as KL
from warp_lamp.kernels.footprint import cell_offset, cell_span, lamp_reach, pack_key
from warp_lamp.lamp import ShiningLamp
from warp_lamp.scenes import scene_lattice_box

wp.set_module_options({"enable_backward": False, "fuse_fp": False})


@wp.func
def row_live(keys: wp.array[wp.uint64], row: int, c0: int, c1: int, bound: wp.uint64, side: int) -> int:
    """Any key of the row at or above bound? Four cells per step, loads issued before any compare."""
    live = int(0)
    i = c0
    while i <= c1:
        k0 = keys[row + 2 * i + side]
        k1 = keys[row + 2 * wp.min(i + 1, c1) + side]
        k2 = keys[row + 2 * wp.min(i + 2, c1) + side]
        k3 = keys[row + 2 * wp.min(i + 3, c1) + side]
        m = wp.max(wp.max(k0, k1), wp.max(k2, k3))
        if m >= bound:
            live = 1
        i += 4
    return live


@wp.func
def axis_pass_both(
    a: int,
    pid: int,
    q: wp.vec4,
    keys: wp.array[wp.uint64],
    corner_u: wp.vec3,
    corner_v: wp.vec3,
    h_u: wp.vec3,
    h_v: wp.vec3,
    n_u: wp.vec3i,
    n_v: wp.vec3i,
    offset: wp.vec3i,
    criterion: int,
):
    r = q[3]
    r2 = r * r
    pu = q[(a + 1) % 3] - corner_u[a]
    pv = q[(a + 2) % 3] - corner_v[a]
    pd = q[a]
    hu = h_u[a]
    hv = h_v[a]
    nu = n_u[a]
    nv = n_v[a]
    base = offset[a]
    rows = cell_span(pv - r, pv + r, hv, nv, criterion)
    for j in range(rows[0], rows[1] + 1):
        dv = cell_offset(j, hv, pv, criterion)
        rem = r2 - dv * dv
        if rem < 0.0:
            continue
        w = wp.sqrt(rem)
        cols = cell_span(pu - w, pu + w, hu, nu, criterion)
        if cols[0] > cols[1]:
            continue
        row = 2 * (base + j * nu)
        reach = lamp_reach(rem, 0.0, criterion)
        live = KL.row_live(keys, row, cols[0], cols[1], pack_key(pd - reach, 0), pack_key(-(pd + reach), 0))
        if live == 0:
            continue
        for i in range(cols[0], cols[1] + 1):
            du = cell_offset(i, hu, pu, criterion)
            if du * du <= rem:
                s = lamp_reach(rem, du, criterion)
                slot = row + 2 * i
                if (live & 1) != 0:
                    KL.offer(keys, slot, pack_key(pd - s, pid))
                if (live & 2) != 0:
                    KL.offer(keys, slot + 1, pack_key(-(pd + s), pid))


@wp.kernel(enable_backward=False)
def depth_both_per_axis(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    active: wp.array[wp.int32],
    origin: wp.vec3,
    corner_u: wp.vec3,
    corner_v: wp.vec3,
    h_u: wp.vec3,
    h_v: wp.vec3,
    n_u: wp.vec3i,
    n_v: wp.vec3i,
    offset: wp.vec3i,
    criterion: int,
    lamp_mask: int,
    keys: wp.array[wp.uint64],
    diag: wp.array[wp.int32],
):
    t = wp.tid()
    n = positions.shape[0]
    a = t / n
    pid = t - a * n
    q = KL.particle_frame(pid, n, positions, radii, active, origin)
    if q[3] == 0.0:
        return
    if a == 0:
        axis_pass_both(0, pid, q, keys, corner_u, corner_v, h_u, h_v, n_u, n_v, offset, criterion)
    elif a == 1:
        axis_pass_both(1, pid, q, keys, corner_u, corner_v, h_u, h_v, n_u, n_v, offset, criterion)
    else:
        axis_pass_both(2, pid, q, keys, corner_u, corner_v, h_u, h_v, n_u, n_v, offset, criterion)


@wp.func
def axis_pass(
    a: int,
    pid: int,
    q: wp.vec4,
    keys: wp.array[wp.uint64],
    corner_u: wp.vec3,
    corner_v: wp.vec3,
    h_u: wp.vec3,
    h_v: wp.vec3,
    n_u: wp.vec3i,
    n_v: wp.vec3i,
    offset: wp.vec3i,
    criterion: int,
):
    r = q[3]
    r2 = r * r
    pu = q[(a + 1) % 3] - corner_u[a]
    pv = q[(a + 2) % 3] - corner_v[a]
    pd = q[a]
    hu = h_u[a]
    hv = h_v[a]
    nu = n_u[a]
    nv = n_v[a]
    base = offset[a]
    rows = cell_span(pv - r, pv + r, hv, nv, criterion)
    for j in range(rows[0], rows[1] + 1):
        dv = cell_offset(j, hv, pv, criterion)
        rem = r2 - dv * dv
        if rem < 0.0:
            continue
        w = wp.sqrt(rem)
        cols = cell_span(pu - w, pu + w, hu, nu, criterion)
        if cols[0] > cols[1]:
            continue
        row = 2 * (base + j * nu)
        reach = lamp_reach(rem, 0.0, criterion)
        lo_live = row_live(keys, row, cols[0], cols[1], pack_key(pd - reach, 0), 0)
        hi_live = row_live(keys, row, cols[0], cols[1], pack_key(-(pd + reach), 0), 1)
        if lo_live + hi_live == 0:
            continue
        for i in range(cols[0], cols[1] + 1):
            du = cell_offset(i, hu, pu, criterion)
            if du * du <= rem:
                s = lamp_reach(rem, du, criterion)
                slot = row + 2 * i
                if lo_live != 0:
                    KL.offer(keys, slot, pack_key(pd - s, pid))
                if hi_live != 0:
                    KL.offer(keys, slot + 1, pack_key(-(pd + s), pid))


@wp.kernel(enable_backward=False)
def depth_chunked(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    active: wp.array[wp.int32],
    origin: wp.vec3,
    corner_u: wp.vec3,
    corner_v: wp.vec3,
    h_u: wp.vec3,
    h_v: wp.vec3,
    n_u: wp.vec3i,
    n_v: wp.vec3i,
    offset: wp.vec3i,
    criterion: int,
    lamp_mask: int,
    keys: wp.array[wp.uint64],
    diag: wp.array[wp.int32],
):
    pid = wp.tid()
    q = KL.particle_frame(pid, positions.shape[0], positions, radii, active, origin)
    if q[3] == 0.0:
        return
    for a in range(3):
        axis_pass(a, pid, q, keys, corner_u, corner_v, h_u, h_v, n_u, n_v, offset, criterion)


@wp.kernel(enable_backward=False)
def depth_per_axis(
    positions: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    active: wp.array[wp.int32],
    origin: wp.vec3,
    corner_u: wp.vec3,
    corner_v: wp.vec3,
    h_u: wp.vec3,
    h_v: wp.vec3,
    n_u: wp.vec3i,
    n_v: wp.vec3i,
    offset: wp.vec3i,
    criterion: int,
    lamp_mask: int,
    keys: wp.array[wp.uint64],
    diag: wp.array[wp.int32],
):
    t = wp.tid()
    n = positions.shape[0]
    a = t / n
    pid = t - a * n
    q = KL.particle_frame(pid, n, positions, radii, active, origin)
    if q[3] == 0.0:
        return
    if a == 0:
        axis_pass(0, pid, q, keys, corner_u, corner_v, h_u, h_v, n_u, n_v, offset, criterion)
    elif a == 1:
        axis_pass(1, pid, q, keys, corner_u, corner_v, h_u, h_v, n_u, n_v, offset, criterion)
    else:
        axis_pass(2, pid, q, keys, corner_u, corner_v, h_u, h_v, n_u, n_v, offset, criterion)


def main():
    wp.config.log_level = wp.LOG_WARNING
    dev = wp.get_device("cuda:0" if wp.get_cuda_device_count() else "cpu")
    for m in [int(x) for x in (sys.argv[1:] or ["100"])]:
        scene = scene_lattice_box(m)
        grid = _lattice_grid(scene, 0.25)
        n = scene.n
        lamp = ShiningLamp(grid, device=dev)
        pos = wp.array((scene.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=dev)
        rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=dev)
        origin = wp.vec3(0.0, 0.0, 0.0)
        lamp._update(pos, rad, None, origin)
        reference = lamp.keys.numpy()
        grid_args = [lamp._corner_u, lamp._corner_v, lamp._h_u, lamp._h_v, lamp._n_u]
        seed = [pos, rad, lamp._no_active, n, origin, *grid_args, lamp._offset, 1]
        args = [pos, rad, lamp._no_active, origin, *grid_args, lamp._n_v, lamp._offset, 1, lamp.lamp_mask]
        reps = 50 if dev.is_cuda else 3

        def run(kernel, dim, seed_only=False, block_dim=256):
            wp.launch(KL.lamp_seed, dim=lamp._n_cells, inputs=seed, outputs=[lamp.keys], device=dev)
            if not seed_only:
                wp.launch(kernel, dim=dim, inputs=args, outputs=[lamp.keys, lamp.diag], device=dev, block_dim=block_dim)

        def timed(fn):
            if not dev.is_cuda:
                return _median_gpu_time(fn, dev, reps)
            with wp.ScopedCapture(device=dev) as cap:
                fn()
            return _median_gpu_time(lambda: wp.capture_launch(cap.graph), dev, reps)

        t_seed = timed(lambda: run(None, 0, seed_only=True))
        # Cold variants: every key starts empty, so the atomics are all there.
        # A is the library since v4 (chunks of four cells, both lamps, 128-thread blocks); B reads one lamp's
        # chunk at a time; C and E give each (sphere, axis) its own thread. v2's unchunked kernel is gone from
        # the library: its figures stay in bench/NOTES.md.
        variants = (
            ("A library", KL.lamp_depth, n, KL.DEPTH_BLOCK_DIM),
            ("A bd256", KL.lamp_depth, n, 256),
            ("B chunked", depth_chunked, n, 256),
            ("B chunked128", depth_chunked, n, 128),
            ("C bd128", depth_per_axis, 3 * n, 128),
            ("E both/axis", depth_both_per_axis, 3 * n, 256),
            ("E both/axis128", depth_both_per_axis, 3 * n, 128),
        )
        for name, kernel, dim, bd in variants:
            t = timed(lambda k=kernel, d=dim, b=bd: run(k, d, block_dim=b)) - t_seed
            same = np.array_equal(lamp.keys.numpy(), reference)
            lamp.forget()
            t_cold = _median_gpu_time(
                lambda k=kernel, d=dim: (
                    lamp.forget(),
                    wp.launch(k, dim=d, inputs=args, outputs=[lamp.keys, lamp.diag], device=dev),
                ),
                dev,
                max(3, reps // 5),
            )
            same_cold = np.array_equal(lamp.keys.numpy(), reference)
            print(
                f"n={n:>10,} {name:<15} warm depth {t * 1e3:.4f} ms  cold depth+forget {t_cold * 1e3:.4f} ms  "
                f"keys equal: {same} {same_cold}",
                flush=True,
            )


if __name__ == "__main__":
    main()
