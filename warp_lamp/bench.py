"""``warp-lamp bench``: speed against error for the shining lamp, with device ceilings and peers."""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

from warp_lamp.grid import LampGrid
from warp_lamp.kernels import lamp as KL
from warp_lamp.kernels import peers as KP
from warp_lamp.lamp import LAMPS, ShiningLamp, lamp_solve, pressure_area
from warp_lamp.scenes import Scene, scene_lattice_box, scene_sphere_specimen

__all__ = ["bench_lamp", "lone_sphere_error", "specimen_stress"]

P = 10.0e6


# --- timing -----------------------------------------------------------------------------------------------


def _median_time(fn, device, repeats: int, warmup: int = 2) -> float:
    """Median seconds of fn() with the device synchronised around each call, after a warm-up."""
    for _ in range(warmup):
        fn()
    wp.synchronize_device(device)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        wp.synchronize_device(device)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def _median_gpu_time(fn, device, repeats: int, warmup: int = 3) -> float:
    """Median seconds between CUDA events around fn(), after a warm-up: GPU time, without host overhead."""
    if not device.is_cuda:
        return _median_time(fn, device, repeats, warmup)
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        e0 = wp.Event(device, enable_timing=True)
        e1 = wp.Event(device, enable_timing=True)
        wp.record_event(e0)
        fn()
        wp.record_event(e1)
        wp.synchronize_event(e1)
        times.append(wp.get_event_elapsed_time(e0, e1) / 1e3)
    return float(np.median(times))


def device_ceilings(device, *, quick: bool = False) -> dict:
    """Copy bandwidth and the random uint64 atomic_min rate into an L2-sized (8 MiB) table, measured now."""
    nbytes = (64 << 20) if (quick or not device.is_cuda) else (1 << 30)
    src = wp.zeros(nbytes // 4, dtype=wp.float32, device=device)
    dst = wp.empty_like(src)
    t_copy = _median_gpu_time(lambda: wp.copy(dst, src), device, 10)
    table = wp.full(1 << 20, value=np.uint64(2**64 - 1), dtype=wp.uint64, device=device)  # 8 MiB
    threads, iters = ((1 << 16), 16) if not device.is_cuda else ((1 << 20), 64)
    t_atomic = _median_gpu_time(
        lambda: wp.launch(
            KP.probe_atomic_min, dim=threads, inputs=[1, iters, (1 << 20) - 1], outputs=[table], device=device
        ),
        device,
        10,
    )
    return {"copy_GBps": 2 * nbytes / t_copy / 1e9, "atomic_min_Gops": threads * iters / t_atomic / 1e9}


# --- error measures -----------------------------------------------------------------------------------------


def lone_sphere_error(criterion: int, cells_per_diameter: float, device, *, samples: int = 256, seed: int = 7):
    """E_area: RMS over random sub-cell offsets, and over the six lamps, of F_lamp / (P pi r^2) - 1."""
    r = 0.5
    h = 2 * r / cells_per_diameter
    grid = LampGrid([-1.0] * 3, [1.0] * 3, h)
    lamp = ShiningLamp(grid, criterion=criterion, device=device)
    offsets = np.random.default_rng(seed).uniform(0.0, h, (samples, 3))
    rad = wp.array([r], dtype=wp.float32, device=device)
    errs = []
    for off in offsets:
        lamp.update(wp.array([off], dtype=wp.vec3, device=device), rad)
        lit = lamp.diagnostics().lit
        errs.extend(lit[name] * h * h / (np.pi * r * r) - 1.0 for name in LAMPS)
    return float(np.sqrt(np.mean(np.square(errs))))


def specimen_stress(scene: Scene, criterion: int, cells_per_diameter: float, device) -> dict:
    """Average stress the lamp loads imply, sigma = (1/V) sum x_i (x) F_i, on the envelope volume V.

    Returns the mean pressure -tr(sigma)/3 / P, the deviatoric (Frobenius) norm / P, and |M| / (P pi R^3).
    """
    lamp = lamp_solve(
        scene.centers, scene.radii, cells_per_diameter=cells_per_diameter, criterion=criterion, device=device
    )
    f = lamp.counts_numpy() * pressure_area(P, lamp.grid)
    x = scene.centers - scene.center
    volume = 4.0 / 3.0 * np.pi * scene.radius**3
    sigma = np.einsum("ni,nj->ij", x, f) / volume
    mean = -np.trace(sigma) / 3.0
    dev = sigma + mean * np.eye(3)
    moment = np.cross(x, f).sum(axis=0)
    return {
        "mean_pressure_over_P": float(mean / P),
        "deviatoric_over_P": float(np.linalg.norm(dev) / P),
        "moment_over_PpiR3": float(np.linalg.norm(moment) / (P * np.pi * scene.radius**3)),
        "force_sum": f.sum(axis=0).tolist(),
    }


# --- the lamp's speed ---------------------------------------------------------------------------------------


def _expected_updates(radii, grid: LampGrid, criterion: int, lamp_count: int = 2) -> float:
    """Expected number of (sphere, cell) offers per update over random placements: each sphere offers a key
    to both lamps of every cell its footprint covers on each axis."""
    total = 0.0
    for a in range(3):
        hu, hv = grid.cell[a]
        if criterion == 1:
            cells = np.pi * radii**2 / (hu * hv)
        else:
            cells = (np.pi * radii**2 + 2 * radii * (hu + hv) + hu * hv) / (hu * hv)
        total += lamp_count * float(cells.sum())
    return total


def _lattice_grid(scene: Scene, cell: float) -> LampGrid:
    lo = scene.centers.min(axis=0) - scene.radii.max() - cell
    hi = scene.centers.max(axis=0) + scene.radii.max() + cell
    return LampGrid(lo, hi, cell)


def time_lamp(scene: Scene, grid: LampGrid, criterion: int, device, *, repeats: int) -> dict:
    """Cold update, warm eager update, graph replay (CUDA), and the pieces, for one scene and grid."""
    n = scene.n
    lamp = ShiningLamp(grid, criterion=criterion, device=device)
    pos = wp.array((scene.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    origin = wp.vec3(0.0, 0.0, 0.0)
    forces = wp.zeros(n, dtype=wp.vec3, device=device)
    lamp._update(pos, rad, None, origin)

    def cold():
        lamp.forget()
        lamp._update(pos, rad, None, origin)

    def warm():
        lamp._update(pos, rad, None, origin)

    out = {
        "cold_s": _median_gpu_time(cold, device, max(3, repeats // 4), warmup=1),
        "eager_s": _median_gpu_time(warm, device, repeats),
        "add_forces_s": _median_gpu_time(lambda: lamp.add_forces(forces, P), device, repeats),
    }
    if device.is_cuda:
        with wp.ScopedCapture(device=device) as capture:
            lamp._update(pos, rad, None, origin)
        out["replay_s"] = _median_gpu_time(lambda: wp.capture_launch(capture.graph), device, repeats)
        # A moving body: two position sets 1% of a mean radius apart, updated in turn, so that every update
        # starts from owners found at other positions, as in a simulation that updates every step.
        jitter = np.random.default_rng(5).normal(scale=0.01 * float(scene.radii.mean()), size=(n, 3))
        moved = wp.array((scene.centers + jitter - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
        with wp.ScopedCapture(device=device) as cap_moving:
            lamp._update(moved, rad, None, origin)
            lamp._update(pos, rad, None, origin)
        out["moving_s"] = _median_gpu_time(lambda: wp.capture_launch(cap_moving.graph), device, repeats) / 2
        # The depth pass alone, replayed after a seed (which leaves the keys as the full update does).
        grid_args = [lamp._corner_u, lamp._corner_v, lamp._h_u, lamp._h_v, lamp._n_u]
        seed = [pos, rad, lamp._no_active, n, origin, *grid_args, lamp._offset, lamp.criterion]
        depth = [pos, rad, lamp._no_active, origin, *grid_args, lamp._n_v, lamp._offset, lamp.criterion, lamp.lamp_mask]

        def seed_launch():
            wp.launch(KL.lamp_seed, dim=lamp._n_cells, inputs=seed, outputs=[lamp.keys], device=device)

        with wp.ScopedCapture(device=device) as cap_seed:
            seed_launch()
        with wp.ScopedCapture(device=device) as cap_depth:
            seed_launch()
            wp.launch(
                KL.lamp_depth,
                dim=n,
                inputs=depth,
                outputs=[lamp.keys, lamp.diag],
                device=device,
                block_dim=KL.DEPTH_BLOCK_DIM,
            )
        t_fill = _median_gpu_time(lambda: wp.capture_launch(cap_seed.graph), device, repeats)
        out["seed_s"] = t_fill
        out["depth_s"] = _median_gpu_time(lambda: wp.capture_launch(cap_depth.graph), device, repeats) - t_fill
        wp.capture_launch(capture.graph)
    else:
        out["replay_s"] = None
        out["depth_s"] = None
        out["moving_s"] = None
    lit = lamp.diagnostics().lit
    out["lit_cells"] = int(sum(lit.values()))
    out["expected_updates"] = _expected_updates(scene.radii, grid, criterion)
    out["bytes_per_sphere"] = 12 + 4 + 12  # positions, radii (the caller's), signed counts (the lamp's)
    out["bytes_per_cell"] = 16  # a uint64 key per lamp, two lamps per cell
    out["lamp_bytes"] = grid.nbytes + 12 * n
    return out


def time_bvh(scene: Scene, grid: LampGrid, device, *, repeats: int) -> dict:
    """The Warp BVH ray caster on the same scene: build (boxes + BVH), and cast + scatter."""
    from warp_lamp.peers import BvhLamp

    pos = wp.array((scene.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    peer = BvhLamp(grid, scene.n, device=device)
    build = _median_time(lambda: peer.build(pos, rad), device, max(3, repeats // 4), warmup=1)
    cast = _median_gpu_time(peer.cast, device, max(3, repeats // 2))
    return {"bvh_build_s": build, "bvh_cast_s": cast}


def time_reference(scene: Scene, grid: LampGrid, criterion: int) -> dict:
    from warp_lamp.reference import lamp_reference

    t0 = time.perf_counter()
    lamp_reference(scene.centers, scene.radii, grid, criterion=criterion)
    return {"reference_s": time.perf_counter() - t0}


# --- driver -----------------------------------------------------------------------------------------------


class _Progress:
    """tqdm when installed (the `progress` extra), else a one-line counter on stderr."""

    def __init__(self, total: int, desc: str, enabled: bool):
        self.bar = None
        self.total, self.done, self.enabled, self.desc = total, 0, enabled, desc
        if enabled:
            try:
                from tqdm import tqdm

                self.bar = tqdm(total=total, desc=desc, file=sys.stderr, leave=False)
            except ImportError:
                pass

    def step(self, what: str) -> None:
        self.done += 1
        if self.bar is not None:
            self.bar.set_postfix_str(what)
            self.bar.update(1)
        elif self.enabled:
            print(f"\r{self.desc} {self.done}/{self.total} {what:<40}", end="", file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        elif self.enabled:
            print(file=sys.stderr)


def _git_commit() -> str:
    if os.environ.get("WARP_LAMP_COMMIT"):  # the device machine gets a copy of the tree without .git
        return os.environ["WARP_LAMP_COMMIT"]
    try:
        root = Path(__file__).resolve().parent.parent
        return subprocess.check_output(
            ["git", "rev-parse", "HEAD"], cwd=root, text=True, stderr=subprocess.DEVNULL
        ).strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def bench_lamp(devices=None, *, quick: bool = False, progress: bool = True, sizes=None, repeats=None) -> dict:
    """Run the lamp benchmark and return its results as a JSON-ready dict.

    Args:
        devices: Warp devices (names); all present when None.
        quick: A CPU-sized subset that runs in well under a minute.
        progress: Show a progress bar on stderr.
        sizes: Lattice sizes per axis to time (default: 22, 46, 100 on CPU; up to 300 on CUDA; 22 when quick).
        repeats: Timed repeats per figure.
    """
    devices = [wp.get_device(d) for d in (devices or ["cpu"] + [d.alias for d in wp.get_cuda_devices()])]
    cpds = (2, 4, 8, 16)
    criteria = (1, 0)
    result = {
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "warp_version": wp.__version__,
        "git_commit": _git_commit(),
        "host": platform.node(),
        "quick": quick,
        "devices": {},
        "speed": [],
        "sweep": [],
        "errors": [],
    }
    specimen = scene_sphere_specimen()
    samples = 64 if quick else 256
    work = len(cpds) * len(criteria) + len(devices) * (3 + len(cpds) * len(criteria))
    bar = _Progress(work, "bench", progress)
    for criterion in criteria:
        for k in cpds:
            row = {"criterion": criterion, "cells_per_diameter": k}
            row["E_area"] = lone_sphere_error(criterion, k, devices[0], samples=samples)
            row.update(specimen_stress(specimen, criterion, k, devices[0]))
            result["errors"].append(row)
            bar.step(f"errors c{criterion} d/{k}")
    for device in devices:
        gpu = device.is_cuda
        reps = repeats or (5 if quick else (50 if gpu else 5))
        result["devices"][device.alias] = {"name": device.name, **device_ceilings(device, quick=quick)}
        if sizes is not None:
            dev_sizes = sizes
        elif quick:
            dev_sizes = (22,)
        else:
            dev_sizes = (22, 46, 100, 200, 300) if gpu else (22, 46, 100)
        for m in dev_sizes:
            scene = scene_lattice_box(m)
            grid = _lattice_grid(scene, 0.25)
            row = {
                "device": device.alias,
                "scene": scene.name,
                "n": scene.n,
                "cell": 0.25,
                "criterion": 1,
                "cells": grid.n_cells,
            }
            row.update(time_lamp(scene, grid, 1, device, repeats=reps))
            if gpu or m <= 46:
                row.update(time_bvh(scene, grid, device, repeats=reps))
            if m <= 22:
                row.update(time_reference(scene, grid, 1))
            result["speed"].append(row)
            bar.step(f"{device.alias} n={scene.n}")
        # Speed against error: the sweep scene at each resolution and criterion.
        m = 100 if gpu else (22 if quick else 46)
        scene = scene_lattice_box(m)
        dmean = 2 * float(scene.radii.mean())
        for criterion in criteria:
            for k in cpds:
                grid = _lattice_grid(scene, dmean / k)
                t = time_lamp(scene, grid, criterion, device, repeats=reps)
                err = next(e for e in result["errors"] if e["criterion"] == criterion and e["cells_per_diameter"] == k)
                result["sweep"].append(
                    {
                        "device": device.alias,
                        "n": scene.n,
                        "criterion": criterion,
                        "cells_per_diameter": k,
                        "E_area": err["E_area"],
                        **t,
                    }
                )
                bar.step(f"{device.alias} sweep c{criterion} d/{k}")
    bar.close()
    return result


def _ms(x):
    return "-" if x is None else f"{x * 1e3:.3f}"


def format_tables(result: dict) -> str:
    lines = [f"warp {result['warp_version']}, commit {result['git_commit'][:10]}, {result['date']}", ""]
    lines.append("| device | name | copy GB/s | atomic_min G/s (8 MiB) |")
    lines.append("| --- | --- | --- | --- |")
    for alias, d in result["devices"].items():
        lines.append(f"| {alias} | {d['name']} | {d['copy_GBps']:.0f} | {d['atomic_min_Gops']:.2f} |")
    lines += ["", "Lattice box (spacing 1, jitter 0.05, r in [0.4, 0.5]), cell 0.25, criterion 1, all six lamps:", ""]
    lines.append(
        "| device | spheres | cold ms | eager ms | replay ms | depth ms | G updates/s | of atomic ceiling "
        "| BVH build ms | BVH cast ms | lamp vs cast | NumPy ref s |"
    )
    lines.append("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in result["speed"]:
        ceiling = result["devices"][r["device"]]["atomic_min_Gops"]
        depth = r["depth_s"] or r["eager_s"]
        rate = r["expected_updates"] / depth / 1e9
        best = r["replay_s"] or r["eager_s"]
        ratio = f"{r['bvh_cast_s'] / best:.1f}x" if "bvh_cast_s" in r else "-"
        cells = [
            r["device"],
            f"{r['n']:,}",
            _ms(r["cold_s"]),
            _ms(r["eager_s"]),
            _ms(r["replay_s"]),
            _ms(r["moving_s"]),
            _ms(r["depth_s"]),
            f"{rate:.1f}",
            f"{rate / ceiling:.2f}",
            _ms(r.get("bvh_build_s")),
            _ms(r.get("bvh_cast_s")),
            ratio,
            f"{r.get('reference_s', float('nan')):.2f}",
        ]
        lines.append("| " + " | ".join(cells) + " |")
    for r in result["speed"]:
        if "reference_s" in r:
            best = r["replay_s"] or r["eager_s"]
            lines.append(
                f"\nNumPy float64 reference on {r['device']}, {r['n']:,} spheres: {r['reference_s']:.2f} s, "
                f"{r['reference_s'] / best:,.0f}x the lamp's update"
            )
    r0 = result["speed"][-1]
    lines.append(
        f"Memory: {r0['bytes_per_sphere']} B per sphere (12 position + 4 radius of the caller's, 12 counts "
        f"of the lamp's), {r0['bytes_per_cell']} B per cell; nothing allocated per update."
    )
    lines += ["", "Error (lone sphere E_area; SphereTest specimen stress from the loads, envelope volume):", ""]
    lines.append("| criterion | cells/diameter | E_area RMS | mean p / P | deviatoric / P | moment / (P pi R^3) |")
    lines.append("| --- | --- | --- | --- | --- | --- |")
    for e in result["errors"]:
        lines.append(
            f"| {e['criterion']} | {e['cells_per_diameter']} | {e['E_area']:.4f} | "
            f"{e['mean_pressure_over_P']:.4f} | {e['deviatoric_over_P']:.4f} | {e['moment_over_PpiR3']:.2e} |"
        )
    lines += ["", "Speed against error (sweep scene, full update):", ""]
    lines.append("| device | spheres | criterion | cells/diameter | E_area | update ms | cells |")
    lines.append("| --- | --- | --- | --- | --- | --- | --- |")
    for s in result["sweep"]:
        lines.append(
            f"| {s['device']} | {s['n']:,} | {s['criterion']} | {s['cells_per_diameter']} | "
            f"{s['E_area']:.4f} | {_ms(s['replay_s'] or s['eager_s'])} | {s['lit_cells']:,} lit |"
        )
    return "\n".join(lines)


def plot(result: dict, path: str) -> None:
    """Time per update against E_area, one curve per device and criterion (needs the `plot` extra)."""
    try:
        import matplotlib
    except ImportError as e:
        raise SystemExit("--plot needs matplotlib: pip install 'warp-lamp[plot]'") from e
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 5.2))
    keys = sorted({(s["device"], s["criterion"]) for s in result["sweep"]})
    for dev, crit in keys:
        pts = [s for s in result["sweep"] if s["device"] == dev and s["criterion"] == crit]
        err = [s["E_area"] for s in pts]
        t = [(s["replay_s"] or s["eager_s"]) * 1e3 for s in pts]
        name = result["devices"][dev]["name"]
        ax.loglog(err, t, "o-", label=f"{dev} ({name}), criterion {crit}, {pts[0]['n']:,} spheres")
        for s, x, y in zip(pts, err, t, strict=True):
            ax.annotate(f"d/{s['cells_per_diameter']}", (x, y), fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax.set_xlabel("lone-sphere area error E_area (RMS)")
    ax.set_ylabel("full update [ms]")
    ax.set_title("Shining lamp: time against error")
    ax.grid(True, which="both", alpha=0.3)
    fig.legend(fontsize=7, loc="lower center", ncol=2, frameon=False)
    fig.tight_layout(rect=(0, 0.1, 1, 1))
    fig.savefig(path, dpi=120)
