"""Voxel decompositions compared (an experiment, not the library): one thread per sphere setting runs of bits
(the library), against one thread per 32-sub-cell word searching nearby spheres in a hash grid. Both must give
the same bitmap; times are device times of a captured graph (mark + count), medians.

    python bench/experiments/voxel_variants.py          # the r = 1 mm target scene at s = 100
"""

import numpy as np
import warp as wp

from warp_lamp.kernels import porosity as porosity_kernels
from warp_lamp.scenes import scene_overlapping_box
from warp_lamp.timing import time_median_events

wp.set_module_options({"enable_backward": False, "fuse_fp": False})


@wp.kernel(enable_backward=False)
def voxel_word(
    grid: wp.uint64,
    centers: wp.array[wp.vec3d],
    radii: wp.array[wp.float64],
    hs: wp.vec3d,
    sub: wp.vec3i,
    words: wp.int32,
    reach: wp.float32,
    # outputs
    bits: wp.array[wp.uint32],
):
    """One thread per word: one hash-grid query around the word's 32 sub-cells, then the exact test for each."""
    t = wp.tid()
    row = t / words
    w = t - row * words
    k = row / sub[1]
    j = row - k * sub[1]
    y = (wp.float64(j) + wp.float64(0.5)) * hs[1]
    z = (wp.float64(k) + wp.float64(0.5)) * hs[2]
    mid = (wp.float64(w * 32) + wp.float64(16.0)) * hs[0]
    q = wp.hash_grid_query(grid, wp.vec3(wp.float32(mid), wp.float32(y), wp.float32(z)), reach)
    n = int(0)
    word = wp.uint32(0)
    while wp.hash_grid_query_next(q, n):
        c = centers[n]
        r = radii[n]
        rem = r * r - (y - c[1]) * (y - c[1]) - (z - c[2]) * (z - c[2])
        if rem >= wp.float64(0.0):
            for b in range(32):
                i = w * 32 + b
                if i < sub[0]:
                    dx = (wp.float64(i) + wp.float64(0.5)) * hs[0] - c[0]
                    if dx * dx <= rem:
                        word = word | (wp.uint32(1) << wp.uint32(b))
    bits[t] = word


def main():
    wp.config.log_level = wp.LOG_WARNING
    dev = wp.get_device("cuda:0" if wp.get_cuda_device_count() else "cpu")
    quick = not dev.is_cuda
    scene = scene_overlapping_box(0.001, (0.02, 0.02, 0.02) if quick else (0.1, 0.1, 0.2), device=dev)
    size = np.array([0.02] * 3) if quick else np.array([0.1, 0.1, 0.2])
    shape = tuple(round(float(x) / 0.01) for x in size)
    s = 20 if quick else 100
    sub = tuple(n * s for n in shape)
    words = (sub[0] + 31) // 32
    hs = size / np.asarray(shape) / s
    pos = wp.array(scene.centers, dtype=wp.vec3d, device=dev)
    rad = wp.array(scene.radii, dtype=wp.float64, device=dev)
    bits = wp.zeros(words * sub[1] * sub[2], dtype=wp.uint32, device=dev)
    counts = wp.zeros(shape, dtype=wp.int32, device=dev)
    grid = wp.HashGrid(128, 128, 128, device=dev)
    grid.build(wp.array(scene.centers.astype(np.float32), dtype=wp.vec3, device=dev), float(2 * scene.radii.max()))
    # Any sphere reaching a sub-cell of the word lies within r + half the word's diagonal of its middle.
    reach = float(scene.radii.max() + 0.5 * np.linalg.norm([32 * hs[0], hs[1], hs[2]]) + 1e-9)

    def count():
        wp.launch(
            porosity_kernels.bitmap_count,
            dim=(shape[0], shape[1], sub[2]),
            inputs=[bits, wp.vec3i(*sub), words, wp.vec3i(s, s, s)],
            outputs=[counts],
            device=dev,
        )

    def per_sphere():
        bits.zero_()
        counts.zero_()
        wp.launch(
            porosity_kernels.voxel_mark,
            dim=scene.n,
            inputs=[pos, rad, wp.vec3d(*hs), wp.vec3i(*sub), words],
            outputs=[bits],
            device=dev,
        )
        count()

    def per_word():
        counts.zero_()
        wp.launch(
            voxel_word,
            dim=bits.shape[0],
            inputs=[grid.id, pos, rad, wp.vec3d(*hs), wp.vec3i(*sub), words, reach],
            outputs=[bits],
            device=dev,
        )
        count()

    results = {}
    for name, fn in (("per sphere (library)", per_sphere), ("per word, hash grid", per_word)):
        fn()
        snapshot = bits.numpy().copy()
        if dev.is_cuda:
            with wp.ScopedCapture(device=dev) as cap:
                fn()
            t = time_median_events(lambda c=cap: wp.capture_launch(c.graph), dev, repeats=5)
        else:
            t = time_median_events(fn, dev, repeats=2)
        results[name] = snapshot
        print(f"{scene.n:,} spheres, {sub[0] * sub[1] * sub[2]:,} sub-cells: {name:<22} {t * 1e3:9.3f} ms", flush=True)
    a, b = results.values()
    print("bitmaps equal:", bool(np.array_equal(a, b)))


if __name__ == "__main__":
    main()
