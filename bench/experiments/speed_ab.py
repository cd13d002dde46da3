"""Issue 22's A/B on the GPU: stage times of the accurate modes beside criterion 1, and the variants under test.

Every figure is a captured graph replayed (CUDA events, median after warm-up). Stages are timed as graphs of the
steps before them subtracted from graphs that include them, so each stage's figure includes its launch overhead.

    python bench/experiments/speed_ab.py --json $OUT/speed_ab.json

Rows: scene x mode x variant, with ``replay_ms``, ``stages_ms`` and ``ratio`` (over criterion 1 at 4 cells per
diameter on the same scene, in the same run). Variants: the depth pass two rows per step (criterion 1); the area
cell pass with its undecided cells deferred (the default on CUDA) against one thread per cell; the wetted stages.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.scenes import scene_lattice_box, scene_slot_block, scene_sphere_specimen
from warp_lamp.timing import run_header, time_median_events


def _arrays(grid, scene, device):
    pos = wp.array(grid.to_frame(scene.centers).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    return pos, rad


def _replay(fn, device, repeats) -> float:
    fn()
    with wp.ScopedCapture(device=device) as cap:
        fn()
    return 1e3 * time_median_events(lambda: wp.capture_launch(cap.graph), device, repeats=repeats)


def time_lamp(lamp, pos, rad, device, repeats) -> dict:
    """The whole update's replay, and its estimator's steps (cumulative graphs, differences)."""
    lamp.update(pos, rad, in_frame=True)
    total = _replay(lambda: lamp.update(pos, rad, in_frame=True), device, repeats)
    est = lamp.estimator
    stages = {}
    if hasattr(est, "surface"):
        surf = est.surface
        last = 0.0
        for stop in surf.STAGES:
            t = _replay(lambda stop=stop: surf._update(pos, rad, None, stop=stop), device, repeats)
            stages[stop] = t - last
            last = t
    else:
        steps = [getattr(est, f"launch_{s}") for s in est.steps]
        last = 0.0
        for k, name in enumerate(est.steps):
            t = _replay(lambda k=k: [f() for f in steps[: k + 1]], device, repeats)
            stages[name] = t - last
            last = t
    return {"replay_ms": total, "stages_ms": stages}


def run(device, repeats: int, large: bool) -> list[dict]:
    spec = scene_sphere_specimen()
    slot = scene_slot_block()
    scenes = [("specimen d/4", spec, 4.0), ("slot d/4", slot, 4.0)]
    if large:
        box = scene_lattice_box(100)
        scenes.append(("1M cell 0.25", box, 2.0 * float(box.radii.mean()) / 0.25))
    rows = []
    for name, scene, cpd in scenes:
        rbar = float(scene.radii.mean())
        base = None
        cases = [("criterion 1", {}, {})]
        if name != "slot d/4":
            for res in ("subpoints", "exact"):
                # The default on CUDA (undecided cells deferred to a thread per row, blocks of 64) and the one-thread
                # pass of issue 19 (blocks of 256), bitwise the same.
                cases.append((f"area {res}", {"criterion": "area", "resolver": res}, {}))
                one = {"defer": False, "block": 256}
                cases.append((f"area {res}, one thread per cell", {"criterion": "area", "resolver": res}, one))
        cases.append(("wetted rho = r", {"surfaces": "all", "probe_radius": rbar}, {}))
        for tag, opts, variant in cases:
            probe = opts.get("probe_radius", 0.0)
            grid = wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=cpd, probe_radius=probe)
            lamp = wl.ShiningLamp(grid, device=device, **opts)
            if "defer" in variant:
                lamp.estimator.defer = variant["defer"]
            if variant.get("block"):
                lamp.estimator.block_dim = variant["block"]
            pos, rad = _arrays(grid, scene, device)
            row = {"scene": name, "n": int(scene.n), "mode": tag, "cells": int(grid.n_cells)}
            row.update(time_lamp(lamp, pos, rad, device, repeats))
            row["counts_sha"] = __import__("hashlib").sha1(lamp.counts_numpy().tobytes()).hexdigest()[:12]
            if tag == "criterion 1":
                base = row["replay_ms"]
            row["ratio"] = row["replay_ms"] / base if base else None
            rows.append(row)
            st = " ".join(f"{k} {v:.4f}" for k, v in row["stages_ms"].items())
            print(f"| {name} | {tag} | {row['replay_ms']:.4f} | {row['ratio']:.2f} | {st} | {row['counts_sha']} |")
            del lamp
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--no-large", action="store_true")
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    print("| scene | mode | replay ms | x c1 | stages ms | counts |")
    print("| --- | --- | --- | --- | --- | --- |")
    rows = run(args.device, args.repeats, not args.no_large)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump({"header": run_header([args.device]), "rows": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
