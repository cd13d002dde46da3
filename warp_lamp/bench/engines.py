"""``warp-lamp bench``'s peer row from an engine people use: YADE's alpha-shape caps against the lamp's
wetted surface.

YADE's own pressure boundary is ``TesselationWrapper.applyAlphaForces(stress, alpha, shrinkedAlpha, fixedAlpha)``:
a regular (weighted) Delaunay triangulation of the spheres in CGAL, its alpha shape, and on each boundary sphere the
area vector of its Voronoi faces toward fictitious spheres placed on the alpha shape's facets, times the stress.
Here it runs in YADE itself (:mod:`warp_lamp.engines.yade_alpha_job`, a subprocess: YADE has its own interpreter),
against :class:`~warp_lamp.engines.EngineLamp` with ``surfaces="all"`` (probe radius rho = one mean radius, as
``bench modes``' wetted section), both on the CPU, on the slot block and the SphereTest specimen.

The alpha choice. alpha is a squared radius in power distance: a probe ball of radius rho touching spheres of
radius r has alpha = rho (rho + 2 r), so :func:`alpha_for_probe` converts a probe radius. The bench uses a probe of
two mean radii (alpha = 8 r^2) and ``shrinkedAlpha = (sqrt(alpha) - r)^2`` (YADE's examples shrink by one radius),
with ``fixedAlpha=True``. The sweep (``--sweep``) shows why: below about 0.8 r alpha falls under the smallest
alpha that keeps every sphere, every sphere is loaded and the forces no longer balance; at 1 r the slot's walls
take 0.42 of their load; from 1.5 r to 4 r walls take 0.93-0.95 while the floor falls from 0.98 to 0.88 as the
alpha ball rounds the slot's bottom corners; at 8 r it bridges the slot (floor 0.12). 2 r is where walls and floor
both sit within 1.5% of the lamp's. YADE's default alpha = 0 stops in CGAL ("Creating an Mpzf from infinity or
NaN") on 2023.02a, and the job refuses it.

    python -m warp_lamp.bench.engines [--sweep] [--repeats 3] [--json PATH]

DEM-Engine (DEME, a GPU engine) gets its own rows, :func:`deme_section`: the SphereTest held by the lamp inside
DEME and the lamp's share of a DEME step, run by ``bench/deme_share.py`` where ``deme`` and a CUDA device are
present, read from the newest ``bench/results/*-deme.json`` otherwise.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from warp_lamp.engines.core import EngineLamp
from warp_lamp.measures import envelope_stress, slot_load_ratios, stress_summary
from warp_lamp.scenes import Scene, scene_slot_block, scene_sphere_specimen

__all__ = [
    "ALPHA_PROBE",
    "SWEEP",
    "alpha_for_probe",
    "bench_engines",
    "deme_section",
    "find_yade",
    "format_deme",
    "format_engines",
    "yade_alpha_caps",
]

P = 1.0
#: The alpha shape's probe radius the bench uses, in mean radii.
ALPHA_PROBE = 2.0
#: Probe radii of the sweep, in mean radii.
SWEEP = (0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0)
#: The job YADE runs.
JOB = Path(__file__).resolve().parents[1] / "engines" / "yade_alpha_job.py"


def find_yade() -> str | None:
    """The ``yade`` launcher on the PATH (or ``$WARP_LAMP_YADE``), or None."""
    return os.environ.get("WARP_LAMP_YADE") or shutil.which("yade")


def alpha_for_probe(rho: float, radius: float) -> float:
    """alpha (a squared radius in power distance) of a probe ball of radius ``rho`` [m] touching spheres of radius
    ``radius`` [m]: rho (rho + 2 r)."""
    return rho * (rho + 2.0 * radius)


def yade_alpha_caps(scene: Scene, alphas, shrinked, *, pressure: float = P, repeats: int = 3, yade=None, timeout=None):
    """Run YADE's ``applyAlphaForces`` on ``scene`` for each (alpha, shrinkedAlpha) in YADE itself.

    Args:
        scene: The particles.
        alphas: alpha per setting, each > 0 (shape (K,)).
        shrinked: shrinkedAlpha per setting, each > 0 (shape (K,)).
        pressure: P [Pa]; the stress applied is -P I (YADE's tension-positive convention).
        repeats: Timed calls per setting.
        yade: The ``yade`` launcher; :func:`find_yade` by default.
        timeout: Seconds before the job is stopped.

    Returns:
        ``(forces, seconds, cpu_seconds)``: the permanent forces YADE set [N], shape (K, N, 3), and the wall-clock
        and CPU seconds of each call, shape (K, repeats).
    """
    yade = yade or find_yade()
    if yade is None:
        raise FileNotFoundError("yade: not found on the PATH (apt-get install yade, or set WARP_LAMP_YADE)")
    alphas, shrinked = np.atleast_1d(np.asarray(alphas, float)), np.atleast_1d(np.asarray(shrinked, float))
    if alphas.shape != shrinked.shape or np.any(alphas <= 0) or np.any(shrinked <= 0):
        raise ValueError("alphas, shrinked: the same number of settings, each > 0 (alpha = 0 crashes YADE's CGAL)")
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(src, centers=scene.centers, radii=scene.radii, pressure=pressure, alpha=alphas, shrinked=shrinked,
                 repeats=repeats)  # fmt: skip
        run = subprocess.run(
            [yade, "-j1", "-n", "-x", str(JOB), str(src), str(dst)],
            capture_output=True,
            text=True,
            timeout=timeout,
            check=False,
        )
        if run.returncode != 0 or not dst.exists():
            raise RuntimeError(f"yade: the alpha-caps job failed (exit {run.returncode}):\n{run.stderr[-2000:]}")
        out = np.load(dst)
        return out["forces"], out["seconds"], out["cpu_seconds"]


def yade_version(yade=None) -> str:
    """``yade --version``'s last line (e.g. "Yade version: 2023.02a")."""
    run = subprocess.run([yade or find_yade(), "--version"], capture_output=True, text=True, check=False)
    lines = [x.strip() for x in run.stdout.splitlines() if x.strip()]
    return lines[-1] if lines else "yade (version unknown)"


def _loads(scene: Scene, f: np.ndarray, reference: np.ndarray) -> dict:
    loaded = np.any(f != 0.0, axis=1)
    ref = np.any(reference != 0.0, axis=1)
    out = {
        "loaded": int(loaded.sum()),
        "jaccard": float((loaded & ref).sum() / max((loaded | ref).sum(), 1)),
        "force_sum_over_load": float(np.abs(f.sum(axis=0)).max() / max(np.linalg.norm(f, axis=1).sum(), 1e-300)),
    }
    cut = getattr(scene, "cut", None)
    if isinstance(cut, dict) and cut.get("kind") == "slot":
        out["ratios"] = slot_load_ratios(scene, f, P)
    elif scene.radius > 0:
        sigma = envelope_stress(scene.centers, f, scene.center, 4.0 / 3.0 * np.pi * scene.radius**3)
        out["mean_pressure_over_P"] = stress_summary(sigma, P)["mean_pressure_over_P"]
    return out


def _lamp_row(scene: Scene, repeats: int, cells_per_diameter: float) -> tuple[dict, np.ndarray]:
    rho = float(scene.radii.mean())
    lamp = EngineLamp(
        scene.centers, scene.radii, P, cells_per_diameter=cells_per_diameter, surfaces="all", probe_radius=rho
    )
    f = lamp.forces(scene.centers)  # the first update: every owner found from scratch
    times, cpu = [], []
    for _ in range(repeats):
        lamp.lamp.forget()  # each timed call runs cold, as YADE's rebuilds its triangulation
        c0 = time.thread_time()  # Warp's CPU kernels run on the calling thread
        f = lamp.forces(scene.centers)
        cpu.append(time.thread_time() - c0)
        times.append(lamp.seconds)
    row = {
        "scene": scene.name,
        "n": scene.n,
        "method": f"lamp, wetted, rho = {rho / scene.radii.mean():g} r",
        "setting": {"probe_radius": rho, "cells_per_diameter": cells_per_diameter},
        "seconds": float(np.median(times)),
        "cpu_seconds": float(np.median(cpu)),
        **_loads(scene, f, f),
    }
    return row, f


def section_yade_alpha(
    *, repeats: int = 3, sweep: bool = False, cells_per_diameter: float = 4, yade=None, progress: bool = True
) -> list[dict]:
    """The lamp's wetted surface and YADE's alpha caps on the slot block and the specimen, both on the CPU.

    Returns a row per scene and method: ``seconds`` and ``cpu_seconds`` (medians per call, wall clock and the
    calling thread's CPU time: the lamp's upload, cold update and forces; YADE's ``applyAlphaForces`` with a new
    triangulation), ``loaded`` (particles with a nonzero force),
    ``jaccard`` (of the loaded set against the lamp's), ``force_sum_over_load`` (the largest |component| of the
    force sum over the summed force magnitudes: 0 when the loads balance), and the slot block's ``ratios`` or the
    specimen's ``mean_pressure_over_P`` (from the loads on its envelope).
    """
    rows = []
    probes = SWEEP if sweep else (ALPHA_PROBE,)
    for scene in (scene_slot_block(), scene_sphere_specimen()):
        t0 = time.perf_counter()
        row, f_lamp = _lamp_row(scene, repeats, cells_per_diameter)
        rows.append(row)
        r = float(scene.radii.mean())
        alphas = [alpha_for_probe(k * r, r) for k in probes]
        shrinked = [(np.sqrt(a) - r) ** 2 for a in alphas]
        forces, seconds, cpu = yade_alpha_caps(scene, alphas, shrinked, repeats=repeats, yade=yade)
        for k, a, s, f, t, c in zip(probes, alphas, shrinked, forces, seconds, cpu, strict=True):
            rows.append(
                {
                    "scene": scene.name,
                    "n": scene.n,
                    "method": f"YADE alpha caps, probe {k:g} r",
                    "setting": {"alpha": a, "shrinkedAlpha": s, "fixedAlpha": True},
                    "seconds": float(np.median(t)),
                    "cpu_seconds": float(np.median(c)),
                    **_loads(scene, f, f_lamp),
                }
            )
        if progress:
            print(f"  {scene.name}: {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)
    return rows


#: The checkout's DEME bench script and result files (absent from an installed package).
DEME_SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "deme_share.py"  # the repository's bench/
RESULTS = Path(__file__).resolve().parents[2] / "bench" / "results"


def deme_section(*, path=None, run: bool | None = None, timeout: float = 600.0) -> dict:
    """DEME's rows: the result of ``bench/deme_share.py`` (the SphereTest in DEME, the lamp's share of a step).

    Args:
        path: A result file to read; by default the newest ``bench/results/*-deme.json``.
        run: Run ``bench/deme_share.py`` (about seven minutes on a fresh machine: DEME compiles its kernels); by
            default where ``deme`` and a CUDA device are present and no ``path`` is given.
        timeout: Seconds the run may take.

    Returns:
        The result (with ``source``: the file, or "this run"), or ``{"skipped": reason}``.
    """
    from warp_lamp.engines.deme import deme_unavailable

    if run is None:
        run = path is None and deme_unavailable() is None and DEME_SCRIPT.exists()
    if run:
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "deme.json"
            done = subprocess.run([sys.executable, str(DEME_SCRIPT), "--json", str(out)], timeout=timeout, check=False)
            if not out.exists():
                return {"skipped": f"bench/deme_share.py failed (exit {done.returncode})"}
            return {**json.loads(out.read_text()), "source": "this run"}
    if path is None:
        files = sorted(RESULTS.glob("*-deme.json"), key=lambda f: (f.name.split("-", 1)[-1], f.name))
        if not files:
            reason = deme_unavailable() or "no DEME result file"
            return {"skipped": f"{reason}; on a GPU, bench/deme_share.py writes bench/results/<card>-<date>-deme.json"}
        path = files[-1]
    path = Path(path)
    return {**json.loads(path.read_text()), "source": path.name}


def format_deme(result: dict) -> str:
    """DEME's rows as Markdown: the SphereTest's stresses and the lamp's share of a DEME step."""
    if "skipped" in result:
        return f"\nDEM-Engine: skipped ({result['skipped']}).\n"
    lines = ["", f"DEM-Engine {result.get('deme', '?')} on {result.get('gpu', '?')} ({result.get('source', '')}):", ""]
    st = result.get("sphere_test")
    if st:
        sigma = np.asarray(st["sigma_Pa"]) / 1e6
        lines += [
            "| SphereTest | spheres | steps | unbalanced | sxx MPa | syy MPa | szz MPa | mean / P |",
            "| --- | --- | --- | --- | --- | --- | --- | --- |",
            f"| {st['engine']} | {st['n']:,} | {st['steps']} | {st['unbalanced']:.1e} | {sigma[0, 0]:.3f} | "
            f"{sigma[1, 1]:.3f} | {sigma[2, 2]:.3f} | {st['mean_over_P']:.3f} |",
            "",
        ]
    rows = result.get("share", [])
    if rows:
        lines += [
            "Per DEME step (medians, wall clock): DEME's step beside the lamp's update (read: DEME's positions into "
            "a Warp array; write: the owners' accelerations) and the per-step queueing (AddAccFromDevice):",
            "",
            "| spheres | mode | DEME step us | read us | lamp ms | write us | queue us | share, every step | "
            "every 10 |",
            "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
        ]
        for r in rows:
            lines.append(
                f"| {r['n']:,} | {r['mode']}{' (capped)' if r.get('capped') else ''} | "
                f"{r['step_with_lamp_s'] * 1e6:.0f} | {r['read_s'] * 1e6:.0f} | {r['lamp_s'] * 1e3:.2f} | "
                f"{r['write_s'] * 1e6:.0f} | {r['apply_s'] * 1e6:.0f} | {r['share_every_1']:.1%} | "
                f"{r['share_every_10']:.1%} |"
            )
    stages = result.get("stages")
    if stages:
        lines += ["", "Stages: " + ", ".join(f"{k} {v:.0f} s" if isinstance(v, float) else f"{k} {v}"
                                              for k, v in stages.items())]  # fmt: skip
    return "\n".join(lines) + "\n"


def bench_engines(*, repeats: int = 3, sweep: bool = False, progress: bool = True, deme: bool = True) -> dict:
    """The engines' peer rows: ``{"yade_alpha": rows, "yade": version, "deme": ...}``, with ``{"skipped":
    reason}`` in place of YADE's where YADE is not installed; ``deme`` (:func:`deme_section`) unless ``deme`` is
    False."""
    out = {"deme": deme_section()} if deme else {}
    yade = find_yade()
    if yade is None:
        return {"skipped": "YADE not installed (apt-get install yade)", **out}
    return {
        "yade": yade_version(yade),
        "device": "cpu (one Warp CPU thread; YADE -j1)",
        "yade_alpha": section_yade_alpha(repeats=repeats, sweep=sweep, yade=yade, progress=progress),
        **out,
    }


def format_engines(result: dict) -> str:
    """The engines' peer rows as a Markdown table (and DEME's, where the result has them)."""
    deme = format_deme(result["deme"]) if "deme" in result else ""
    if "skipped" in result:
        return f"\nEngines: skipped ({result['skipped']}).\n" + deme
    lines = [
        "",
        f"YADE's alpha-shape caps ({result['yade']}, TesselationWrapper.applyAlphaForces, fixedAlpha, shrinkedAlpha "
        f"= (sqrt(alpha) - r)^2) against the lamp's wetted surface (4 cells/d); {result['device']}; time per call "
        "is a median, wall clock and CPU time of the calling thread (lamp: cold update and forces; YADE: a new "
        "triangulation and the caps):",
        "",
        "| scene | method | alpha | walls (-y / +y) or mean pressure / P | floor | loaded | Jaccard vs lamp | "
        "force sum / load | ms per call (wall / CPU) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in result["yade_alpha"]:
        alpha = f"{r['setting']['alpha']:.4g}" if "alpha" in r["setting"] else "-"
        if "ratios" in r:
            q = r["ratios"]
            load, floor = f"{q['wall_lo']:.3f} / {q['wall_hi']:.3f}", f"{q['floor']:.3f}"
        else:
            load, floor = f"{r.get('mean_pressure_over_P', float('nan')):.3f}", "-"
        lines.append(
            f"| {r['scene']}, {r['n']:,} | {r['method']} | {alpha} | {load} | {floor} | {r['loaded']:,} | "
            f"{r['jaccard']:.3f} | {r['force_sum_over_load']:.1e} | {r['seconds'] * 1e3:.1f} / "
            f"{r['cpu_seconds'] * 1e3:.1f} |"
        )
    return "\n".join(lines) + "\n" + deme


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="YADE's alpha-shape caps against the lamp's wetted surface.")
    parser.add_argument("--repeats", type=int, default=3, help="timed calls per method")
    parser.add_argument("--sweep", action="store_true", help="also the alpha sweep (probe 0.75 r to 8 r)")
    parser.add_argument("--json", metavar="PATH", help="write the result as JSON")
    args = parser.parse_args(argv)
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    result = bench_engines(repeats=args.repeats, sweep=args.sweep)
    print(format_engines(result))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
