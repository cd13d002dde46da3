"""The area criterion against refinement on one device, in one JSON: the rows of the speed-error targets (graph
replay), the stage table (seed / depth / cells), and the speed-error table's times for this device kind merged into
the shipped table, with what ``tolerance=`` then chooses.

Rows: the SphereTest specimen with criterion 1 at 4 / 16 / 32 cells per diameter, the area criterion's sub-points
(D = 3, 8 x 8) at 3 and 4 and its exact resolver (D = 4) at 4; the 1M lattice box (cells of 0.25 diameters) with
criterion 1 and the sub-points (CUDA only, unless ``--large``). And the gathers that find the lattice balls'
buried spheres (off by default, ``AreaSplit.hidden_rounds`` and ``gather_both``), whose cost is not yet known.
Errors are not measured here (the shipped table's, device-independent, ``warp_lamp/data/speed_error.json``, and
``bench/results/experiments/cpu-2026-11-28-area-gather.json`` for the new gathers).

    python bench/experiments/area33_gpu.py --device cuda:0 --json $OUT/area33.json       # the lease part
    python bench/experiments/area33_gpu.py --device cpu --quick --json /tmp/a.json     # a dry run here
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.bench import lattice_grid
from warp_lamp.scenes import scene_lattice_box, scene_sphere_specimen
from warp_lamp.timing import run_header, time_median_events

ROOT = Path(__file__).resolve().parents[2]

_BOTH = {"criterion": "area", "resolver": "subpoints", "subpoints": 8, "hidden_rounds": 2, "gather_both": True}
#: (label, lamp options, cells per diameter) on the specimen.
SPECIMEN_ROWS = (
    ("criterion 1", {"criterion": 1}, 4),
    ("criterion 1", {"criterion": 1}, 16),
    ("criterion 1", {"criterion": 1}, 32),
    ("area sub-points S8 D3", {"criterion": "area", "resolver": "subpoints", "depth_slots": 3, "subpoints": 8}, 3),
    ("area sub-points S8 D3", {"criterion": "area", "resolver": "subpoints", "depth_slots": 3, "subpoints": 8}, 4),
    ("area exact D4", {"criterion": "area", "resolver": "exact", "depth_slots": 4}, 4),
    (
        "area sub-points S8 D3 hidden 2",
        {"criterion": "area", "resolver": "subpoints", "depth_slots": 3, "subpoints": 8, "hidden_rounds": 2},
        4,
    ),
    ("area exact D4 hidden 2", {"criterion": "area", "resolver": "exact", "depth_slots": 4, "hidden_rounds": 2}, 4),
    ("area sub-points S8 D4 both hidden 2", {**_BOTH, "depth_slots": 4}, 4),
)
#: The 1M lattice box's rows (cells of 0.25 diameters: 4 per diameter).
LATTICE_ROWS = (
    ("criterion 1", {"criterion": 1}),
    ("area sub-points S8 D3", {"criterion": "area", "resolver": "subpoints", "depth_slots": 3, "subpoints": 8}),
    (
        "area sub-points S8 D3 hidden 2",
        {"criterion": "area", "resolver": "subpoints", "depth_slots": 3, "subpoints": 8, "hidden_rounds": 2},
    ),
    ("area sub-points S8 D4 both hidden 2", {**_BOTH, "depth_slots": 4}),
)


def _lamp(grid, options, device) -> wl.ShiningLamp:
    # hidden_rounds and gather_both are the area estimator's attributes, not lamp options.
    opts = dict(options)
    rounds = opts.pop("hidden_rounds", 0)
    both = opts.pop("gather_both", False)
    lamp = wl.ShiningLamp(grid, device=device, **opts)
    if rounds:
        lamp.estimator.hidden_rounds = rounds
    if both:
        lamp.estimator.gather_both = True
    return lamp


def stages(scene, grid, options, device, repeats) -> dict:
    """Seed, depth (with the hidden rounds) and cell pass, each the difference of captured graphs (as
    ``area_stages.py``)."""
    lamp = _lamp(grid, options, device)
    pos = wp.array(grid.to_frame(scene.centers).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    lamp.update(pos, rad, in_frame=True)
    steps = (lamp.launch_seed, lamp.launch_depth, lamp.launch_scatter)
    t = {}
    for k, name in enumerate(("seed", "depth", "cells")):
        with wp.ScopedCapture(device=device) as cap:
            for step in steps[: k + 1]:
                step()
        t[name] = time_median_events(lambda c=cap: wp.capture_launch(c.graph), device, repeats=repeats)
    return {"seed_s": t["seed"], "depth_s": t["depth"] - t["seed"], "cells_s": t["cells"] - t["depth"]}


def _update_time(scene, grid, options, device, repeats) -> float:
    # Graph replay on CUDA (CUDA-event median); eager on the CPU (wall-clock median): not comparable.
    lamp = _lamp(grid, options, device)
    pos = wp.array(grid.to_frame(scene.centers).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    lamp.update(pos, rad, in_frame=True)
    if device.is_cuda:
        with wp.ScopedCapture(device=device) as cap:
            lamp.update(pos, rad, in_frame=True)
        return time_median_events(lambda: wp.capture_launch(cap.graph), device, repeats=repeats)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        lamp.update(pos, rad, in_frame=True)
        wp.synchronize_device(device)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def timed_rows(device, repeats: int, *, large: bool, quick: bool) -> list[dict]:
    """The specimen's rows and, with ``large``, the 1M lattice box's: update time and, on CUDA, the stages."""
    rows = []
    spec = scene_sphere_specimen()
    plan = [("specimen", spec, k, label, opts) for label, opts, k in SPECIMEN_ROWS]
    if quick:
        plan = [p for p in plan if p[2] <= 4]
    if large:
        box = scene_lattice_box(100)
        plan += [("lattice 1M", box, 4, label, opts) for label, opts in LATTICE_ROWS]
    for scene_name, scene, k, label, opts in plan:
        if scene_name == "lattice 1M":
            grid = lattice_grid(scene, 0.25)
        else:
            grid = wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=k)
        row = {"scene": scene_name, "setting": label, "cells_per_diameter": k, "options": opts}
        row["update_s"] = _update_time(scene, grid, opts, device, repeats)
        if device.is_cuda:
            row["stages"] = stages(scene, grid, opts, device, repeats)
        rows.append(row)
        st = row.get("stages")
        extra = (
            ""
            if st is None
            else (f"  seed {st['seed_s'] * 1e3:.3f} depth {st['depth_s'] * 1e3:.3f} cells {st['cells_s'] * 1e3:.3f}")
        )
        print(f"{scene_name:<11} {label:<36} {k:>3} cells/d  update {row['update_s'] * 1e3:8.3f} ms{extra}", flush=True)
    # Ratios over criterion 1 at 4 cells per diameter on the same scene and device.
    for scene_name in {r["scene"] for r in rows}:
        base = [r for r in rows if r["scene"] == scene_name and r["options"] == {"criterion": 1}]
        base = [r for r in base if r["cells_per_diameter"] == 4]
        for r in rows:
            if r["scene"] == scene_name and base:
                r["ratio"] = r["update_s"] / base[0]["update_s"]
    return rows


def tolerance_table(device, repeats: int) -> dict:
    """The shipped speed-error table with this device kind's times merged in (``merge_kind``), and the choices
    of ``tolerance=`` for this kind (errors: the table's)."""
    from warp_lamp.bench.tolerance import merge_kind
    from warp_lamp.tolerance import TABLE_PATH, choose_settings

    with open(TABLE_PATH, encoding="utf-8") as f:
        table = json.load(f)
    table = merge_kind(table, device, repeats=repeats)
    choices = {}
    for tol in (0.02, 0.01, 0.005):
        try:
            choices[str(tol)] = choose_settings(tol, device, table=table).describe()
        except ValueError as e:
            choices[str(tol)] = f"none: {e}"
    return {"table": table, "choices": choices}


def run_tests(device, limit_s: int) -> dict:
    """tests/test_area.py and tests/test_tolerance.py on this device's parameters (and device-free tests)."""
    sel = "not cpu" if device.is_cuda else "cpu"
    cmd = [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", "-k", sel]
    cmd += ["tests/test_area.py", "tests/test_tolerance.py"]
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=limit_s)
        rc, out = p.returncode, p.stdout + p.stderr
    except subprocess.TimeoutExpired as e:
        rc, out = 124, (e.stdout or b"").decode() if isinstance(e.stdout, bytes) else (e.stdout or "")
    tail = out.strip().splitlines()[-15:]
    print("\n".join(tail), flush=True)
    return {"command": " ".join(cmd), "rc": rc, "seconds": time.perf_counter() - t0, "tail": tail}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--json", required=True)
    ap.add_argument("--quick", action="store_true", help="specimen rows to 4 cells/d only, no table (a dry run)")
    ap.add_argument("--large", action="store_true", help="the 1M lattice box even on the CPU")
    ap.add_argument("--tests-limit", type=int, default=200, help="seconds for the tests (0: skip them)")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    wp.config.quiet = True
    device = wp.get_device(args.device)
    out = {"device": run_header([device]), "note": "CUDA: graph replay, CUDA-event medians; CPU: eager wall clock"}
    t0 = time.perf_counter()

    def save():
        out["seconds"] = time.perf_counter() - t0
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump(out, f, indent=1)

    # Each section saved as it ends, so that a part cut off by its time limit still returns what it measured.
    out["rows"] = timed_rows(device, args.repeats, large=args.large or device.is_cuda, quick=args.quick)
    save()
    if not args.quick:
        tol = tolerance_table(device, max(3, args.repeats // 6))
        out["speed_error"] = tol["table"]
        out["choices"] = tol["choices"]
        print("tolerance= on this kind:", json.dumps(tol["choices"], indent=1), flush=True)
        save()
    if args.tests_limit > 0:
        out["tests"] = run_tests(device, args.tests_limit)
        save()
    print("\n| scene | setting | cells/d | update ms | x criterion 1 at 4 |")
    print("| --- | --- | --- | --- | --- |")
    for r in out["rows"]:
        print(
            f"| {r['scene']} | {r['setting']} | {r['cells_per_diameter']} | {r['update_s'] * 1e3:.3f} | "
            f"{r.get('ratio', float('nan')):.2f} |"
        )
    return 0 if out.get("tests", {}).get("rc", 0) == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
