"""Differential runs of the mutants the mutation README calls equivalent: each mutant and the original code run the
same targeted inputs (random, dense, tied, walled) in fresh processes, and their outputs are compared bit for bit.

    python bench/mutation/differential.py run [NAMES...] [--out results/differential.json]
    python bench/mutation/differential.py list

A mutant whose outputs all equal the original's on these inputs stays "equivalent (differential: N arrays equal)";
one whose outputs differ is not equivalent, whatever reading it suggested, and the arrays that differ are named.
Each variant is a copy of warp_lamp/ and tests/ under /tmp/warp_lamp_differential/<name>, the mutant written into
it (the exact line of the mutation session, found by its text), so that Warp compiles a mutated kernel module afresh
(into the user's kernel cache, under the module's new hash).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
WORK = Path(os.environ.get("WARP_LAMP_DIFFERENTIAL_DIR", "/tmp/warp_lamp_differential"))

#: name: (file, line of the mutation session's code, original line (stripped), mutant line (stripped), driver)
MUTANTS = {
    "area.py:167": ("warp_lamp/kernels/area.py", 167, "for e in range(4):", "for e in range(5):", "area"),
    "area.py:308": ("warp_lamp/kernels/area.py", 308, "if full == 0 and d2 > r2:", "if full == 0 and d2 <= r2:",
                    "area"),
    "lamp.py:358": ("warp_lamp/kernels/lamp.py", 358, "cell_keys[p] = grid.offset[a] + j * grid.n_u[a] + i",
                    "cell_keys[p] = grid.offset[a] + j * grid.n_u[a] - i", "lamp"),
    "lamp.py:714": ("warp_lamp/kernels/lamp.py", 714, "nf = wp.vec3(0.0)", "nf = wp.vec3(-1.0)", "lamp"),
    "packing.py:38": ("warp_lamp/kernels/packing.py", 38, "n = wp.vec3(1.0, 0.0, 0.0)", "n = wp.vec3(0.0, 0.0, 0.0)",
                      "packing"),
    "porosity.py:291": (
        "warp_lamp/kernels/porosity.py", 291,
        "x = wp.int64((wp.float64(1.0) + wp.sqrt(wp.float64(8) * wp.float64(r) * wp.float64(r))) / wp.float64(4.0))",
        "x = wp.int64((wp.float64(1.0) + wp.sqrt(wp.float64(8) * wp.float64(r) / wp.float64(r))) / wp.float64(4.0))",
        "porosity",
    ),
    "wetted.py:2128": ("warp_lamp/kernels/wetted.py", 2128, "for bz in range(span.lo[2], span.hi[2] + 1):",
                       "for bz in range(span.lo[2], span.hi[2] - 1):", "wetted"),
    "wetted.py:2130": ("warp_lamp/kernels/wetted.py", 2130, "for bx in range(span.lo[0], span.hi[0] + 1):",
                       "for bx in range(span.lo[0], span.hi[0] + 2):", "wetted"),
    "wetted.py:2135": ("warp_lamp/kernels/wetted.py", 2135, "if dot3(v, v) < r * r:", "if dot3(v, v) <= r * r:",
                       "wetted"),
    "wetted.py:2169": ("warp_lamp/kernels/wetted.py", 2169, "while slot > 0 and depth[slot - 1] < dep:",
                       "while slot > 0 and depth[slot - 0] < dep:", "wetted"),
    "wetted.py:2322": ("warp_lamp/kernels/wetted.py", 2322,
                       "rd = (wp.float64(r32) + box.rho + box.diag) * (wp.float64(1.0) + SLACK)",
                       "rd = (wp.float64(r32) + box.rho + box.diag) * (wp.float64(2.0) + SLACK)", "wetted"),
    "pipeline.py:168": ("warp_lamp/pipeline.py", 168, "dim=1,", "dim=2,", "follow"),
    "frames.py:62": (
        "warp_lamp/frames.py", 62,
        "if not np.isfinite(x).all() or np.abs(x).max(initial=0.0) > 2.0**960:",
        "if not np.isfinite(x).all() or np.abs(x).max(initial=-1.0) > 2.0**960:",
        "frames",
    ),
    "reference/area.py:179": ("warp_lamp/reference/area.py", 179, "r = np.asarray(radii, dtype=np.float64).reshape(-1)",
                              "r = np.asarray(radii, dtype=np.float64).reshape(-2)", "refarea"),
    "reference/area.py:961": (
        "warp_lamp/reference/area.py", 961,
        'chunk = max(16, int(2e6 // (k * (2 * k + 10) if resolver == "exact" else k * subpoints * subpoints)))',
        'chunk = max(16, int(2e6 // (k * (2 * k + 10) if resolver != "exact" else k * subpoints * subpoints)))',
        "refarea",
    ),
    "reference/area.py:1123": (
        "warp_lamp/reference/area.py", 1123,
        'stats["sample_hits"] += len(_sample_hits(q[ids, u] - cu, q[ids, v] - cv, r[ids], hu, hv, nu, nv)[0])',
        'stats["sample_hits"] += len(_sample_hits(q[ids, u] - cu, q[ids, v] - cv, r[ids], hu, hv, nu, nv)[-1])',
        "refarea",
    ),
    "scenes.py:300": ("warp_lamp/scenes.py", 300, "dim = max(8, min(128, int(np.ceil(n ** (1.0 / 3.0)))))",
                      "dim = max(7, min(128, int(np.ceil(n ** (1.0 / 3.0)))))", "scenes"),
    "scenes.py:316": ("warp_lamp/scenes.py", 316, "w = float(worst.numpy()[0])", "w = float(worst.numpy()[-1])",
                      "scenes"),
    "wetted.py:249": ("warp_lamp/wetted.py", 249, "columns = [0, nwx * int(n[2]), nwx * int(n[1])]",
                      "columns = [1, nwx * int(n[2]), nwx * int(n[1])]", "wettednbytes"),
}  # fmt: skip


# --- drivers: each returns {name: array}, run in a fresh process on the variant's code -------------------------


def _drive_area():
    sys.path.insert(0, str(Path.cwd() / "tests"))
    from test_area import cap_stack, one_cell_units

    import warp_lamp as wl
    from warp_lamp.scenes import scene_overlapping_polydisperse

    out = {}
    rng = np.random.default_rng(35)
    for t in range(8):
        views, r = cap_stack(rng, t % 2 == 0)
        for res in ("exact", "subpoints"):
            out[f"cap{t}_{res}"] = one_cell_units(views, r, "cpu", resolver=res)
    s = scene_overlapping_polydisperse(300)
    rng = np.random.default_rng(1)
    scenes = {"overlap": (s.centers, s.radii), "random": (rng.uniform(0, 5, (150, 3)), rng.uniform(0.2, 0.6, 150))}
    scenes["dense"] = (rng.uniform(0, 2, (300, 3)), rng.uniform(0.25, 0.45, 300))
    for name, (c, r) in scenes.items():
        for res in ("exact", "subpoints"):
            for cpd in (2, 3, 5):
                lamp = wl.lamp_update(c, r, criterion="area", resolver=res, cells_per_diameter=cpd, device="cpu")
                out[f"{name}_{res}_{cpd}"] = lamp.counts_numpy()
    return out


def _drive_lamp():
    import warp_lamp as wl

    out = {}
    rng = np.random.default_rng(2)
    c, r = rng.uniform(0, 5, (300, 3)), rng.uniform(0.1, 0.6, 300)
    lattice = np.stack(np.meshgrid(*[np.arange(5)] * 3, indexing="ij"), -1).reshape(-1, 3) * 1.0
    for crit in (0, 1):
        for cpd in (2, 4, 7):
            opts = {"criterion": crit, "cells_per_diameter": cpd, "device": "cpu"}
            out[f"random_c{crit}_{cpd}"] = wl.lamp_forces(c, r, 1.0, **opts)
            out[f"lattice_c{crit}_{cpd}"] = wl.lamp_forces(lattice, np.full(len(lattice), 0.5), 1.0, **opts)
        walls = [((0.0, 0.0, 2.5), (0.0, 0.0, 1.0)), ((2.5, 0.0, 0.0), (-1.0, 0.3, 0.1))]
        out[f"walls_c{crit}"] = wl.lamp_forces(c, r, 1.0, criterion=crit, walls=walls, device="cpu")
        turn = np.array([[0.8, -0.6, 0.0], [0.6, 0.8, 0.0], [0.0, 0.0, 1.0]])
        grid = wl.LampGrid([-1.0] * 3, [6.0] * 3, 0.2, rotation=turn)
        out[f"rotated_walls_c{crit}"] = wl.lamp_forces(c, r, 1.0, criterion=crit, grid=grid, walls=walls[:1],
                                                       device="cpu")  # fmt: skip
    return out


def _drive_packing():
    from warp_lamp.scenes import relax_packing

    out = {}
    rng = np.random.default_rng(3)
    for k in range(3):
        x0 = rng.uniform(0, 1, (60, 3))
        x0[1::7] = x0[0::7][: len(x0[1::7])]  # coincident pairs
        r = rng.uniform(0.05, 0.08, 60)
        out[f"relaxed{k}"] = relax_packing(x0, r, box=(np.zeros(3), np.ones(3)), tol=0.01, device="cpu")
    return out


def _drive_porosity():
    from warp_lamp.bench.porosity import table_1
    from warp_lamp.porosity import porosity

    out = {}
    rng = np.random.default_rng(4)
    for k, (rmin, rmax) in enumerate(((0.001, 0.01), (0.003, 0.03), (0.02, 0.08))):
        c, r = rng.uniform(0, 0.2, (120, 3)), rng.uniform(rmin, rmax, 120)
        for alg in (1, 2):
            out[f"midpoint{k}_{alg}"] = porosity(c, r, np.zeros(3), np.full(3, 0.2), (4, 4, 4), method="midpoint",
                                                 subdivisions=64, midpoint_algorithm=alg, device="cpu")  # fmt: skip
    out["table_1"] = np.array([[t["r"], t["midpoint"]] for t in table_1()], dtype=np.float64)
    return out


def _drive_wetted():
    import warp_lamp as wl
    from warp_lamp.scenes import (
        scene_cavity_block,
        scene_overlapping_polydisperse,
        scene_slot_block,
        scene_tunnel_block,
    )

    out = {}
    s = scene_overlapping_polydisperse(40, solid_fraction=0.4)
    rng = np.random.default_rng(5)
    fines = (rng.uniform(0, 3, (200, 3)), rng.uniform(0.03, 0.3, 200))  # many thin chords at h = 0.25
    scenes = {"overlap": (s.centers, s.radii), "fines": fines}
    for name, (c, r) in scenes.items():
        for h in (0.25, 0.125):
            for rho in (0.1, 0.25, 0.6):
                lo = (c - r[:, None]).min(axis=0) - rho - 2 * h
                hi = (c + r[:, None]).max(axis=0) + rho + 2 * h
                grid = wl.LampGrid(lo, hi, h)
                for wall in (False, True):
                    walls = [((0.0, 0.0, float(np.median(c[:, 2]))), (0.0, 0.3, 1.0))] if wall else None
                    out[f"{name}_{h}_{rho}_{wall}"] = wl.lamp_forces(
                        c, r, 1.0, grid=grid, surfaces="all", probe_radius=rho, walls=walls, device="cpu"
                    )
    for name, block in (("slot", scene_slot_block((10, 12, 8), width=4, depth=3)),
                        ("tunnel", scene_tunnel_block()), ("cavity", scene_cavity_block())):  # fmt: skip
        rho = float(block.radii.mean())
        out[name] = wl.lamp_forces(block.centers, block.radii, 1.0, surfaces="all", probe_radius=rho, device="cpu")
    return out


def _drive_follow():
    import warp as wp

    import warp_lamp as wl

    out = {}
    rng = np.random.default_rng(6)
    c, r = rng.uniform(0, 2, (200, 3)), rng.uniform(0.1, 0.3, 200)
    grid = wl.LampGrid([-1.0] * 3, [3.5] * 3, 0.1)
    for crit in (0, 1):
        lamp = wl.ShiningLamp(grid, criterion=crit, follow=True, device="cpu")
        for step in range(6):
            x = c + step * np.array([0.37, -0.21, 0.13])
            pos = wp.array(x.astype(np.float32), dtype=wp.vec3, device="cpu")
            rad = wp.array(r.astype(np.float32), dtype=wp.float32, device="cpu")
            lamp.update(pos, rad)
            f = wp.zeros(len(r), dtype=wp.vec3, device="cpu")
            lamp.add_forces(f, 1.0)
            out[f"c{crit}_{step}"] = f.numpy()
            out[f"c{crit}_{step}_origin"] = np.asarray(lamp.diagnostics().counts)
    return out


def _drive_frames():
    from warp_lamp.frames import lamp_force_factors

    out = {}
    rng = np.random.default_rng(7)
    for k in range(20):
        p = rng.uniform(0, 1e7, 3) * (k % 4 != 0)
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        q = q * np.sign(np.linalg.det(q))
        out[f"f{k}"] = lamp_force_factors(p, rng.uniform(1e-6, 1e-2, 3), q if k % 2 else None)
    return out


def _drive_refarea():
    import warp_lamp as wl
    from warp_lamp.reference import area_estimate_reference, visible_area_reference
    from warp_lamp.reference.area import visible_disk_areas, visible_sphere_areas

    out = {}
    rng = np.random.default_rng(8)
    c, r = rng.uniform(0, 4, (120, 3)), rng.uniform(0.2, 0.5, 120)
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3)
    for res in ("exact", "subpoints"):
        ref = area_estimate_reference(c, r, grid, resolver=res)
        out[f"units_{res}"] = ref.units
        out[f"stats_{res}"] = np.array([ref.stats[k] for k in sorted(ref.stats)], dtype=np.float64)
    out["visible"] = visible_area_reference(c[:30], r[:30])
    # _checked (reshape(-1)): planar and per-sphere areas with radii as a column and a scalar per disk
    rect = (0.5, 0.5, 2.5, 2.0)
    out["disks_column"] = visible_disk_areas(c[:20, :2], r[:20].reshape(-1, 1), rect)
    out["spheres_list"] = visible_sphere_areas(c[:12], r[:12].tolist(), rect)
    out["one_sphere"] = visible_sphere_areas(c[:1], float(r[0]), rect)
    return out


def _drive_scenes():
    from warp_lamp.scenes import relax_packing, scene_box_specimen

    out = {}
    rng = np.random.default_rng(9)
    for n in (20, 200, 700):
        x0 = rng.uniform(0, 1, (n, 3))
        r = np.full(n, 0.35 / n ** (1 / 3))
        out[f"relax{n}"] = relax_packing(x0, r, box=(np.zeros(3), np.ones(3)), tol=0.01, device="cpu")
    s = scene_box_specimen((2e-3, 2e-3, 2e-3), 0.5e-3, cache=False)
    out["box"] = s.centers
    return out


def _drive_wettednbytes():
    import warp_lamp as wl
    from warp_lamp.wetted import wetted_nbytes

    out = []
    for h in (0.05, 0.1, 0.25):
        for rho in (0.0, 0.1, 0.5):
            grid = wl.LampGrid([0.0] * 3, [3.0, 2.0, 5.0], h)
            out.append(wetted_nbytes(grid, rho))
    return {"nbytes": np.array(out)}


DRIVERS = {name[len("_drive_") :]: f for name, f in globals().items() if name.startswith("_drive_")}


def drive(name: str, path: str) -> None:
    import warp as wp

    wp.config.quiet = True
    out = DRIVERS[name]()
    np.savez(path, **{k: np.asarray(v) for k, v in out.items()})


# --- variants -------------------------------------------------------------------------------------------------


def _variant(name: str | None) -> Path:
    """A copy of warp_lamp/, tests/ and this script, with mutant ``name`` written in (None: the original)."""
    dest = WORK / ("original" if name is None else name.replace("/", "_").replace(":", "_"))
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    for part in ("warp_lamp", "tests"):
        shutil.copytree(ROOT / part, dest / part, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(Path(__file__), dest / "differential.py")
    if name is not None:
        path, line, old, new, _ = MUTANTS[name]
        lines = (dest / path).read_text().split("\n")
        if lines[line - 1].strip() != old:
            raise RuntimeError(f"{name}: line {line} of {path} is {lines[line - 1].strip()!r}, not {old!r}")
        lines[line - 1] = lines[line - 1].replace(old, new)
        (dest / path).write_text("\n".join(lines))
    return dest


def _run_driver(root: Path, driver: str, timeout: int = 1800) -> tuple[dict | None, str]:
    out = root / f"{driver}.npz"
    env = {**os.environ, "PYTHONPATH": str(root), "WARP_LAMP_CACHE": str(WORK / "scene-cache")}
    proc = subprocess.run(
        [sys.executable, str(root / "differential.py"), "drive", driver, str(out)],
        cwd=root, env=env, capture_output=True, text=True, timeout=timeout, check=False,
    )  # fmt: skip
    if proc.returncode != 0:
        return None, proc.stderr[-1500:]
    with np.load(out) as z:
        return {k: z[k] for k in z.files}, ""


def run(names, out_path: Path) -> None:
    results = json.loads(out_path.read_text()) if out_path.exists() else {}
    original = _variant(None)
    cache = {}
    for name in names:
        driver = MUTANTS[name][4]
        if driver not in cache:
            cache[driver] = _run_driver(original, driver)
            if cache[driver][0] is None:
                raise RuntimeError(f"original, driver {driver}: {cache[driver][1]}")
        want = cache[driver][0]
        t0 = time.time()
        got, err = _run_driver(_variant(name), driver)
        if got is None:
            verdict = {"verdict": "differs (the mutant fails or crashes on these inputs)", "error": err}
        else:
            differ = [k for k in want if k not in got or want[k].shape != got[k].shape or not np.array_equal(
                want[k], got[k], equal_nan=True)]  # fmt: skip
            verdict = {
                "verdict": "differs" if differ else "equal",
                "arrays": len(want),
                "differ": differ,
                "max_abs_diff": max(
                    (float(np.max(np.abs(want[k].astype(np.float64) - got[k].astype(np.float64))))
                     for k in differ if k in got and want[k].shape == got[k].shape), default=None),
            }  # fmt: skip
        verdict.update(driver=driver, seconds=round(time.time() - t0, 1))
        results[name] = verdict
        print(f"{name:26s} {verdict['verdict']:8s} {verdict.get('differ', '')} {verdict['seconds']} s", flush=True)
        out_path.write_text(json.dumps(results, indent=1))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("names", nargs="*")
    r.add_argument("--out", default=str(Path(__file__).resolve().parent / "results" / "differential.json"))
    d = sub.add_parser("drive")
    d.add_argument("driver")
    d.add_argument("path")
    sub.add_parser("list")
    args = parser.parse_args(argv)
    if args.cmd == "list":
        for name, (_path, _line, old, new, driver) in MUTANTS.items():
            print(f"{name:26s} {driver:12s} {old} -> {new}")
        return 0
    if args.cmd == "drive":
        drive(args.driver, args.path)
        return 0
    run(args.names or list(MUTANTS), Path(args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
