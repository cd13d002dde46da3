"""The area criterion's cell pass, one thread per cell (``cell_pass="cells"``, shipped) against one thread per
(lamp, cell) (``"sides"``), and hidden rounds from emptied slots against the kept keys (``hidden_warm``), in one run
on one device: update and cell-pass times (graph replay on CUDA), and
whether the two give bitwise the same counts and counters. Then, with the faster pass, the speed-error table's
times for this device kind merged into the shipped table (a candidate for ``warp_lamp/data/speed_error.json``) and
what ``tolerance=`` would choose with it.

Rows: the SphereTest specimen at 3 and 4 cells per diameter with sub-points D = 3, sub-points D = 4 with the deep
gather (the table's only sub-point rows eligible for a 1% tolerance) and the exact resolver D = 4; criterion 1 at
4 and 32 cells per diameter for the ratios; the 1M lattice box (cells of 0.25 diameters) with criterion 1 and
sub-points D = 3 and D = 4 deep (CUDA, or ``--large``).

    python bench/experiments/cell33_gpu.py --device cuda:0 --json $OUT/cell33.json --table $OUT/cell33_table.json
    python bench/experiments/cell33_gpu.py --device cpu --quick --json /tmp/c.json --table /tmp/t.json   # dry run
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.bench import lattice_grid
from warp_lamp.estimators import AreaSplit
from warp_lamp.scenes import scene_lattice_box, scene_sphere_specimen
from warp_lamp.timing import run_header, time_median_events

ROOT = Path(__file__).resolve().parents[2]
#: The variants timed on every area row: (cell_pass, subpoint_rows, block_dim on CUDA, hidden_warm). "old" is the
#: code before this branch (one thread per cell, hidden rounds from emptied slots), the baseline of the bitwise check.
VARIANTS = {
    "old": ("cells", True, 64, False),
    "warm": ("cells", True, 64, True),
    "sides": ("sides", False, 64, True),
    "sides+rows": ("sides", True, 64, True),
    "sides+rows b32": ("sides", True, 32, True),
    "sides+rows b128": ("sides", True, 128, True),
}
PASSES = tuple(VARIANTS)
#: The variants the speed-error table may be re-measured with (the estimator's class defaults can express them).
TABLE_VARIANTS = ("old", "warm", "sides", "sides+rows")
_S3 = {"criterion": "area", "resolver": "subpoints", "depth_slots": 3, "subpoints": 8}
_DEEP = {"criterion": "area", "resolver": "subpoints", "depth_slots": 4, "subpoints": 8, "gather": "deep"}
_EXACT = {"criterion": "area", "resolver": "exact", "depth_slots": 4}
#: (label, lamp options) of the area rows, each at 3 and 4 cells per diameter on the specimen.
AREA_ROWS = (("sub-points D3", _S3), ("sub-points D4 deep", _DEEP), ("exact D4", _EXACT))


def _arrays(scene, grid, device):
    pos = wp.array(grid.to_frame(scene.centers).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    return pos, rad


def _replay(fn, device, repeats: int) -> float:
    # Graph replay on CUDA (CUDA-event median); eager wall clock on the CPU (not comparable).
    fn()
    if device.is_cuda:
        with wp.ScopedCapture(device=device) as cap:
            fn()
        return time_median_events(lambda: wp.capture_launch(cap.graph), device, repeats=repeats)
    return time_median_events(fn, device, repeats=repeats)


def _state(lamp) -> tuple[np.ndarray, tuple]:
    d = lamp.diagnostics()
    return lamp.counts_numpy().copy(), (d.area_overflow, d.area_one_sided) if hasattr(d, "area_overflow") else ()


def measure(scene, grid, options, device, repeats: int, variant: str | None) -> dict:
    """One setting: update time, cell-pass time (the scatter step alone, replayed), and the counts' hash."""
    lamp = wl.ShiningLamp(grid, device=device, **options)
    cell_pass = None
    if variant is not None:
        cell_pass, rows, block, warm = VARIANTS[variant]
        lamp.estimator.cell_pass = cell_pass
        lamp.estimator.subpoint_rows = rows
        lamp.estimator.hidden_warm = warm
        if device.is_cuda:
            lamp.estimator.block_dim = block
    pos, rad = _arrays(scene, grid, device)
    lamp.update(pos, rad, in_frame=True)
    counts, diag = _state(lamp)
    out = {"update_s": _replay(lambda: lamp.update(pos, rad, in_frame=True), device, repeats)}
    # The counts after the replays: a check that nothing depends on what ran before.
    lamp.update(pos, rad, in_frame=True)
    again, diag2 = _state(lamp)
    out["stable"] = bool(np.array_equal(counts, again) and diag == diag2)
    if cell_pass is not None:
        # The cell pass alone on the keys the update left (its counts then add up; they were hashed before).
        out["cells_s"] = _replay(lamp.estimator.launch_scatter, device, repeats)
    out["hash"] = hashlib.sha256(counts.tobytes()).hexdigest()[:16]
    out["diag"] = list(diag)
    out["_counts"] = counts
    return out


def timed_rows(device, repeats: int, *, large: bool, quick: bool, log) -> list[dict]:
    rows = []
    spec = scene_sphere_specimen()
    plan = [("specimen", spec, k, "criterion 1", {"criterion": 1}) for k in ((4,) if quick else (4, 32))]
    for k in (4,) if quick else (3, 4):
        plan += [("specimen", spec, k, label, opts) for label, opts in AREA_ROWS]
    if large:
        box = scene_lattice_box(100)
        plan += [("lattice 1M", box, 4, "criterion 1", {"criterion": 1}), ("lattice 1M", box, 4, "sub-points D3", _S3)]
        plan += [("lattice 1M", box, 4, "sub-points D4 deep", _DEEP)]
    grids = {}
    for scene_name, scene, k, label, opts in plan:
        key = (scene_name, k)
        if key not in grids:
            grids[key] = (
                lattice_grid(scene, 0.25)
                if scene_name == "lattice 1M"
                else wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=k)
            )
        grid = grids[key]
        row = {"scene": scene_name, "setting": label, "cells_per_diameter": k, "options": opts}
        if opts["criterion"] == 1:
            row["update_s"] = measure(scene, grid, opts, device, repeats, None)["update_s"]
            log(f"{scene_name:<11} {label:<20} {k:>3} cells/d  update {row['update_s'] * 1e3:8.3f} ms")
        else:
            res = {p: measure(scene, grid, opts, device, repeats, p) for p in PASSES}
            base = res["old"]["_counts"]
            row["bitwise"] = all(
                np.array_equal(v["_counts"], base) and v["diag"] == res["old"]["diag"] for v in res.values()
            )
            for v in res.values():
                v.pop("_counts")
            row["passes"] = res
            cells = " / ".join(f"{res[p]['cells_s'] * 1e3:.3f}" for p in PASSES)
            log(
                f"{scene_name:<11} {label:<20} {k:>3} cells/d  update {res['old']['update_s'] * 1e3:8.3f} -> "
                f"{res['sides+rows']['update_s'] * 1e3:8.3f} ms; cell pass {cells} ms ({' / '.join(PASSES)})  "
                f"bitwise {row['bitwise']}  stable {all(v['stable'] for v in res.values())}"
            )
        rows.append(row)
    for r in rows:
        base = [b for b in rows if b["scene"] == r["scene"] and b["options"] == {"criterion": 1}]
        base = [b for b in base if b["cells_per_diameter"] == 4]
        if base:
            t0 = base[0]["update_s"]
            if "passes" in r:
                r["ratio"] = {p: r["passes"][p]["update_s"] / t0 for p in PASSES}
            else:
                r["ratio"] = r["update_s"] / t0
    return rows


def faster_pass(rows) -> str:
    """Among :data:`TABLE_VARIANTS`, the one with the smallest update times over the specimen's sub-point rows (the
    geometric mean of the ratios to the shipped pass: the exact rows, ten times slower, are never the cheapest
    choice of ``tolerance=``; ties: the shipped one)."""
    sub = [x for x in rows if "passes" in x and x["scene"] == "specimen" and x["options"]["resolver"] == "subpoints"]
    if not sub:
        return "old"
    score = {
        v: float(np.mean([np.log(x["passes"][v]["update_s"] / x["passes"]["old"]["update_s"]) for x in sub]))
        for v in TABLE_VARIANTS
    }
    return min(TABLE_VARIANTS, key=lambda v: (score[v], v != "old"))


def table_with(variant: str, device, repeats: int) -> dict:
    """The shipped speed-error table with this kind's times re-measured with a cell-pass ``variant``, and the
    choices of ``tolerance=`` with the shipped table and with this one."""
    from warp_lamp.bench.tolerance import _kind_of, merge_kind
    from warp_lamp.tolerance import TABLE_PATH, choose_settings

    with open(TABLE_PATH, encoding="utf-8") as f:
        shipped = json.load(f)
    keep = AreaSplit.CELL_PASS, AreaSplit.SUBPOINT_ROWS, AreaSplit.HIDDEN_WARM
    cell_pass, rows, _block, warm = VARIANTS[variant]
    AreaSplit.CELL_PASS, AreaSplit.SUBPOINT_ROWS, AreaSplit.HIDDEN_WARM = cell_pass, rows, warm
    try:
        table = merge_kind(copy.deepcopy(shipped), device, repeats=repeats)
    finally:
        AreaSplit.CELL_PASS, AreaSplit.SUBPOINT_ROWS, AreaSplit.HIDDEN_WARM = keep
    kind = _kind_of(device)
    table["kinds"][kind].update(cell_pass=cell_pass, subpoint_rows=rows, hidden_warm=warm)
    choices = {}
    for tol in (0.02, 0.01, 0.005):
        for name, t in (("shipped", shipped), ("candidate", table)):
            try:
                choices[f"{name} {tol}"] = choose_settings(tol, device, table=t).describe()
            except ValueError as e:
                choices[f"{name} {tol}"] = f"none: {str(e)[:90]}"
    return {"table": table, "choices": choices, "kind": kind}


def run_tests(device, limit_s: int) -> dict:
    """The area tests of the two passes, the deferred cells and CPU = CUDA, on every device present (the CPU's
    share of them runs in about 12 s on the dev machine)."""
    sel = "side_pass or cell_pass or deferred or bitwise"
    cmd = [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", "-k", sel, "tests/test_area.py"]
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=limit_s)
        rc, out = p.returncode, p.stdout + p.stderr
    except subprocess.TimeoutExpired as e:
        rc, out = 124, e.stdout.decode() if isinstance(e.stdout, bytes) else (e.stdout or "")
    tail = out.strip().splitlines()[-8:]
    return {"command": " ".join(cmd), "rc": rc, "seconds": time.perf_counter() - t0, "tail": tail}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--json", required=True)
    ap.add_argument("--table", help="write the candidate speed-error table here (JSON)")
    ap.add_argument("--quick", action="store_true", help="4 cells/d only, table repeats 1 (a dry run)")
    ap.add_argument("--large", action="store_true", help="the 1M lattice box even on the CPU")
    ap.add_argument("--budget", type=float, default=270.0, help="seconds: skip the table past this")
    ap.add_argument("--tests-limit", type=int, default=90, help="seconds for the tests (0: skip them)")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    wp.config.quiet = True
    device = wp.get_device(args.device)
    t_start = time.perf_counter()
    out = {"device": run_header([device]), "note": "CUDA: graph replay, CUDA-event medians; CPU: eager wall clock"}

    def log(msg):
        print(f"[{time.perf_counter() - t_start:6.1f} s] {msg}", flush=True)

    def save():
        out["seconds"] = time.perf_counter() - t_start
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump(out, f, indent=1)

    out["rows"] = timed_rows(device, args.repeats, large=args.large or device.is_cuda, quick=args.quick, log=log)
    out["bitwise_all"] = all(r.get("bitwise", True) for r in out["rows"])
    out["faster_pass"] = faster_pass(out["rows"])
    save()
    if args.table and time.perf_counter() - t_start < args.budget:
        log(f"speed-error table with the variant {out['faster_pass']!r}: {VARIANTS[out['faster_pass']]}")
        tol = table_with(out["faster_pass"], device, 1 if args.quick else 5)
        with open(args.table, "w", encoding="utf-8") as f:
            json.dump(tol["table"], f, indent=1)
        out["choices"] = tol["choices"]
        out["table_kind"] = tol["kind"]
        out["table_rows"] = [
            {k: r.get(k) for k in ("criterion", "resolver", "depth_slots", "cells_per_diameter", "gather", "error")}
            | {"ratio": r["ratio"].get(tol["kind"])}
            for r in tol["table"]["rows"]
        ]
        save()
    elif args.table:
        out["choices"] = "skipped: past the budget"
    if args.tests_limit > 0:
        out["tests"] = run_tests(device, args.tests_limit)
        log("tests: rc " + str(out["tests"]["rc"]) + " | " + " / ".join(out["tests"]["tail"][-2:]))
        save()
    print(f"\nupdate ms (x criterion 1 at 4) per variant: {' | '.join(PASSES)}; then the cell pass alone")
    for r in out["rows"]:
        head = f"| {r['scene']} | {r['setting']} | {r['cells_per_diameter']} |"
        if "passes" in r:
            ratio = r.get("ratio", {})
            nan = float("nan")
            ups = " | ".join(f"{r['passes'][p]['update_s'] * 1e3:.3f} ({ratio.get(p, nan):.1f})" for p in PASSES)
            cps = " | ".join(f"{r['passes'][p]['cells_s'] * 1e3:.3f}" for p in PASSES)
            print(f"{head} {ups} || {cps} | bitwise {r['bitwise']} |")
        else:
            print(f"{head} {r['update_s'] * 1e3:.3f} ({r.get('ratio', float('nan')):.1f}) |")
    if isinstance(out.get("choices"), dict):
        for k, v in out["choices"].items():
            print(f"{k}: {v}")
    stable = all(r.get("passes", {}).get(p, {}).get("stable", True) for r in out["rows"] for p in PASSES)
    ok = out["bitwise_all"] and stable
    return 0 if ok and out.get("tests", {}).get("rc", 0) == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
