"""The wetted surface's skin on one device: from scratch against the skin over a DEM-like run, bitwise every step.

"Kept" counts both kinds of kept voxel decision: dry voxels whose certificate holds, wet voxels whose witness
re-check holds (``WettedSurface(skin=...)``); "tested" the voxels that got the full exact test; "owners" the
crossings whose nearest sphere was kept without a search.

"Held": wet voxels kept by their witness's margin alone, without a search (a part of "witnessed").

Per scene (the SphereTest specimen and the slot block at 4 cells per diameter, rho = one mean radius):

1. Stage table from scratch (graphs that stop after each stage, static positions), as bench/experiments/wetted_bench.py.
2. The same with the skin at rest (primed, never reset: every certified dry decision kept): its stages.
3. The skin's reset update: two position sets one particle apart by 0.75 skin, updated in turn (every update takes
   a new reference and certifies again).
4. A DEM-like sequence: ``--steps`` updates, every particle's centre a random walk of ``--jiggle`` mean radii per
   step and coordinate, one particle jumping one mean radius every ``--jump-every`` steps; per step, one graph
   replay of the skinned surface and one of a from-scratch surface (CUDA events around each), the kept and tested
   counts, and a bitwise comparison of fluid words, counts, hits and the exact test's counters. On the CPU: eager.

    PYTHONPATH=$PWD python bench/gpu/parts/skin32_run.py --device cuda:0 --out $OUT/skin32.json
    PYTHONPATH=$PWD python bench/gpu/parts/skin32_run.py --device cpu --quick
"""

import argparse
import json
import time

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.kernels import wetted_base as KB
from warp_lamp.scenes import scene_lattice_box, scene_slot_block, scene_sphere_specimen
from warp_lamp.timing import run_header, time_median_events
from warp_lamp.wetted import WettedSurface


def capture(device, fn):
    with wp.ScopedCapture(device=device) as cap:
        fn()
    return cap.graph


def stage_table(surf, pos, rad, device, repeats):
    """Per stage [s] as differences of graphs (CUDA) or eager runs (CPU) that stop after each stage."""
    out, prev = {}, 0.0
    for s in surf.STAGES:
        if device.is_cuda:
            g = capture(device, lambda s=s: surf._update(pos, rad, None, stop=s))
            t = time_median_events(lambda g=g: wp.capture_launch(g), device, repeats=repeats)
        else:
            t = time_median_events(lambda s=s: surf._update(pos, rad, None, stop=s), device, repeats=repeats, warmup=1)
        out[s] = t - prev
        prev = t
    out["total"] = prev
    return out


def answer(surf):
    """The skin's counters and what must be bitwise equal: fluid words, counts, hits, per-ray crossings, and the
    exact test's counters (tested, found wet, thin intervals); host copies without unpacking the maps."""
    diag = surf.diag.numpy()
    st = surf._skin_state.numpy() if surf.skin else np.zeros(KB.N_SKIN, dtype=np.int32)
    skin = {
        "kept": int(st[KB.SKIN_KEPT]),
        "witnessed": int(st[KB.SKIN_WITNESSED]),
        "held": int(st[KB.SKIN_HELD]) if hasattr(KB, "SKIN_HELD") else 0,  # main's library has no margins
        "cross_kept": int(st[KB.SKIN_CROSS_KEPT]),
        "certified": int(st[KB.SKIN_CERTIFIED]),
        "reset": bool(st[KB.SKIN_RESET]),
    }
    key = (
        surf.fluid.numpy().tobytes(),
        surf.counts.numpy()[: 3 * surf.n].tobytes(),
        surf.hits.numpy()[: surf.n].tobytes(),
        surf.rays.numpy().tobytes(),
        int(diag[KB.DIAG_UNCERTAIN]),
        int(diag[KB.DIAG_RESCUED]),
        int(diag[KB.DIAG_THIN]),
    )
    return skin, key, int(diag[KB.DIAG_UNCERTAIN])


def bench_scene(name, scene, device, args):
    rbar = float(scene.radii.mean())
    rho = rbar
    grid = wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=4, margin=2.0 * rbar + rho)
    n = scene.n
    c0 = scene.centers - grid.origin
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    pos = wp.array(c0.astype(np.float32), dtype=wp.vec3, device=device)
    skin = WettedSurface(grid, probe_radius=rho, device=device, skin="auto")
    fresh = WettedSurface(grid, probe_radius=rho, device=device)
    row = {"scene": scene.name, "particles": n, "rho": rho, "cell": float(grid.cell[0, 0]), "skin": skin.skin}
    row["voxels"] = list(fresh.shape)
    reps = args.repeats
    t0 = time.perf_counter()
    fresh.update(pos, rad)
    skin.update(pos, rad)
    d0 = fresh.diagnostics()
    ds = skin.diagnostics()
    row.update(tested=d0.uncertain, wet=d0.rescued, certified=ds.skin_certified)
    row["scratch_stages_s"] = stage_table(fresh, pos, rad, device, reps)
    skin.update(pos, rad)  # primed at these positions: the stage graphs below keep every certificate
    row["skin_rest_stages_s"] = stage_table(skin, pos, rad, device, reps)
    rest = skin.diagnostics()
    row["skin_rest_kept"] = rest.skin_kept
    row["skin_rest_witnessed"] = rest.skin_witnessed
    row["skin_rest_held"] = getattr(rest, "skin_held", 0)
    row["skin_rest_cross_kept"] = rest.skin_cross_kept
    row["crossings"] = 2 * sum(int(c.sum()) for c in rest.crossings.values())
    # Every update a reset: one particle 0.75 skin away and back.
    moved_np = c0.copy()
    moved_np[0, 0] += 0.75 * skin.skin
    moved = wp.array(moved_np.astype(np.float32), dtype=wp.vec3, device=device)
    if device.is_cuda:
        g = capture(device, lambda: (skin.update(moved, rad), skin.update(pos, rad)))
        row["skin_reset_update_s"] = time_median_events(lambda: wp.capture_launch(g), device, repeats=reps) / 2
    else:
        row["skin_reset_update_s"] = (
            time_median_events(lambda: (skin.update(moved, rad), skin.update(pos, rad)), device, repeats=reps) / 2
        )
    # The DEM-like run, both surfaces reading one positions array that the host rewrites between steps.
    work = wp.array(c0.astype(np.float32), dtype=wp.vec3, device=device)
    if device.is_cuda:
        g_skin = capture(device, lambda: skin.update(work, rad))
        g_fresh = capture(device, lambda: fresh.update(work, rad))

        def run_skin():
            return wp.capture_launch(g_skin)

        def run_fresh():
            return wp.capture_launch(g_fresh)
    else:

        def run_skin():
            return skin.update(work, rad)

        def run_fresh():
            return fresh.update(work, rad)

    rng = np.random.default_rng(args.seed)
    c = c0.copy()
    steps = []
    mismatches = 0
    resets = 0
    for step in range(args.steps):
        c += rng.normal(scale=args.jiggle * rbar, size=c.shape)
        if args.jump_every and step % args.jump_every == args.jump_every - 1:
            j = int(rng.integers(n))
            c[j] += rng.normal(scale=rbar / np.sqrt(3.0), size=3)
        work.assign(c.astype(np.float32))
        ts = time_median_events(run_skin, device, repeats=1, warmup=0)  # each step once: it changes the state
        tf = time_median_events(run_fresh, device, repeats=1, warmup=0)
        ds, a, uncertain = answer(skin)
        _, b, _ = answer(fresh)
        same = a == b
        mismatches += 0 if same else 1
        resets += int(ds["reset"])
        steps.append(
            {
                "skin_s": ts,
                "scratch_s": tf,
                "kept": ds["kept"],
                "witnessed": ds["witnessed"],
                "held": ds["held"],
                "cross_kept": ds["cross_kept"],
                "tested": uncertain - ds["kept"] - ds["witnessed"],
                "certified": ds["certified"],
                "reset": ds["reset"],
                "same": bool(same),
            }
        )
    ts = np.array([s["skin_s"] for s in steps])
    tf = np.array([s["scratch_s"] for s in steps])
    kept = np.array([s["kept"] + s["witnessed"] for s in steps])
    tested = np.array([s["tested"] for s in steps])
    quiet = np.array([not s["reset"] for s in steps])
    row["dem"] = {
        "steps": args.steps,
        "jiggle_rbar": args.jiggle,
        "jump_every": args.jump_every,
        "mismatching_steps": mismatches,
        "resets": resets,
        "skin_median_s": float(np.median(ts)),
        "skin_mean_s": float(ts.mean()),
        "scratch_median_s": float(np.median(tf)),
        "scratch_mean_s": float(tf.mean()),
        "skin_quiet_median_s": float(np.median(ts[quiet])) if quiet.any() else None,
        "kept_fraction_mean": float((kept / np.maximum(kept + tested, 1)).mean()),
        "cross_kept_mean": float(np.mean([s["cross_kept"] for s in steps])),
        "held_mean": float(np.mean([s["held"] for s in steps])),
        "per_step": steps,
    }
    row["seconds"] = time.perf_counter() - t0
    return row


def scenes(quick):
    if quick:
        spec = scene_lattice_box(8)
        spec.name = "small lattice (quick stand-in for the specimen)"
        return [("specimen", spec)]
    return [("specimen", scene_sphere_specimen()), ("slot", scene_slot_block())]


def table(result) -> str:
    lines = [
        f"skin32 on {result['device']} ({result.get('name', '')}), rho = rbar, 4 cells/d; ms",
        "| scene | stage | scratch | skin at rest |",
        "| --- | --- | --- | --- |",
    ]
    for r in result["rows"]:
        for s in [*WettedSurface.STAGES, "total"]:
            lines.append(
                f"| {r['scene'][:24]} | {s} | {r['scratch_stages_s'][s] * 1e3:.3f} | "
                f"{r['skin_rest_stages_s'][s] * 1e3:.3f} |"
            )
    lines += [
        "",
        "| scene | tested | wet | certified | kept dry / wet (held) / owners at rest (crossings) | reset update ms "
        "| DEM steps | mismatching | resets | kept frac | skin median ms | skin quiet median | scratch median ms |",
        "| --- " * 13 + "|",
    ]
    for r in result["rows"]:
        m = r["dem"]
        quiet = m["skin_quiet_median_s"]
        lines.append(
            f"| {r['scene'][:24]} | {r['tested']} | {r['wet']} | {r['certified']} | "
            f"{r['skin_rest_kept']} / {r['skin_rest_witnessed']} ({r.get('skin_rest_held', '-')}) / "
            f"{r['skin_rest_cross_kept']} ({r['crossings']}) | "
            f"{r['skin_reset_update_s'] * 1e3:.3f} | {m['steps']} | {m['mismatching_steps']} | {m['resets']} | "
            f"{m['kept_fraction_mean']:.3f} | {m['skin_median_s'] * 1e3:.3f} | "
            f"{'-' if quiet is None else f'{quiet * 1e3:.3f}'} | {m['scratch_median_s'] * 1e3:.3f} |"
        )
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--device", default=None)
    ap.add_argument("--quick", action="store_true", help="a tiny scene (a CPU smoke run)")
    ap.add_argument("--only", nargs="*", default=None, help="scenes: specimen, slot")
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--jiggle", type=float, default=2e-4, help="random-walk step per coordinate [mean radii]")
    ap.add_argument("--jump-every", type=int, default=50, help="one particle jumps a mean radius this often")
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--seed", type=int, default=32)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    wp.config.quiet = True
    wp.init()
    device = wp.get_device(args.device)
    result = {**run_header([device]), "device": str(device), "name": getattr(device, "name", ""), "rows": []}
    for name, scene in scenes(args.quick):
        if args.only and name not in args.only:
            continue
        row = bench_scene(name, scene, device, args)
        result["rows"].append(row)
        m = row["dem"]
        print(
            f"{name}: {m['steps']} steps, {m['mismatching_steps']} mismatching, {m['resets']} resets, kept "
            f"{m['kept_fraction_mean']:.3f}, skin {m['skin_median_s'] * 1e3:.3f} ms vs scratch "
            f"{m['scratch_median_s'] * 1e3:.3f} ms (median), {row['seconds']:.0f} s",
            flush=True,
        )
        if args.out:
            with open(args.out, "w") as f:
                json.dump(result, f, indent=1)
    print(table(result))


if __name__ == "__main__":
    main()
