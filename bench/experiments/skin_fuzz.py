"""Fuzz (CPU): the skin against from-scratch updates over random DEM-like runs, bitwise at every step.

Random scenes from ``wetted_fuzz_knobs.draw_scene`` (polydisperse spheres, jittered lattices, bodies touching the
box's edge, anisotropic voxels, probe radii 0.05 to 0.8 diameters, a tilted wall in 30%; half a unit more margin
here), then 6 to 14 steps of moves drawn per step from: every sphere a random step of 0.02 to 0.6 skins, a few
spheres jumping a radius, a sphere switched off or on, nothing at all; the skinned surface (default skin, the exact
tests queued for some threads in half the runs: CUDA's layout) is compared with a fresh one after every step (fluid
words, counts, hits). Counts how often each kind of kept decision was used. Arguments: seed, seconds.

    PYTHONPATH=$PWD python bench/experiments/skin_fuzz.py 3 600
"""

import sys
import time

import numpy as np
import warp as wp
from wetted_fuzz_knobs import draw_scene  # this folder: the same random scenes

from warp_lamp.wetted import WettedSurface, cross_list_capacity, exact_queue_capacity

wp.config.quiet = True


def main():
    rng = np.random.default_rng(int(sys.argv[1]) if len(sys.argv) > 1 else 0)
    t_end = time.time() + float(sys.argv[2] if len(sys.argv) > 2 else 300)
    runs = steps = bad = 0
    used = {"kept": 0, "held": 0, "witnessed": 0, "cross_kept": 0, "resets": 0}
    while time.time() < t_end:
        _kind, c, r, h, rho, _margin, grid, walls = draw_scene(rng, extra=0.5)
        skinned = WettedSurface(grid, probe_radius=rho, device="cpu", walls=walls, skin="auto")
        fresh = WettedSurface(grid, probe_radius=rho, device="cpu", walls=walls)
        if rng.random() < 0.5:
            skinned._exact_queue(exact_queue_capacity(skinned.shape, None), int(rng.integers(1, 9)))
            skinned._cross_list(cross_list_capacity(skinned._faces, None))
            skinned._bits = 4
        skin = skinned.skin
        active = np.ones(len(r), dtype=np.int32)
        runs += 1
        for _ in range(int(rng.integers(6, 15))):
            move = rng.integers(5)
            if move == 0 and skin > 0:
                c = c + rng.uniform(-1, 1, c.shape) * rng.uniform(0.02, 0.6) * skin / np.sqrt(3.0)
            elif move == 1:
                j = rng.integers(len(r), size=int(rng.integers(1, 4)))
                c[j] += rng.normal(scale=r.mean(), size=(len(j), 3))
            elif move == 2:
                active[rng.integers(len(r))] ^= 1
            elif move == 3 and skin > 0:
                c = c + rng.normal(scale=0.05 * skin, size=c.shape)
            pos = wp.array(grid.to_frame(c).astype(np.float32), dtype=wp.vec3, device="cpu")
            rad = wp.array(r.astype(np.float32), device="cpu")
            act = wp.array(active, device="cpu")
            skinned.update(pos, rad, act)
            fresh.update(pos, rad, act)
            a, b = skinned.diagnostics(), fresh.diagnostics()
            steps += 1
            same = (
                np.array_equal(skinned.fluid.numpy(), fresh.fluid.numpy())
                and np.array_equal(a.counts, b.counts)
                and np.array_equal(a.hits, b.hits)
            )
            if not same:
                bad += 1
                print(f"MISMATCH run {runs} step {steps}: rho {rho:.3g} h {h} walls {walls is not None}", flush=True)
            used["kept"] += a.skin_kept
            used["held"] += a.skin_held
            used["witnessed"] += a.skin_witnessed
            used["cross_kept"] += a.skin_cross_kept
            used["resets"] += int(a.skin_reset)
    print(f"{runs} runs, {steps} steps, {bad} mismatching; decisions used: {used}")


if __name__ == "__main__":
    main()
