"""Fuzz (CPU): the exact test's reach masks (always, never) and the queue (none, in voxel order, in the atomics'
order, too small) give the same fluid map and counts on random scenes: polydisperse spheres, lattices jittered by
1e-6 to 1e-1 of their spacing, bodies touching the box's edge, anisotropic voxels, probe radii from 0.05 to 0.8
diameters, a tilted wall in 30% of them. Arguments: seed, seconds.

    PYTHONPATH=$PWD python bench/experiments/wetted_fuzz_knobs.py 7 400
"""

import hashlib
import sys
import time

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.validate import check_walls
from warp_lamp.wetted import WettedSurface

wp.config.quiet = True


def draw_scene(rng, extra=0.0):
    """A random body and its box: polydisperse spheres, a jittered lattice or a small dense clump (``kind`` 0, 1,
    2), voxels isotropic or not, a probe radius of 0.05 to 0.8 diameters, a margin of 0 (the body touching the box's
    edge), 0.3 or 1 (plus ``extra``), and a tilted wall in 30%. Returns kind, centres, radii, h, rho, margin, grid,
    walls (None or checked planes)."""
    kind = rng.integers(3)
    if kind == 0:
        n = int(rng.integers(40, 160))
        c = rng.uniform(0, 4, (n, 3))
        r = rng.uniform(0.2, 0.6, n)
    elif kind == 1:
        m = int(rng.integers(3, 6))
        idx = np.stack(np.meshgrid(*[np.arange(m)] * 3, indexing="ij"), -1).reshape(-1, 3).astype(float)
        c = idx + rng.uniform(-1, 1, idx.shape) * 10.0 ** rng.uniform(-6, -1)
        r = np.full(len(c), 0.5)
    else:
        n = int(rng.integers(20, 80))
        c = rng.uniform(0, 2, (n, 3))
        r = rng.uniform(0.3, 0.5, n)
    h = rng.uniform(0.12, 0.3, 3) if rng.random() < 0.5 else np.full(3, rng.uniform(0.12, 0.3))
    rho = float(rng.choice([0.05, 0.15, 0.3, 0.5, 0.8]) * r.mean() * 2)
    margin = float(rng.choice([0.0, 0.3, 1.0]))  # 0: the body touches the box's edge
    pad = r.max() + margin + extra
    grid = wl.LampGrid(c.min(0) - pad, c.max(0) + pad, h)
    walls = None
    if rng.random() < 0.3:
        p = c.mean(0) + rng.uniform(-1, 1, 3)
        nrm = rng.normal(size=3)
        walls = check_walls([(tuple(p), tuple(nrm))])
    return kind, c, r, h, rho, margin, grid, walls


def main():
    rng = np.random.default_rng(int(sys.argv[1]) if len(sys.argv) > 1 else 0)
    t_end = time.time() + float(sys.argv[2] if len(sys.argv) > 2 else 300)
    cases = bad = 0
    while time.time() < t_end:
        kind, c, r, h, rho, margin, grid, walls = draw_scene(rng)
        pos = wp.array(grid.to_frame(c).astype(np.float32), dtype=wp.vec3, device="cpu")
        rad = wp.array(r.astype(np.float32), device="cpu")
        s = (
            WettedSurface(grid, probe_radius=rho, device="cpu", walls=walls)
            if walls is not None
            else WettedSurface(grid, probe_radius=rho, device="cpu")
        )
        out = []
        for mask_from, cap, ordered in (
            (1 << 20, 0, True),
            (0, 0, True),
            (0, 1 << 20, True),
            (1 << 20, 1 << 20, False),
            (0, 200, True),
        ):
            s._box.mask_from = mask_from
            s._exact_queue(cap)
            s._queue_in_order(ordered)
            s.update(pos, rad)
            d = s.diagnostics()
            out.append(hashlib.sha1(d.fluid.tobytes() + d.counts.tobytes()).hexdigest())
        cases += 1
        if len(set(out)) != 1:
            bad += 1
            print("MISMATCH", kind, len(c), h, rho, margin, walls is not None, out, flush=True)
    print(f"{cases} cases, {bad} mismatching")


if __name__ == "__main__":
    main()
