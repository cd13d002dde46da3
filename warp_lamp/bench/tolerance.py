"""The speed-error table behind ``tolerance=`` (:mod:`warp_lamp.tolerance`): measure it, and check its choices.

``measure_table`` runs every candidate setting on the table's scenes (errors: device-independent, against the
exact visible areas) and times it on one device (graph replay on CUDA); ``merge_kind`` adds another device kind's
times to a table; ``check_tolerance`` asks for a range of tolerances and measures what each choice really gives,
on the table's scenes and on a scene held out of the table.

    python -m warp_lamp.bench.tolerance --device cpu --out table.json            # errors + CPU times
    python -m warp_lamp.bench.tolerance --device cuda:0 --times-only --merge table.json --out table.json
    python -m warp_lamp.bench.tolerance --check table.json --device cpu
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
import warp as wp

from warp_lamp.bench.modes import P, exact_areas, time_update
from warp_lamp.grid import LampGrid
from warp_lamp.lamp import ShiningLamp
from warp_lamp.measures import visible_area_error
from warp_lamp.scenes import Scene, scene_lattice_ball, scene_sphere_specimen
from warp_lamp.timing import run_header
from warp_lamp.tolerance import LampChoice, choose_settings, device_kind

__all__ = [
    "SETTINGS",
    "UNIT",
    "check_tolerance",
    "complete_table",
    "held_out_scene",
    "measure_table",
    "merge_kind",
    "table_scenes",
]

#: Candidate settings: (criterion, resolver, depth_slots, subpoints, cells per diameter, gather); the table's rows in
#: this order.
SETTINGS = (
    *[(1, None, None, None, k, None) for k in (2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64)],
    *[("area", "subpoints", 3, 8, k, "front") for k in (2, 3, 4)],
    *[("area", "subpoints", 2, 4, k, "front") for k in (2, 3, 4)],
    *[("area", "exact", d, None, k, "front") for d in (3, 4) for k in (2, 3, 4)],
    *[("area", "subpoints", 4, 8, k, "deep") for k in (3, 4)],
    *[("area", "exact", 4, None, k, "deep") for k in (3, 4)],
    *[("area", "exact", 5, None, k, "deep") for k in (3, 4)],
)
#: The table's unit: criterion 1 at 4 cells per diameter (every ratio is a time over its time on the same kind).
UNIT = (1, None, None, None, 4, None)
#: Tolerances the check asks for.
CHECK_TOLERANCES = (0.2, 0.1, 0.05, 0.02, 0.01, 0.005, 0.003, 0.002, 0.001, 0.0005)


def table_scenes() -> dict[str, Scene]:
    """The scenes whose errors make the table: the SphereTest specimen (a dense random packing, 4,628 spheres) and
    lattice balls of 3,627 and 466 spheres (ordered, overlapping; the small one has more of its particles on its
    rim), all of radius ratio 1.66."""
    return {
        "specimen": scene_sphere_specimen(),
        "lattice ball": scene_lattice_ball(),
        "small lattice ball": scene_lattice_ball(diameter=0.05),
    }


def held_out_scene() -> Scene:
    """A scene the table never saw: the SphereTest specimen's generator with another seed (another packing)."""
    return scene_sphere_specimen(seed=7)


def _options(criterion, resolver, slots, subpoints, gather="front") -> dict:
    if criterion != "area":
        return {"criterion": criterion}
    out = {"criterion": "area", "resolver": resolver, "depth_slots": slots}
    if subpoints is not None:
        out["subpoints"] = subpoints
    if gather != "front":
        out["gather"] = gather
    return out


def _lamp(scene: Scene, options: dict, cells_per_diameter: float, device) -> ShiningLamp:
    grid = LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=cells_per_diameter)
    return ShiningLamp(grid, device=device, **options)


def setting_error(scene: Scene, options: dict, cells_per_diameter: float, device) -> float:
    """RMS per-particle force error of one setting on one scene, over P pi rbar^2 (``visible_area_error``)."""
    lamp = _lamp(scene, options, cells_per_diameter, device)
    pos = wp.array(lamp.grid.to_frame(scene.centers).astype(np.float32), dtype=wp.vec3, device=lamp.device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=lamp.device)
    lamp.update(pos, rad, in_frame=True)
    exact, _ = exact_areas(scene)
    return visible_area_error(lamp.forces_numpy(P), exact, P, float(scene.radii.mean()))["rms"]


def _times(device, repeats: int, timing_scene: Scene, settings=SETTINGS) -> list[float]:
    out = []
    for criterion, resolver, slots, s, k, gather in settings:
        lamp = _lamp(timing_scene, _options(criterion, resolver, slots, s, gather), k, device)
        out.append(time_update(lamp, timing_scene, device, repeats=repeats, moving=False)["update_s"])
    return out


def _kind_of(device) -> str:
    d = wp.get_device(device)
    if not d.is_cuda:
        return "cpu"
    for k in ("h100", "h200", "a100", "l40", "b200"):
        if k in d.name.lower():
            return k
    return "cuda"


def setting_row(setting, scenes: dict, errors_device="cpu") -> dict:
    """One row of the table without its times: the setting and its errors on ``scenes``."""
    criterion, resolver, slots, s, k, gather = setting
    err = {name: setting_error(sc, _options(*setting[:4], gather), k, errors_device) for name, sc in scenes.items()}
    row = {"criterion": criterion, "resolver": resolver, "depth_slots": slots, "subpoints": s}
    if criterion == "area":
        row["gather"] = gather
    return {**row, "cells_per_diameter": k, "errors": err, "error": max(err.values())}


def measure_table(device="cpu", *, repeats: int = 5, errors_device="cpu") -> dict:
    """Errors of every setting on :func:`table_scenes` (on ``errors_device``), and its update time on ``device``
    (the specimen; graph replay on CUDA, eager on the CPU)."""
    scenes = table_scenes()
    rows = [setting_row(setting, scenes, errors_device) for setting in SETTINGS]
    table = {
        "rule": "error = max over scenes of the RMS per-particle force error over P pi rbar^2 (surface particles); "
        "ratio = update time over criterion 1 at 4 cells per diameter on the same device kind (the specimen)",
        "scenes": list(scenes),
        "held_out": held_out_scene.__doc__,
        "rows": rows,
        "kinds": {},
    }
    return merge_kind(table, device, repeats=repeats)


def _row_setting(row: dict) -> tuple:
    gather = row.get("gather", "front") if row["criterion"] == "area" else None
    keys = ("criterion", "resolver", "depth_slots", "subpoints", "cells_per_diameter")
    return (*(row[k] for k in keys), gather)


def complete_table(table: dict, device="cpu", *, repeats: int = 5, errors_device="cpu") -> dict:
    """Add the rows of :data:`SETTINGS` that ``table`` lacks (in place, in their order): errors on the table's
    scenes, and times on ``device`` over criterion 1 at 4 cells per diameter timed again in the same run (the other
    rows and kinds are kept; a GPU kind's times for the new rows come with its next ``merge_kind``)."""
    have = {_row_setting(r): r for r in table["rows"]}
    missing = [s for s in SETTINGS if s not in have]
    if not missing:
        return table
    scenes = table_scenes()
    kind = _kind_of(device)
    base, *times = _times(device, repeats, scene_sphere_specimen(), [UNIT, *missing])
    for setting, t in zip(missing, times, strict=True):
        row = setting_row(setting, scenes, errors_device)
        row["time_s"] = {kind: t}
        row["ratio"] = {kind: t / base}
        have[setting] = row
    table["rows"] = [have[s] for s in SETTINGS if s in have] + [r for k, r in have.items() if k not in SETTINGS]
    return table


def merge_kind(table: dict, device, *, repeats: int = 5, missing_only: bool = False) -> dict:
    """Time every setting on ``device`` and add its kind's times and ratios to ``table`` (in place).

    With ``missing_only``, time only the rows that lack this kind (rows :func:`complete_table` added on another
    device), over criterion 1 at 4 cells per diameter timed again in the same run; the kind's other rows keep their
    times, and the run's header goes under ``table["completed"][kind]``.
    """
    kind = _kind_of(device)
    scene = scene_sphere_specimen()
    if missing_only:
        rows = [r for r in table["rows"] if kind not in r.get("ratio", {})]
        if not rows:
            return table
        base, *times = _times(device, repeats, scene, [UNIT, *(_row_setting(r) for r in rows)])
    else:
        rows = table["rows"]
        times = _times(device, repeats, scene)
        base = times[SETTINGS.index(UNIT)]
    for row, t in zip(rows, times, strict=True):
        row.setdefault("time_s", {})[kind] = t
        row.setdefault("ratio", {})[kind] = t / base
    if missing_only:
        unit_row = next(r for r in table["rows"] if _row_setting(r) == UNIT)
        table.setdefault("completed", {})[kind] = {
            **run_header([device]),
            "rows": len(rows),
            "base_s": base,
            "base_s_table": unit_row.get("time_s", {}).get(kind),
        }
    else:
        table["kinds"][kind] = run_header([device])
    return table


def check_tolerance(table: dict, device="cpu", *, tolerances=CHECK_TOLERANCES) -> list[dict]:
    """For each tolerance: the choice on ``device``'s kind and the error it really gives on every table scene and
    on the held-out scene (``ok``: every measured error within the tolerance)."""
    scenes = {**table_scenes(), "held out": held_out_scene()}
    out = []
    for tol in tolerances:
        try:
            choice: LampChoice = choose_settings(tol, device, table=table)
        except ValueError as e:
            out.append({"tolerance": tol, "choice": None, "reason": str(e)})
            continue
        measured = {
            name: setting_error(sc, choice.options(), choice.cells_per_diameter, device) for name, sc in scenes.items()
        }
        out.append(
            {
                "tolerance": tol,
                "choice": choice.describe(),
                "kind": device_kind(device, table),
                "measured": measured,
                "ok": all(v <= tol for v in measured.values()),
            }
        )
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Measure or check the speed-error table behind tolerance=.")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", help="write the table (JSON) here")
    ap.add_argument("--merge", help="an existing table: add this device's times to it (with --times-only)")
    ap.add_argument("--times-only", action="store_true")
    ap.add_argument(
        "--missing", action="store_true", help="with --times-only: time only the rows without this device's kind"
    )
    ap.add_argument("--check", metavar="TABLE", help="check a table's choices on this device")
    ap.add_argument("--complete", metavar="TABLE", help="add the settings a table lacks (errors, this device's times)")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    t0 = time.perf_counter()
    if args.check:
        with open(args.check, encoding="utf-8") as f:
            table = json.load(f)
        rows = check_tolerance(table, args.device)
        for r in rows:
            if r["choice"] is None:
                print(f"| {r['tolerance']:g} | none: {r['reason']} |")
                continue
            m = ", ".join(f"{k} {100 * v:.3g}%" for k, v in r["measured"].items())
            print(f"| {r['tolerance']:g} | {r['choice']} | {m} | {'ok' if r['ok'] else 'MISSED'} |")
        if args.out:
            with open(args.out, "w", encoding="utf-8") as f:
                json.dump({"check": rows, "device": run_header([args.device])}, f, indent=1)
        return 0 if all(r.get("ok", True) for r in rows) else 1
    if args.complete:
        with open(args.complete, encoding="utf-8") as f:
            table = complete_table(json.load(f), args.device, repeats=args.repeats)
    elif args.times_only:
        if not args.merge:
            ap.error("--times-only needs --merge TABLE")
        with open(args.merge, encoding="utf-8") as f:
            table = merge_kind(json.load(f), args.device, repeats=args.repeats, missing_only=args.missing)
    if not (args.complete or args.times_only):
        table = measure_table(args.device, repeats=args.repeats)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as f:
            json.dump(table, f, indent=1)
    for row in table["rows"]:
        ratios = ", ".join(f"{k} {v:.3g}x" for k, v in row.get("ratio", {}).items())
        name = row["criterion"] if row["criterion"] != "area" else f"area {row['resolver']} D{row['depth_slots']}"
        name = f"{name} deep" if row.get("gather") == "deep" else name
        print(f"| {name} | {row['cells_per_diameter']:g} | {100 * row['error']:.3g}% | {ratios} |")
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
