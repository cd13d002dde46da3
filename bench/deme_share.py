"""The lamp's share of a DEM-Engine (DEME 3) step on a GPU: the SphereTest held at P, then per-step costs.

    python bench/deme_share.py --json out.json [--budget 450] [--big 1000000] [--steps 200]
    python bench/deme_share.py --standin --json out.json      # the whole flow on the CPU stand-in (tests/)

Stages, the JSON rewritten after each (so a stage that runs out of time keeps the ones before):

1. ``sphere_test``: ``examples/deme_sphere_test.py``'s run (the memo's specimen, 4,628 spheres, 10 MPa; DEME's first
   ``Initialize()`` on a machine compiles its kernels, about three minutes).
2. ``share`` at 4,628 spheres on the settled ball: DEME's step alone (``DoStepDynamics`` per call, and
   ``DoDynamics`` over many steps: DEME's own pace), DEME's copies alone (``PositionsToDevice``,
   ``AddAccFromDevice``, and the host list ``Positions()``), then :class:`~warp_lamp.engines.DemeLamp` with the
   lamp every step, first-hit and wetted (probe one mean radius): its read, lamp and write parts, the per-step
   queueing and DEME's step beside them.
3. The same at about ``--big`` spheres (a cubic-lattice ball, radii drawn from the specimen's largest fifth, the
   spacing twice the largest: neighbours touch or stand apart by up to 8% of the spacing, a looser body than the
   specimen, with fewer contacts), in a child process under the time left; wetted capped (``--cap`` seconds of
   updates). DEME compiles its domain box and its templates' volumes into its kernels: both bodies get one box and
   the specimen's templates, so that DEME compiles once (this is why the SphereTest runs in a box wide enough for
   the big ball).

The lamp's share of a step is (read + lamp + write) / every + queueing, over that plus DEME's step; printed for the
lamp every step and every 10 steps (the memo's ``ct_pressrate``).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

ROOT = Path(__file__).resolve().parent.parent
P = 10e6
MODES = ("first-hit", "wetted")


def _load(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def example():
    return sys.modules.get("deme_sphere_test") or _load("deme_sphere_test", ROOT / "examples" / "deme_sphere_test.py")


def lattice_body(n_target: int, pool, *, seed: int = 0):
    """A ball cut from a cubic lattice with about ``n_target`` spheres; spacing twice the largest radius of
    ``pool``'s upper fifth, radii drawn from that fifth (neighbours touch or stand apart by up to 8% of the spacing;
    no overlaps), so that DEME's templates can be the SphereTest's."""
    from warp_lamp.scenes import Scene

    pool = np.sort(np.asarray(pool, dtype=np.float64))
    top = pool[int(0.8 * len(pool)) :]
    spacing = 2.0 * float(top[-1])
    k = int(np.ceil((6.0 * n_target / np.pi) ** (1.0 / 3.0))) + 1
    axis = (np.arange(k) - (k - 1) / 2.0) * spacing
    pts = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    radius = (k - 1) / 2.0 * spacing
    pts = pts[np.linalg.norm(pts, axis=1) <= radius - 0.5 * spacing]
    radii = np.random.default_rng(seed).choice(top, len(pts))
    return Scene("lattice ball", pts, radii, np.zeros(3), radius)


def _median(v) -> float:
    return float(np.median(v)) if len(v) else float("nan")


def _times(fn, repeats: int) -> list[float]:
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def measure(
    deme,
    solver,
    tracker,
    radii,
    *,
    steps: int,
    cap_s: float,
    modes=MODES,
    device=None,
    hold=None,
    on_row=None,
    log=print,
) -> list:
    """Per-step costs on a built solver: DEME alone, DEME's copies, and the lamp in each mode (every step).
    ``hold``: a DemeLamp whose last load is queued (untimed) before each of DEME's lone steps, so that a settled
    ball stays under pressure while DEME is timed alone."""
    from warp_lamp.engines import DemeLamp

    n = len(radii)
    opts = {"device": device} if device else {}
    dev = wp.get_device(device) if device else wp.get_device("cuda:0" if wp.is_cuda_available() else "cpu")
    ordinal = dev.ordinal if dev.is_cuda else 0
    dt = float(solver.GetTimeStepSize())
    alone = []
    for k in range(steps + 5):
        if hold is not None:
            hold.apply()
        t0 = time.perf_counter()
        solver.DoStepDynamics()
        if k >= 5:
            alone.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    solver.DoDynamics(steps * dt)
    bulk = (time.perf_counter() - t0) / steps
    buf = wp.zeros(n, dtype=wp.vec3, device=dev)
    to_device = _times(lambda: tracker.PositionsToDevice(int(buf.ptr), n, ordinal, True), 20)
    zeros = wp.zeros(n, dtype=wp.vec3, device=dev)  # queued as accelerations: harmless
    from_device = _times(lambda: tracker.AddAccFromDevice(int(zeros.ptr), ordinal, True), 20)
    host = _times(tracker.Positions, 3)
    base = {
        "n": n,
        "deme_step_s": _median(alone),
        "deme_bulk_step_s": bulk,
        "positions_to_device_s": _median(to_device),
        "add_acc_from_device_s": _median(from_device),
        "positions_host_list_s": _median(host),
    }
    log(
        f"  {n:,} spheres: DEME step {base['deme_step_s'] * 1e6:.0f} us per call, {bulk * 1e6:.0f} us in DoDynamics; "
        f"PositionsToDevice {base['positions_to_device_s'] * 1e6:.0f} us, AddAccFromDevice "
        f"{base['add_acc_from_device_s'] * 1e6:.0f} us, Positions() {base['positions_host_list_s'] * 1e3:.1f} ms"
    )
    rows = []
    rho = float(np.mean(radii))
    for mode in modes:
        mode_opts = {"surfaces": "all", "probe_radius": rho} if mode == "wetted" else {}
        lamp = DemeLamp(solver, tracker, P, radii=radii, every=1, **mode_opts, **opts)
        t0 = time.perf_counter()
        lamp.step(1)  # the first update finds every owner (and may compile Warp's kernels)
        first = time.perf_counter() - t0
        start, capped = time.perf_counter(), False
        while lamp.steps < steps + 1:
            lamp.step(1)
            if time.perf_counter() - start > cap_s and lamp.steps >= 3:
                capped = True
                break
        c = lamp.cost(skip=1)
        update = c["wall"]["total"]
        row = {
            **base,
            "mode": mode,
            "updates": c["calls"],
            "capped": capped,
            "first_update_s": first,
            "read_s": c["wall"]["read"],
            "lamp_s": c["wall"]["lamp"],
            "write_s": c["wall"]["write"],
            "update_s": update,
            "apply_s": c["apply"],
            "step_with_lamp_s": c["step"],
            "cpu_s": c["cpu"],
        }
        for every in (1, 10):
            lamp_part = update / every + c["apply"]
            row[f"share_every_{every}"] = lamp_part / (lamp_part + c["step"])
        rows.append(row)
        if on_row is not None:
            on_row(rows)
        log(
            f"  {mode}: {c['calls']} updates{' (capped)' if capped else ''}, read {row['read_s'] * 1e6:.0f} us, "
            f"lamp {row['lamp_s'] * 1e3:.2f} ms, write {row['write_s'] * 1e6:.0f} us, queue {row['apply_s'] * 1e6:.0f} "
            f"us, DEME step {row['step_with_lamp_s'] * 1e6:.0f} us: share {row['share_every_1']:.1%} every step, "
            f"{row['share_every_10']:.1%} every 10"
        )
    return rows


def table(result: dict) -> str:
    """The per-step shares as Markdown."""
    lines = [
        "| spheres | mode | DEME step us | DoDynamics us/step | PositionsToDevice us | AddAccFromDevice us | "
        "read us | lamp ms | write us | queue us | share, lamp every step | every 10 |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in result.get("share", []):
        lines.append(
            f"| {r['n']:,} | {r['mode']}{' (capped)' if r['capped'] else ''} | {r['step_with_lamp_s'] * 1e6:.0f} | "
            f"{r['deme_bulk_step_s'] * 1e6:.0f} | {r['positions_to_device_s'] * 1e6:.0f} | "
            f"{r['add_acc_from_device_s'] * 1e6:.0f} | {r['read_s'] * 1e6:.0f} | {r['lamp_s'] * 1e3:.2f} | "
            f"{r['write_s'] * 1e6:.0f} | {r['apply_s'] * 1e6:.0f} | {r['share_every_1']:.1%} | "
            f"{r['share_every_10']:.1%} |"
        )
    return "\n".join(lines)


sys.path.insert(0, str(ROOT / "tests"))  # the stand-in (deme_standin.py)
sys.path.insert(1, str(ROOT))  # warp_lamp from this checkout, wherever the script runs from


def _deme(standin: bool):
    if standin:
        from deme_standin import StandInDeme

        return StandInDeme
    from warp_lamp.engines import load_deme

    return load_deme()


def _small_scene(standin: bool):
    from warp_lamp.scenes import scene_lattice_ball, scene_sphere_specimen

    if standin:
        s = scene_lattice_ball(diameter=0.03)
        s.centers *= 0.97
        return s
    return scene_sphere_specimen()


def _box(big):
    """One DEME domain for both bodies (the example's, unless the big body needs more), so DEME compiles once."""
    half = max(0.42, float(np.abs(big.centers).max() + big.radii.max()) * 1.05) if big is not None else 0.42
    return ((-half, half),) * 3


def big_stage(args) -> None:
    """Stage 3 in a child process: build the big body and measure, rewriting ``args.json`` after each mode (so a
    mode the parent's time limit stops keeps the rows before it)."""
    deme = _deme(args.standin)
    ex = example()
    small = _small_scene(args.standin)
    scene = lattice_body(args.big, small.radii)
    box = _box(scene)
    t0 = time.perf_counter()
    dt = 0.1 * ex.rayleigh_step(float(small.radii.min()))  # the SphereTest's step, as DEME's kernels were built for
    solver, tracker, init_s = ex.build(deme, scene.centers, scene.radii, dt=dt, box=box, template_radii=small.radii)
    print(f"  {scene.n:,} spheres built in {time.perf_counter() - t0:.1f} s (Initialize {init_s:.1f} s)", flush=True)

    def save(rows):
        with open(args.json, "w") as f:
            json.dump({"n": scene.n, "initialize_s": init_s, "rows": rows}, f)

    save([])
    device = "cpu" if args.standin else None
    measure(deme, solver, tracker, scene.radii, steps=args.steps, cap_s=args.cap, device=device, on_row=save,
            log=lambda m: print(m, flush=True))  # fmt: skip


def warm() -> None:
    """Compile Warp's kernels for the adapter (first-hit, wetted, the owner kernels) on a small body, so that a
    process started beside DEME's first compile finds them in Warp's cache."""
    from deme_standin import StandInSolver, StandInTracker

    from warp_lamp.engines import DemeLamp
    from warp_lamp.scenes import scene_lattice_ball

    s = scene_lattice_ball(diameter=0.03)
    device = "cuda:0" if wp.is_cuda_available() else "cpu"
    for opts in ({}, {"surfaces": "all", "probe_radius": float(s.radii.mean())}):
        tracker = StandInTracker(s.centers)
        # The stand-in's device calls read and write host memory: on a GPU the lamp takes the host path here,
        # which compiles the same lamp kernels; the owner kernels compile through a CPU-pointer-free launch.
        lamp = DemeLamp(StandInSolver(tracker), tracker, P, radii=s.radii, device=device, transfer="host", **opts)
        lamp.update()
    from warp_lamp.kernels import owners

    wp.load_module(owners, device=device)
    wp.synchronize()
    print(f"warm: Warp kernels ready on {device}", flush=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--json", required=True, help="the result file (rewritten after each stage)")
    parser.add_argument("--budget", type=float, default=450.0, help="seconds for all stages")
    parser.add_argument("--big", type=int, default=1_000_000, help="spheres of the big body (0: none)")
    parser.add_argument("--steps", type=int, default=200, help="timed steps per measurement")
    parser.add_argument("--cap", type=float, default=20.0, help="seconds of lamp updates per mode, at most")
    parser.add_argument("--settle", type=int, default=40000, help="SphereTest: most steps")
    parser.add_argument("--standin", action="store_true", help="run on the CPU stand-in of DEME (tests/)")
    parser.add_argument("--stage", choices=("all", "big", "warm"), default="all", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    t_start = time.perf_counter()
    if args.stage == "warm":
        warm()
        return 0
    if args.stage == "big":
        big_stage(args)
        return 0
    deme = _deme(args.standin)
    ex = example()
    device = "cpu" if args.standin else None
    result = {
        "what": "DEME 3 SphereTest under the lamp, and the lamp's share of a DEME step",
        "deme": getattr(deme, "__version__", "?"),
        "warp": wp.config.version,
        "gpu": wp.get_device("cuda:0").name if wp.is_cuda_available() and not args.standin else "cpu (stand-in)",
        "date": time.strftime("%Y-%m-%d", time.gmtime()),
        "stages": {},
    }

    def save():
        result["total_s"] = time.perf_counter() - t_start
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)

    # 1. The SphereTest (its settled solver is stage 2's).
    scene = _small_scene(args.standin)
    box = _box(lattice_body(args.big, scene.radii) if args.big > 0 else None)
    keep = {}
    t0 = time.perf_counter()
    log = lambda m: print(m, flush=True)  # noqa: E731
    st = ex.run(
        deme, scene, steps=args.settle, check=min(2000, args.settle), device=device, box=box, keep=keep, log=log
    )
    result["sphere_test"] = st
    result["stages"]["sphere_test"] = time.perf_counter() - t0
    save()
    print(ex.report(st), flush=True)
    # 2. Shares at 4,628 on the settled ball.
    t0 = time.perf_counter()
    rows = measure(deme, keep["solver"], keep["tracker"], scene.radii, steps=args.steps, cap_s=args.cap,
                   device=device, hold=keep["lamp"], log=log)  # fmt: skip
    result["share"] = rows
    result["stages"]["share_small"] = time.perf_counter() - t0
    save()
    # 3. The big body, in a child process under the time left.
    left = args.budget - (time.perf_counter() - t_start) - 10.0
    if args.big > 0 and left > 30.0:
        child = Path(args.json).with_suffix(".big.json")
        cmd = [sys.executable, __file__, "--stage", "big", "--json", str(child), "--big", str(args.big)]
        cmd += ["--steps", str(args.steps), "--cap", str(args.cap)] + (["--standin"] if args.standin else [])
        t0 = time.perf_counter()
        try:
            run = subprocess.run(cmd, timeout=left, check=False)
            status = time.perf_counter() - t0 if run.returncode == 0 else f"failed (exit {run.returncode})"
        except subprocess.TimeoutExpired:
            status = f"stopped after {left:.0f} s (the budget)"
        result["stages"]["share_big"] = status
        if child.exists():  # the rows the child finished, whatever stopped it
            big = json.loads(child.read_text())
            result["share"] += big["rows"]
            result["big_initialize_s"] = big["initialize_s"]
            child.unlink()
    else:
        result["stages"]["share_big"] = f"skipped ({left:.0f} s left)"
    save()
    print()
    print(f"DEME {result['deme']} on {result['gpu']}; stages: {result['stages']}")
    print(table(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
