"""Issue 11 A/B: the v4 depth pass (one thread per sphere, row filter) against shared rows (``split``), a work
order sorted by cell (``order``), one run, one device (the coarse depth buffer, ``culling``, was removed in v5f).

Every variant must reproduce the v4 keys and counts bitwise (checked); times are CUDA-event medians of captured
graph replays: "replay" updates a static body (warm owners), "moving" alternates two position sets 1% of a radius
apart, "cold" forgets the owners first. Small bodies: the SphereTest specimen at 2, 4, 8, 16 cells per diameter;
large: the jittered lattice box at cell 0.25 (1M and 8M) and at d/16 (1M).

    python bench/experiments/depth_blocks.py --json out.json
"""

import argparse
import json

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.bench import lattice_grid
from warp_lamp.scenes import scene_lattice_box, scene_sphere_specimen
from warp_lamp.timing import run_header, time_median_events

wp.config.log_level = wp.LOG_WARNING


def scenes(quick):
    spec = scene_sphere_specimen()
    for k in (2, 4, 8, 16):
        yield f"specimen d/{k}", spec, wl.LampGrid.enclosing(spec.centers, spec.radii, cells_per_diameter=k)
    if quick:
        return
    box = scene_lattice_box(100)
    yield "lattice 1M cell 0.25", box, lattice_grid(box, 0.25)
    yield "lattice 1M d/16", box, lattice_grid(box, 2 * float(box.radii.mean()) / 16)
    big = scene_lattice_box(200)
    yield "lattice 8M cell 0.25", big, lattice_grid(big, 0.25)


def variants(n, device):
    yield "v4", {"split": 0, "order": False}
    yield "s1", {"split": 1, "order": False}
    yield "s1 sorted", {"split": 1, "order": True}
    if n < 200_000:
        for s in (8, 16):
            yield f"s{s}", {"split": s, "order": False}
    else:
        yield "s2 sorted", {"split": 2, "order": True}
    yield "auto", {}


def time_variant(scene, grid, options, device, repeats):
    lamp = wl.ShiningLamp(grid, device=device, **options)
    pos = wp.array((scene.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
    jitter = np.random.default_rng(5).normal(scale=0.01 * float(scene.radii.mean()), size=scene.centers.shape)
    moved = wp.array((scene.centers + jitter - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    lamp.update(pos, rad, in_frame=True)
    with wp.ScopedCapture(device=device) as cap:
        lamp.update(pos, rad, in_frame=True)
    with wp.ScopedCapture(device=device) as cap_moving:
        lamp.update(moved, rad, in_frame=True)
        lamp.update(pos, rad, in_frame=True)
    with wp.ScopedCapture(device=device) as cap_cold:
        lamp.forget()
        lamp.update(pos, rad, in_frame=True)
    out = {
        "replay_s": time_median_events(lambda: wp.capture_launch(cap.graph), device, repeats=repeats),
        "moving_s": time_median_events(lambda: wp.capture_launch(cap_moving.graph), device, repeats=repeats) / 2,
        "cold_s": time_median_events(lambda: wp.capture_launch(cap_cold.graph), device, repeats=max(5, repeats // 3)),
    }
    wp.capture_launch(cap.graph)
    return out, lamp.keys.numpy(), lamp.counts_numpy(), lamp.split


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--json")
    args = parser.parse_args()
    device = wp.get_device("cuda:0" if wp.get_cuda_device_count() else "cpu")
    rows = []
    for name, scene, grid in scenes(args.quick):
        reps = 30 if grid.n_cells < 5_000_000 else 12
        ref = None
        for vname, options in variants(scene.n, device):
            t, keys, counts, split = time_variant(scene, grid, options, device, reps)
            if ref is None:
                ref = (keys, counts)
            same = bool(np.array_equal(keys, ref[0]) and np.array_equal(counts, ref[1]))
            row = {"scene": name, "n": scene.n, "cells": grid.n_cells, "variant": vname, "split": split, "same": same}
            row.update(t)
            rows.append(row)
            print(
                f"{name:<22} {vname:<18} split {split:>2}  replay {t['replay_s'] * 1e3:8.4f}  moving "
                f"{t['moving_s'] * 1e3:8.4f}  cold {t['cold_s'] * 1e3:8.4f} ms  same {same}",
                flush=True,
            )
    if args.json:
        with open(args.json, "w") as f:
            json.dump({**run_header([device]), "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
