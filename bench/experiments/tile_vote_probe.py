"""Feasibility probe for a warp-cooperative blocker scan (not used by the library): a block of 32 lanes scans a
test's list of spheres 32 at a time and takes the first that holds the point with a vote (``wp.tile`` of each lane's
hit, ``wp.tile_reduce(wp.min, ...)``), which is the serial scan's first blocker, index for index, so the exact test's
"same answer and the same blocker" would survive. Runs on the CPU with ``wp.config.enable_cpu_blocks`` (Warp 1.19),
against a plain NumPy serial scan.

    python bench/experiments/tile_vote_probe.py [--device cuda:0]
"""

from __future__ import annotations

import argparse

import numpy as np
import warp as wp

LANES = 32
NONE = 1 << 30


@wp.kernel(enable_backward=False)
def first_blocker(
    spheres: wp.array[wp.vec4],
    lists: wp.array2d[wp.int32],
    counts: wp.array[wp.int32],
    points: wp.array[wp.vec3],
    # outputs
    out: wp.array[wp.int32],
):
    test, lane = wp.tid()
    n = counts[test]
    p = points[test]
    found = int(-1)
    base = int(0)
    while base < n and found < 0:
        k = base + lane
        hit = int(NONE)
        if k < n:
            s = spheres[lists[test, k]]
            d = wp.vec3(s[0], s[1], s[2]) - p
            if wp.dot(d, d) < s[3] * s[3]:
                hit = k
        first = wp.tile_reduce(wp.min, wp.tile(hit))[0]
        if first < NONE:
            found = first
        base += LANES
    if lane == 0:
        out[test] = found


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    args = ap.parse_args()
    wp.config.enable_cpu_blocks = True
    rng = np.random.default_rng(1)
    n_tests, width = 2000, 128
    sph = np.concatenate([rng.uniform(0, 10, (1000, 3)), rng.uniform(0.2, 1.6, (1000, 1))], axis=1).astype(np.float32)
    lists = rng.integers(0, 1000, (n_tests, width)).astype(np.int32)
    counts = rng.integers(0, width + 1, n_tests).astype(np.int32)
    pts = rng.uniform(0, 10, (n_tests, 3)).astype(np.float32)
    ref = np.full(n_tests, -1)
    for t in range(n_tests):
        for k in range(counts[t]):
            s = sph[lists[t, k]]
            d = s[:3] - pts[t]
            if np.float32(d @ d) < s[3] * s[3]:
                ref[t] = k
                break
    dev = args.device
    out = wp.zeros(n_tests, dtype=wp.int32, device=dev)
    inputs = [
        wp.array(sph, dtype=wp.vec4, device=dev),
        wp.array(lists, device=dev),
        wp.array(counts, device=dev),
        wp.array(pts, dtype=wp.vec3, device=dev),
    ]
    wp.launch_tiled(first_blocker, dim=[n_tests], inputs=inputs, outputs=[out], block_dim=LANES, device=dev)
    got = out.numpy()
    same, blocked = int((got == ref).sum()), int((ref >= 0).sum())
    print(f"{dev}: {same} of {n_tests} tests give the serial scan's first blocker; {blocked} have one")


if __name__ == "__main__":
    main()
