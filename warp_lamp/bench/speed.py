"""``warp-lamp bench``: speed against error for the shining lamp, with device ceilings and peers."""

from __future__ import annotations

import time

import numpy as np
import warp as wp

from warp_lamp.bench.common import MISSING, lattice_grid, markdown_table
from warp_lamp.bench.modes import bench_modes, format_modes, plot_area
from warp_lamp.grid import LampGrid
from warp_lamp.kernels import peers as peer_kernels
from warp_lamp.lamp import ShiningLamp, lamp_update, pressure_area
from warp_lamp.measures import envelope_stress, lone_sphere_error, stress_summary
from warp_lamp.scenes import Scene, scene_lattice_box, scene_sphere_specimen
from warp_lamp.timing import Progress, run_header, time_median, time_median_events

__all__ = [
    "bench_lamp",
    "format_tables",
    "place_labels",
    "plot",
    "specimen_stress",
    "time_bvh",
    "time_lamp",
]

P = 10.0e6


# --- ceilings ----------------------------------------------------------------------------------------------


def device_ceilings(device, *, quick: bool = False) -> dict:
    """Copy bandwidth and the random uint64 atomic_min rate into an L2-sized (8 MiB) table, measured now."""
    nbytes = (64 << 20) if (quick or not device.is_cuda) else (1 << 30)
    src = wp.zeros(nbytes // 4, dtype=wp.float32, device=device)
    dst = wp.empty_like(src)
    t_copy = time_median_events(lambda: wp.copy(dst, src), device, repeats=10)
    table = wp.full(1 << 20, value=np.uint64(2**64 - 1), dtype=wp.uint64, device=device)  # 8 MiB
    threads, iters = ((1 << 16), 16) if not device.is_cuda else ((1 << 20), 64)
    t_atomic = time_median_events(
        lambda: wp.launch(
            peer_kernels.probe_atomic_min, dim=threads, inputs=[1, iters, (1 << 20) - 1], outputs=[table], device=device
        ),
        device,
        repeats=10,
    )
    return {"copy_GBps": 2 * nbytes / t_copy / 1e9, "atomic_min_Gops": threads * iters / t_atomic / 1e9}


# --- error measures -----------------------------------------------------------------------------------------


def specimen_stress(scene: Scene, criterion: int, cells_per_diameter: float, device) -> dict:
    """The average stress the lamp's loads imply on a spherical specimen's envelope (:func:`envelope_stress`).

    Returns the mean pressure -tr(sigma)/3 / P, the deviatoric (Frobenius) norm / P, |M| / (P pi R^3) and the
    force sum.
    """
    lamp = lamp_update(
        scene.centers, scene.radii, cells_per_diameter=cells_per_diameter, criterion=criterion, device=device
    )
    f = lamp.counts_numpy() * pressure_area(P, lamp.grid)
    sigma = envelope_stress(scene.centers, f, scene.center, 4.0 / 3.0 * np.pi * scene.radius**3)
    moment = np.cross(scene.centers - scene.center, f).sum(axis=0)
    return {
        **stress_summary(sigma, P),
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


def time_lamp(scene: Scene, grid: LampGrid, criterion: int, device, *, repeats: int, **lamp_options) -> dict:
    """Cold update, warm eager update, graph replay and moving body (CUDA), and the update's steps, for one scene
    and grid. Positions go in frame coordinates (subtracted in float64), as :func:`lamp_forces` passes them.
    ``lamp_options`` go to :class:`ShiningLamp`."""
    n = scene.n
    lamp = ShiningLamp(grid, criterion=criterion, device=device, **lamp_options)
    pos = wp.array((scene.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    forces = wp.zeros(n, dtype=wp.vec3, device=device)
    lamp.update(pos, rad, in_frame=True)

    def cold():
        lamp.forget()
        lamp.update(pos, rad, in_frame=True)

    def warm():
        lamp.update(pos, rad, in_frame=True)

    out = {
        "cold_s": time_median_events(cold, device, repeats=max(3, repeats // 4), warmup=1),
        "eager_s": time_median_events(warm, device, repeats=repeats),
        "add_forces_s": time_median_events(lambda: lamp.add_forces(forces, P), device, repeats=repeats),
        "replay_s": None,
        "moving_s": None,
        "seed_s": None,
        "depth_s": None,
    }
    if device.is_cuda:
        with wp.ScopedCapture(device=device) as capture:
            lamp.update(pos, rad, in_frame=True)
        out["replay_s"] = time_median_events(lambda: wp.capture_launch(capture.graph), device, repeats=repeats)
        # A moving body: two position sets 1% of a mean radius apart, updated in turn, so that every update
        # starts from owners found at other positions, as in a simulation that updates every step.
        jitter = np.random.default_rng(5).normal(scale=0.01 * float(scene.radii.mean()), size=(n, 3))
        moved = wp.array((scene.centers + jitter - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
        with wp.ScopedCapture(device=device) as cap_moving:
            lamp.update(moved, rad, in_frame=True)
            lamp.update(pos, rad, in_frame=True)
        out["moving_s"] = time_median_events(lambda: wp.capture_launch(cap_moving.graph), device, repeats=repeats) / 2
        # The depth pass alone: replayed after a seed, which leaves the keys as the full update does.
        lamp.update(pos, rad, in_frame=True)
        with wp.ScopedCapture(device=device) as cap_seed:
            lamp.launch_seed()
        with wp.ScopedCapture(device=device) as cap_depth:
            lamp.launch_seed()
            lamp.launch_depth()
        out["seed_s"] = time_median_events(lambda: wp.capture_launch(cap_seed.graph), device, repeats=repeats)
        seed_depth = time_median_events(lambda: wp.capture_launch(cap_depth.graph), device, repeats=repeats)
        out["depth_s"] = seed_depth - out["seed_s"]
        wp.capture_launch(capture.graph)
    lit = lamp.diagnostics().lit
    out["lit_cells"] = int(sum(lit.values()))
    out["expected_updates"] = _expected_updates(scene.radii, grid, criterion)
    out["bytes_per_sphere"] = 12 + 4 + 12  # positions, radii (the caller's), signed counts (the lamp's)
    out["bytes_per_cell"] = 16  # a uint64 key per lamp, two lamps per cell
    out["lamp_bytes"] = grid.nbytes + 12 * n
    return out


def time_bvh(scene: Scene, grid: LampGrid, device, *, repeats: int) -> dict:
    """The Warp BVH ray caster on the same scene: build (boxes + BVH), and cast + scatter."""
    from warp_lamp.bench.peers import BvhLamp

    pos = wp.array((scene.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    peer = BvhLamp(grid, scene.n, device=device)
    build = time_median(lambda: peer.build(pos, rad), device, repeats=max(3, repeats // 4), warmup=1)
    cast = time_median_events(peer.cast, device, repeats=max(3, repeats // 2))
    return {"bvh_build_s": build, "bvh_cast_s": cast}


def time_reference(scene: Scene, grid: LampGrid, criterion: int) -> dict:
    from warp_lamp.reference import lamp_reference

    t0 = time.perf_counter()
    lamp_reference(scene.centers, scene.radii, grid, criterion=criterion)
    return {"reference_s": time.perf_counter() - t0}


# --- driver -----------------------------------------------------------------------------------------------


def bench_lamp(
    devices=None, *, quick: bool = False, progress: bool = True, sizes=None, repeats=None, modes: bool = True
) -> dict:
    """Run the lamp benchmark and return its results as a JSON-ready dict.

    Args:
        devices: Warp devices (names); all present when None.
        quick: A CPU-sized subset: about 40 s of CPU on the 2-core dev machine with the kernels compiled.
        progress: Show a progress bar on stderr.
        sizes: Lattice sizes per axis to time (default: 22, 46, 100 on CPU; up to 300 on CUDA; 22 when quick).
        repeats: Timed repeats per figure.
        modes: Also run :func:`~warp_lamp.bench.modes.bench_modes` (small bodies, area, wetted, frames); off, the
            speed, sweep and error sections alone (``bench/experiments/bench_split.py`` runs the two on two GPUs).
    """
    devices = [wp.get_device(d) for d in (devices or ["cpu"] + [d.alias for d in wp.get_cuda_devices()])]
    cpds = (2, 4, 8, 16)
    criteria = (1, 0)
    result = {
        **run_header(devices),
        "quick": quick,
        "devices": {},
        "speed": [],
        "sweep": [],
        "errors": [],
    }
    specimen = scene_sphere_specimen()
    samples = 64 if quick else 256
    work = len(cpds) * len(criteria) + len(devices) * (3 + len(cpds) * len(criteria))
    bar = Progress(work, "bench", enabled=progress)
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
            grid = lattice_grid(scene, 0.25)
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
                grid = lattice_grid(scene, dmean / k)
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
    if modes:
        result.update(bench_modes(devices, quick=quick, progress=progress, repeats=repeats))
    return result


def _ms(x):
    return MISSING if x is None else f"{x * 1e3:.3f}"


def format_tables(result: dict) -> str:
    """The benchmark's result as Markdown tables: ceilings, speed, error, speed against error."""
    lines = [f"warp {result['warp_version']}, commit {result['git_commit'][:10]}, {result['date']}", ""]
    lines += markdown_table(
        ["device", "name", "copy GB/s", "atomic_min G/s (8 MiB)"],
        [[a, d["name"], f"{d['copy_GBps']:.0f}", f"{d['atomic_min_Gops']:.2f}"] for a, d in result["devices"].items()],
    )
    lines += ["", "Lattice box (spacing 1, jitter 0.05, r in [0.4, 0.5]), cell 0.25, criterion 1, all six lamps:", ""]
    rows = []
    for r in result["speed"]:
        ceiling = result["devices"][r["device"]]["atomic_min_Gops"]
        rate = r["expected_updates"] / (r["depth_s"] or r["eager_s"]) / 1e9
        best = r["replay_s"] or r["eager_s"]
        rows.append(
            [
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
                f"{r['bvh_cast_s'] / best:.1f}x" if r.get("bvh_cast_s") else MISSING,
                f"{r['reference_s']:.2f}" if r.get("reference_s") else MISSING,
            ]
        )
    header = ["device", "spheres", "cold ms", "eager ms", "replay ms", "moving ms", "depth ms", "G updates/s"]
    header += ["of atomic ceiling", "BVH build ms", "BVH cast ms", "lamp vs cast", "NumPy ref s"]
    lines += markdown_table(header, rows)
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
    offsets = (
        "64 random offsets with --quick (the full run, and the README, use 256)"
        if result.get("quick")
        else ("256 random offsets")
    )
    lines += [
        "",
        f"Error (lone sphere E_area over {offsets}; SphereTest specimen stress from the loads, envelope volume):",
        "",
    ]
    lines += markdown_table(
        ["criterion", "cells/diameter", "E_area RMS", "mean p / P", "deviatoric / P", "moment / (P pi R^3)"],
        [
            [
                str(e["criterion"]),
                str(e["cells_per_diameter"]),
                f"{e['E_area']:.4f}",
                f"{e['mean_pressure_over_P']:.4f}",
                f"{e['deviatoric_over_P']:.4f}",
                f"{e['moment_over_PpiR3']:.2e}",
            ]
            for e in result["errors"]
        ],
    )
    lines += ["", "Speed against error (sweep scene, full update):", ""]
    lines += markdown_table(
        ["device", "spheres", "criterion", "cells/diameter", "E_area", "update ms", "cells"],
        [
            [
                s["device"],
                f"{s['n']:,}",
                str(s["criterion"]),
                str(s["cells_per_diameter"]),
                f"{s['E_area']:.4f}",
                _ms(s["replay_s"] or s["eager_s"]),
                f"{s['lit_cells']:,} lit",
            ]
            for s in result["sweep"]
        ],
    )
    lines.append(format_modes(result))
    return "\n".join(lines)


#: Where a point's label may go, in points from the point, in the order tried: upper right first.
_LABEL_OFFSETS = ((4, 3), (4, -10), (-22, 3), (-22, -10), (4, 11), (-22, 11), (4, -18), (-22, -18), (12, -4))


def place_labels(ax, labels) -> list:
    """Annotate points so that no two labels overlap: each label (``(text, (x, y), fontsize)``, in data
    coordinates) takes the first of :data:`_LABEL_OFFSETS` whose box meets no label placed before it (the last
    one tried when all are taken). Returns the annotations."""
    renderer = ax.figure.canvas.get_renderer()
    placed, boxes = [], []
    for text, xy, size in labels:
        ann = None
        for dx, dy in _LABEL_OFFSETS:
            if ann is not None:
                ann.remove()
            ann = ax.annotate(text, xy, fontsize=size, xytext=(dx, dy), textcoords="offset points")
            box = ann.get_window_extent(renderer)
            if not any(box.overlaps(b) for b in boxes):
                break
        boxes.append(ann.get_window_extent(renderer))
        placed.append(ann)
    return placed


def plot(result: dict, path: str) -> None:
    """Time per update against E_area, one panel per device (each times its own scene size), one curve per
    criterion; and, with the ``area`` section, a last panel of update time against the specimen's force error for
    criterion 1 and the area criterion (needs matplotlib: the ``plot`` extra)."""
    try:
        import matplotlib
    except ImportError as e:
        raise SystemExit(
            "--plot needs matplotlib: pip install '.[plot]' in a clone, or pip install 'warp-lamp[plot]'"
        ) from e
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    devices = list(dict.fromkeys(s["device"] for s in result["sweep"]))
    area = bool(result.get("area"))
    fig, axes = plt.subplots(1, len(devices) + area, figsize=(4.6 * (len(devices) + area), 4.6), squeeze=False)
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    labels = {ax: [] for ax in axes[0]}
    for ax, dev in zip(axes[0][: len(devices)], devices, strict=True):
        for crit, marker in ((1, "o"), (0, "s")):
            pts = [s for s in result["sweep"] if s["device"] == dev and s["criterion"] == crit]
            if not pts:
                continue
            err = [100.0 * s["E_area"] for s in pts]
            t = [(s["replay_s"] or s["eager_s"]) * 1e3 for s in pts]
            label = "criterion 1 (centre ray)" if crit == 1 else "criterion 0 (overlap)"
            ax.loglog(err, t, marker + "-", label=label)
            labels[ax] += [(f"d/{s['cells_per_diameter']}", (x, y), 7) for s, x, y in zip(pts, err, t, strict=True)]
        n = next(s["n"] for s in result["sweep"] if s["device"] == dev)
        ax.set_title(f"{dev} ({result['devices'][dev]['name']}), {n:,} spheres", fontsize=9)
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            axis.set_major_formatter(plain)
            axis.set_minor_formatter(NullFormatter())
        ax.tick_params(labelsize=8)
        ax.grid(True, which="both", alpha=0.3)
        ax.set_xlabel(r"$E_\mathrm{area}$ [%]: lone-sphere force error, RMS", fontsize=9)
        ax.legend(fontsize=8, loc="lower left")
        ax.margins(x=0.12, y=0.08)
    axes[0, 0].set_ylabel("full update of all six lamps [ms]", fontsize=9)
    if area:
        ax = axes[0, -1]
        labels[ax] = plot_area(ax, result)
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            axis.set_major_formatter(plain)
            axis.set_minor_formatter(NullFormatter())
        ax.tick_params(labelsize=8)
    fig.suptitle("Shining lamp: time against error, per device", fontsize=10)
    fig.text(
        0.5,
        0.01,
        r"$E_\mathrm{area}$: RMS over random sub-cell offsets and the six lamps of $F / (P \pi r^2) - 1$, $F$ the "
        "force one lamp puts on a lone sphere; d/k: k cells per diameter; every error axis in per cent",
        ha="center",
        fontsize=7.5,
    )
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    for ax, items in labels.items():  # after the layout, which fixes where each point lands
        place_labels(ax, items)
    fig.savefig(path, dpi=120)
