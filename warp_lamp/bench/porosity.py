"""``warp-lamp bench porosity``: speed against error of the porosity methods, and the paper's experiments."""

from __future__ import annotations

import functools
import importlib.util
import time
import warnings

import numpy as np
import warp as wp

from warp_lamp.bench.peers import overlap_hexahedron
from warp_lamp.porosity import POROSITY_METHODS, count_bitmap, kozeny_carman, porosity, porosity_mark_union
from warp_lamp.reference import PAPER_TABLE_1, midpoint_sphere_offsets
from warp_lamp.scenes import scene_overlapping_box
from warp_lamp.timing import Progress, run_header, time_median, time_median_events

__all__ = [
    "PAPER_CPU_SECONDS",
    "PAPER_WALL_SECONDS_SHARED",
    "bench_porosity",
    "format_porosity",
    "paper_experiment",
    "paper_note",
    "paper_work",
    "plot_histograms",
]

SUBDIVISIONS = (2, 4, 8, 16, 32)


def _error_scene(quick: bool):
    """A packing whose spheres overlap by under 1% of a radius, so that union and sum agree (r = 2.5 mm)."""
    size = (0.04, 0.04, 0.04) if quick else (0.1, 0.1, 0.2)
    scene = scene_overlapping_box(0.0025, size, solid_fraction=0.55, max_overlap=0.0099)
    shape = tuple(round(float(x) / 0.01) for x in size)
    return scene, np.zeros(3), np.asarray(size), shape


def _time_overlap_peer(scene, lower, upper, shape, limit_s: float = 20.0):
    """The `overlap` package called per sphere-cell pair (CPU), extrapolated from the pairs done in limit_s."""
    try:
        import overlap
    except ImportError:
        return None
    h = (upper - lower) / np.asarray(shape)
    pairs = 0
    t0 = time.perf_counter()
    for c, r in zip(scene.centers, scene.radii, strict=True):
        first = np.clip(np.floor((c - r - lower) / h), 0, np.asarray(shape) - 1).astype(int)
        last = np.clip(np.floor((c + r - lower) / h), 0, np.asarray(shape) - 1).astype(int)
        for idx in np.ndindex(*(last - first + 1)):
            lo = lower + (first + idx) * h
            hi = lo + h
            verts = overlap_hexahedron(lo, hi)
            overlap.overlap_volume(overlap.Sphere(tuple(c), float(r)), overlap.Hexahedron(verts))
            pairs += 1
        if time.perf_counter() - t0 > limit_s:
            break
    per_pair = (time.perf_counter() - t0) / max(pairs, 1)
    # Pairs in the whole scene: the same count for every sphere's bounding box.
    total_pairs = 0
    for c, r in zip(scene.centers, scene.radii, strict=True):
        first = np.clip(np.floor((c - r - lower) / h), 0, np.asarray(shape) - 1)
        last = np.clip(np.floor((c + r - lower) / h), 0, np.asarray(shape) - 1)
        total_pairs += int(np.prod(last - first + 1))
    return {"overlap_s": per_pair * total_pairs, "overlap_pairs": total_pairs, "overlap_measured_pairs": pairs}


#: ``bench porosity --paper`` on the 2-core development machine, CPU only, packings cached: 77 s of CPU time,
#: 4 min 37 s wall-clock while the machine was shared (a user's first trial took 3 min 57 s) [s].
PAPER_CPU_SECONDS = 77
PAPER_WALL_SECONDS_SHARED = 277


def paper_note(*, quick: bool = False) -> str:
    """What ``bench porosity --paper`` will take, said before it starts (one line, for stderr)."""
    if quick:
        return "warp-lamp: bench porosity --quick --paper takes about a minute on a CPU"
    m, s = divmod(PAPER_WALL_SECONDS_SHARED, 60)
    return (
        f"warp-lamp: bench porosity --paper takes minutes on a CPU ({PAPER_CPU_SECONDS} s of CPU time on a 2-core "
        f"machine, {m} min {s} s while it was shared; far less on a GPU), longer on the first run, which packs "
        "its scenes (cached); the progress bar covers all of it"
    )


def _quiet_midpoint(fn):
    """The benchmark measures the midpoint method's error at coarse subdivisions on purpose: its warning that the
    radii round badly there is what the error column shows, so it is not repeated on stderr."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="subdivisions: with", category=RuntimeWarning)
            return fn(*args, **kwargs)

    return wrapper


@_quiet_midpoint
def bench_porosity(
    devices=None, *, quick: bool = False, progress: bool = True, target: bool = False, paper: bool = False
) -> dict:
    """Time and error of every method against `exact`, per device; with ``target``, the 1 mm scene at 0.1 mm;
    with ``paper``, the paper's experiment (:func:`paper_experiment`, on the last device) under the same progress
    bar, in the result's ``paper``."""
    devices = [wp.get_device(d) for d in (devices or ["cpu"] + [d.alias for d in wp.get_cuda_devices()])]
    scene, lower, upper, shape = _error_scene(quick)
    subs = (2, 4, 8) if quick else SUBDIVISIONS
    result = {
        **run_header(devices),
        "quick": quick,
        "scene": {"name": scene.name, "n": scene.n, "shape": list(shape), "size_m": (upper - lower).tolist()},
        "devices": {d.alias: d.name for d in devices},
        "rows": [],
    }
    args = (scene.centers, scene.radii, lower, upper, shape)
    exact = porosity(*args, method="exact", device=devices[0])
    paper_steps = paper_work(quick=quick) if paper else 0
    bar = Progress(len(devices) * (3 + 2 * len(subs)) + 1 + paper_steps, "bench porosity", enabled=progress)
    for device in devices:
        reps = 3 if not device.is_cuda else 10
        for method in POROSITY_METHODS:
            for s in subs if POROSITY_METHODS[method] == "union" else (None,):
                kw = {"method": method, "device": device}
                if s is not None:
                    kw["subdivisions"] = s
                p = porosity(*args, **kw)
                t = time_median(lambda kw=kw: porosity(*args, **kw), device, repeats=reps, warmup=1)
                err = p - exact
                result["rows"].append(
                    {
                        "device": device.alias,
                        "method": method,
                        "subdivisions": s,
                        "time_s": t,
                        "rms": float(np.sqrt(np.mean(err**2))),
                        "max": float(np.abs(err).max()),
                    }
                )
                bar.step(f"{device.alias} {method} {s}")
    result["peers"] = {"overlap": _time_overlap_peer(scene, lower, upper, shape)}
    bar.step("peer overlap")
    result["peers"]["porespy"] = (
        "installed, not timed: its spheres_from_coords rounds centres to voxels"
        if importlib.util.find_spec("porespy")
        else "not installed"
    )
    if target:
        result["target"] = time_target(devices)
    if paper:
        result["paper"] = paper_experiment(devices[-1], quick=quick, bar=bar)
    bar.close()
    return result


def time_target(devices) -> list:
    """The speed target: r = 1 mm box (about 300k spheres), 10 x 10 x 20 cells, 0.1 mm sub-cells (s = 100)."""
    scene = scene_overlapping_box(0.001, device=devices[-1])
    out = []
    for device in devices:
        args = (scene.centers, scene.radii, np.zeros(3), np.array([0.1, 0.1, 0.2]), (10, 10, 20))
        kw = {"method": "voxel", "subdivisions": 100, "device": device}
        if device.is_cuda:
            pos = wp.array(scene.centers, dtype=wp.vec3d, device=device)
            rad = wp.array(scene.radii, dtype=wp.float64, device=device)
            t = _time_voxel_device(pos, rad, args, device)
        else:
            t0 = time.perf_counter()
            porosity(*args, **kw)
            t = {"total_s": time.perf_counter() - t0}
        out.append({"device": device.alias, "n": scene.n, "subcells": 1000 * 1000 * 2000, **t})
    return out


def _time_voxel_device(pos, rad, args, device) -> dict:
    """Voxel's device work alone (clear, mark, count), CUDA events around a captured graph; arrays resident."""
    _, _, lower, upper, shape = args
    s = 100
    sub = tuple(x * s for x in shape)
    h = (upper - lower) / np.asarray(shape)
    bits = porosity_mark_union("voxel", pos, rad, h / s, sub, device)
    counts = wp.zeros(shape, dtype=wp.int64, device=device)

    def run():
        bits.zero_()
        counts.zero_()
        porosity_mark_union("voxel", pos, rad, h / s, sub, device, bits=bits)
        count_bitmap(bits, shape, s, counts)

    run()
    with wp.ScopedCapture(device=device) as cap:
        run()
    total = time_median_events(lambda: wp.capture_launch(cap.graph), device, repeats=10)
    return {"device_s": total, "bitmap_bytes": int(bits.shape[0] * 4)}


# --- the paper -----------------------------------------------------------------------------------------------


def table_1(samples: int = 64, seed: int = 0) -> list:
    """Sub-cells per sphere of radius 1 ... 25 sub-cells: the paper, our midpoint, our voxel (RMS over random
    sub-cell offsets of the centre), and the true volume."""
    rng = np.random.default_rng(seed)
    rows = []
    for r in range(1, 26):
        true = 4.0 / 3.0 * np.pi * r**3
        mid = len(midpoint_sphere_offsets(r))
        counts = []
        g = np.arange(-r - 1, r + 2) + 0.5
        for _ in range(samples):
            off = rng.uniform(0, 1, 3)
            d2 = (g - off[0])[:, None, None] ** 2 + (g - off[1])[None, :, None] ** 2 + (g - off[2])[None, None, :] ** 2
            counts.append(int(np.count_nonzero(d2 <= r * r)))
        counts = np.asarray(counts, dtype=np.float64)
        rows.append(
            {
                "r": r,
                "true": true,
                "paper": PAPER_TABLE_1[r - 1],
                "midpoint": mid,
                "voxel_rms": float(np.sqrt(np.mean(counts**2))),
                "voxel_rms_error": float(np.sqrt(np.mean((counts - true) ** 2)) / true),
            }
        )
    return rows


PAPER_RADII = (0.001, 0.0025, 0.005)


def paper_work(*, quick: bool = False, radii=PAPER_RADII) -> int:
    """Progress steps of :func:`paper_experiment`: one per scene and method, and Table 1."""
    return len(_paper_radii(quick, radii)) * (1 + len(POROSITY_METHODS)) + 1


def _paper_radii(quick: bool, radii) -> tuple:
    # Quick: a 4 cm cube, room for a few 2.5 mm spheres across, none for 5 mm at this density.
    return tuple(r for r in radii if r <= 0.0025) if quick else tuple(radii)


def paper_experiment(
    device=None, *, radii=PAPER_RADII, subdivisions: int = 100, quick: bool = False, bar: Progress | None = None
):
    """Section 3.2: a 10 x 10 x 20 cm box on a 10 x 10 x 20 grid, filled densely with overlapping spheres of each
    radius; porosity by every method; near-zero fractions and Kozeny-Carman ranges. ``bar`` advances by
    :func:`paper_work` steps."""
    radii = _paper_radii(quick, radii)
    size = np.array([0.04, 0.04, 0.04]) if quick else np.array([0.1, 0.1, 0.2])
    shape = tuple(round(float(x) / 0.01) for x in size)
    out = {"shape": list(shape), "size_m": size.tolist(), "subdivisions": subdivisions, "cases": []}
    for r in radii:
        scene = scene_overlapping_box(r, tuple(size), device=device)
        if bar is not None:
            bar.step(f"paper r = {r * 1e3:g} mm packing")
        case = {
            "radius": r,
            "n": scene.n,
            "solid_sum_fraction": float(np.sum(4 / 3 * np.pi * scene.radii**3) / np.prod(size)),
            "methods": {},
        }
        for method in POROSITY_METHODS:
            kw = {"method": method, "device": device}
            if POROSITY_METHODS[method] == "union":
                kw["subdivisions"] = subdivisions
            t0 = time.perf_counter()
            p = porosity(scene.centers, scene.radii, np.zeros(3), size, shape, **kw)
            dt = time.perf_counter() - t0
            ok = p > 0
            k = kozeny_carman(p[ok], r) if ok.any() else np.array([np.nan])
            case["methods"][method] = {
                "porosity": p.ravel().tolist(),
                "time_s": dt,
                "below_0.05": float(np.mean(p < 0.05)),
                "at_most_0": float(np.mean(p <= 0)),
                "min": float(p.min()),
                "mean": float(p.mean()),
                "kc_min": float(k.min()),
                "kc_max": float(k.max()),
                "kc_undefined_cells": int((~ok).sum()),
            }
            if bar is not None:
                bar.step(f"paper r = {r * 1e3:g} mm {method}")
        out["cases"].append(case)
    out["table_1"] = table_1()
    if bar is not None:
        bar.step("paper Table 1")
    return out


def plot_histograms(paper: dict, path: str) -> None:
    """Porosity histograms per method (rows) and radius (columns), as the paper's Figures 12-20 (needs
    matplotlib: the ``plot`` extra)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    methods = list(POROSITY_METHODS)
    cases = paper["cases"]
    colour = {"sum": "tab:red", "union": "tab:blue"}
    fig, axes = plt.subplots(
        len(methods), len(cases), figsize=(3.3 * len(cases), 1.9 * len(methods) + 0.9), squeeze=False, sharex=True
    )
    bins = np.linspace(-1.0, 1.0, 41)
    for j, case in enumerate(cases):
        for i, m in enumerate(methods):
            ax = axes[i, j]
            p = np.asarray(case["methods"][m]["porosity"])
            ax.hist(np.clip(p, -1.0, 1.0), bins=bins, color=colour[POROSITY_METHODS[m]])
            ax.axvline(0.05, color="k", lw=0.6, ls="--")
            if i == 0:
                ax.set_title(f"r = {case['radius'] * 1e3:g} mm ({case['n']:,} spheres)", fontsize=9)
            if j == 0:
                ax.set_ylabel(m, fontsize=9)
            ax.set_xticks([-1.0, -0.5, 0.0, 0.5, 1.0])
            ax.tick_params(labelsize=7)
            ax.text(0.03, 0.88, f"< 0.05: {case['methods'][m]['below_0.05']:.0%}", transform=ax.transAxes, fontsize=7)
    fig.supxlabel("cell porosity (clipped to [-1, 1]); dashed line: 0.05", fontsize=9)
    fig.supylabel("cells per bin (rows: method)", fontsize=9)
    fig.legend(
        handles=[
            Patch(color=colour["sum"], label="sum: overlaps count twice, may go below 0"),
            Patch(color=colour["union"], label="union: each sub-cell counted once"),
        ],
        loc="upper center",
        ncol=2,
        fontsize=8,
        frameon=False,
    )
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    fig.savefig(path, dpi=110)


def format_porosity(result: dict | None, paper: dict | None) -> str:
    lines = []
    if result:
        sc = result["scene"]
        lines += [
            f"warp {result['warp_version']}, commit {result['git_commit'][:10]}, {result['date']}",
            f"Error scene: {sc['name']}, {sc['n']:,} spheres overlapping < 1% of a radius, {sc['shape']} cells "
            "of 1 cm; error = porosity - exact porosity, over cells",
            "",
            "| device | method | subdivisions | time ms | RMS error | max error |",
            "| --- | --- | --- | --- | --- | --- |",
        ]
        for r in result["rows"]:
            s = "\u2013" if r["subdivisions"] is None else r["subdivisions"]
            lines.append(
                f"| {r['device']} | {r['method']} | {s} | {r['time_s'] * 1e3:.2f} | {r['rms']:.2e} | {r['max']:.2e} |"
            )
        ov = result["peers"].get("overlap")
        if ov:
            lines.append(
                f"\nPeer `overlap` per sphere-cell pair (CPU): {ov['overlap_s']:.2f} s for "
                f"{ov['overlap_pairs']:,} pairs (timed {ov['overlap_measured_pairs']:,})."
            )
        lines.append(f"Peer porespy: {result['peers']['porespy']}.")
        for t in result.get("target", []):
            lines.append(
                f"Target, r = 1 mm box, {t['n']:,} spheres, {t['subcells']:,} sub-cells, voxel on "
                f"{t['device']}: " + ", ".join(f"{k} {v * 1e3:.2f} ms" for k, v in t.items() if k.endswith("_s"))
            )
    if paper:
        lines += [
            "",
            "Table 1 (sub-cells per sphere of radius r sub-cells):",
            "",
            "| r | 4/3 pi r^3 | paper | our midpoint | voxel RMS over offsets | voxel RMS error |",
            "| --- | --- | --- | --- | --- | --- |",
        ]
        for t in paper["table_1"]:
            lines.append(
                f"| {t['r']} | {t['true']:.1f} | {t['paper']} | {t['midpoint']} | {t['voxel_rms']:.1f} | "
                f"{t['voxel_rms_error']:.2%} |"
            )
        lines += [
            "",
            f"Section 3.2 ({paper['shape']} cells, union methods at {paper['subdivisions']} subdivisions):",
            "",
            "| radius | spheres | method | porosity < 0.05 | porosity <= 0 | min | mean | Kozeny-Carman K [m^2] |",
            "| --- | --- | --- | --- | --- | --- | --- | --- |",
        ]
        for case in paper["cases"]:
            for m, v in case["methods"].items():
                kc = f"{v['kc_min']:.2e} .. {v['kc_max']:.2e}"
                if v["kc_undefined_cells"]:
                    kc += f" (undefined in {v['kc_undefined_cells']} cells)"
                lines.append(
                    f"| {case['radius'] * 1e3:g} mm | {case['n']:,} | {m} | {v['below_0.05']:.1%} | "
                    f"{v['at_most_0']:.1%} | {v['min']:.3f} | {v['mean']:.3f} | {kc} |"
                )
    return "\n".join(lines)
