"""Graph-replay times of the lamp's modes on the benchmark scenes, through the public API only, so that the same
script times two versions of the code in one lease (issue 21: "graph replays within 3%, in one run").

    PYTHONPATH=<checkout> python bench/experiments/replay.py --label before --json before.json
    python bench/experiments/replay.py --label after --json after.json
    python bench/experiments/replay.py --compare before.json after.json

Each row: a scene, a mode and a grid; the update captured once and replayed, CUDA events, median of repeats after
a warm-up (``warp_lamp.timing.time_median_events``).
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.scenes import scene_lattice_box, scene_slot_block, scene_sphere_specimen
from warp_lamp.timing import time_median_events


def _cases(large: bool):
    spec = scene_sphere_specimen()
    slot = scene_slot_block()
    r_spec = float(spec.radii.mean())
    r_slot = float(slot.radii.mean())
    out = [
        ("specimen d/4 c1", spec, 4, {}),
        ("specimen d/16 c1", spec, 16, {}),
        ("specimen d/4 area", spec, 4, {"criterion": "area"}),
        ("specimen d/4 wetted r", spec, 4, {"surfaces": "all", "probe_radius": r_spec}),
        ("slot d/4 c1", slot, 4, {}),
        ("slot d/4 wetted r", slot, 4, {"surfaces": "all", "probe_radius": r_slot}),
    ]
    if large:
        box = scene_lattice_box(100)
        d = 2.0 * float(box.radii.mean())
        out += [
            ("1M cell 0.25 c1", box, d / 0.25, {}),
            ("1M cell 0.25 area", box, d / 0.25, {"criterion": "area"}),
            ("1M cell 0.25 wetted r", box, d / 0.25, {"surfaces": "all", "probe_radius": 0.5 * d}),
        ]
    return out


def run(device: str, *, repeats: int, large: bool) -> list[dict]:
    rows = []
    for name, scene, cpd, opts in _cases(large):
        probe = opts.get("probe_radius", 0.0)
        grid = wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=cpd, probe_radius=probe)
        for _ in range(1):
            lamp = wl.ShiningLamp(grid, device=device, **opts)
            pos = wp.array(grid.to_frame(scene.centers).astype(np.float32), dtype=wp.vec3, device=device)
            rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
            lamp.update(pos, rad, in_frame=True)
            with wp.ScopedCapture(device=device) as cap:
                lamp.update(pos, rad, in_frame=True)
            t = time_median_events(lambda cap=cap: wp.capture_launch(cap.graph), device, repeats=repeats)
            counts = lamp.counts_numpy()
            rows.append(
                {
                    "case": name,
                    "n": int(scene.n),
                    "cells": int(grid.n_cells),
                    "replay_ms": 1e3 * t,
                    "counts_sha": __import__("hashlib").sha1(counts.tobytes()).hexdigest()[:12],
                }
            )
            print(f"| {rows[-1]['case']} | {scene.n:,} | {grid.n_cells:,} | {1e3 * t:.4f} | {rows[-1]['counts_sha']} |")
            del lamp
    return rows


def compare(a_path: str, b_path: str) -> None:
    a = {r["case"]: r for r in json.load(open(a_path, encoding="utf-8"))["rows"]}
    b = {r["case"]: r for r in json.load(open(b_path, encoding="utf-8"))["rows"]}
    print("| case | before ms | after ms | after / before | counts equal |")
    print("| --- | --- | --- | --- | --- |")
    for k, rb in b.items():
        ra = a.get(k)
        if ra is None:
            continue
        same = "yes" if ra["counts_sha"] == rb["counts_sha"] else "NO"
        ratio = rb["replay_ms"] / ra["replay_ms"]
        print(f"| {k} | {ra['replay_ms']:.4f} | {rb['replay_ms']:.4f} | {ratio:.3f} | {same} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--repeats", type=int, default=50)
    ap.add_argument("--label", default="")
    ap.add_argument("--json")
    ap.add_argument("--no-large", action="store_true")
    ap.add_argument("--compare", nargs=2)
    args = ap.parse_args(argv)
    if args.compare:
        compare(*args.compare)
        return 0
    wp.config.log_level = wp.LOG_WARNING
    rows = run(args.device, repeats=args.repeats, large=not args.no_large)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump({"label": args.label, "device": wp.get_device(args.device).name, "rows": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
