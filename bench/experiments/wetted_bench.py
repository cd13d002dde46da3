"""Speed of the wetted-surface mode beside the first-surface lamp, per stage, on the issue's scenes.

Scenes (all lamps, P = 1): the SphereTest specimen at 4 cells per diameter, the 1M jittered lattice box
(scene_lattice_box(100)) at cell 0.25, and the slot block at 4 cells per diameter; rho = one mean radius unless
--rho-diameters is given. On CUDA: graph replay (static and moving body: two position sets 1% of a mean radius
apart, updated in turn), and stage times as differences of graphs that stop after each stage. On the CPU: eager.

    PYTHONPATH=$PWD python bench/experiments/wetted_bench.py --device cuda:0 --out $OUT/wetted.json
    PYTHONPATH=$PWD python bench/experiments/wetted_bench.py --device cpu --quick
    PYTHONPATH=$PWD python bench/experiments/wetted_bench.py --device cpu --only specimen slot --rho-diameters 0.5 1
"""

import argparse
import hashlib
import json
import platform
import subprocess

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.scenes import scene_lattice_box, scene_slot_block, scene_sphere_specimen
from warp_lamp.timing import time_median_events
from warp_lamp.wetted import WettedSurface


def capture(device, fn):
    with wp.ScopedCapture(device=device) as cap:
        fn()
    return cap.graph


def scenes(quick):
    if quick:
        box = scene_lattice_box(20)
        spec = scene_lattice_box(12)
        spec.name = "small lattice (quick stand-in for the specimen)"
        slot = scene_slot_block((14, 14, 10), width=4, depth=4)
        return [("specimen", spec, None), ("lattice", box, 0.25), ("slot", slot, None)]
    return [
        ("specimen", scene_sphere_specimen(), None),
        ("lattice", scene_lattice_box(100), 0.25),
        ("slot", scene_slot_block(), None),
    ]


def grid_for(scene, cell, rho):
    r = scene.radii
    if cell is None:
        return wl.LampGrid.enclosing(scene.centers, r, cells_per_diameter=4, margin=2.0 * float(r.mean()) + rho)
    lo = scene.centers.min(axis=0) - r.max() - cell - rho
    hi = scene.centers.max(axis=0) + r.max() + cell + rho
    return wl.LampGrid(lo, hi, cell)


def bench_scene(name, scene, cell, rho_d, device, repeats, queue=None, cross_list=None, sparse_block=None):
    rho = rho_d * 2.0 * float(scene.radii.mean())
    grid = grid_for(scene, cell, rho)
    n = scene.n
    pos = wp.array((scene.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    jitter = np.random.default_rng(5).normal(scale=0.01 * float(scene.radii.mean()), size=(n, 3))
    moved = wp.array((scene.centers + jitter - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
    out = {"scene": scene.name, "particles": n, "rho": rho, "rho_over_d": rho_d, "cell": float(grid.cell[0, 0])}

    lamp = wl.ShiningLamp(grid, device=device)
    lamp.update(pos, rad, in_frame=True)
    surf = WettedSurface(grid, probe_radius=rho, device=device)
    if queue is not None and hasattr(surf, "_exact_queue"):
        # The exact tests queued (1, the capacity CUDA gets) or tested where the band's words are (0: as before).
        from warp_lamp.wetted import exact_queue_capacity

        surf._exact_queue(exact_queue_capacity(surf.shape, None) if queue else 0)
        out["queue"] = queue
    if cross_list is not None and hasattr(surf, "_cross_list"):
        # The crossings listed for a thread each (1, the capacity CUDA gets) or loaded where found (0).
        from warp_lamp.wetted import cross_list_capacity

        surf._cross_list(cross_list_capacity(surf._faces, None) if cross_list else 0)
        out["cross_list"] = cross_list
    if sparse_block is not None:
        import warp_lamp.wetted as wetted_module

        if hasattr(wetted_module, "SPARSE_BLOCK_DIM"):
            wetted_module.SPARSE_BLOCK_DIM = sparse_block  # read at each launch
            out["sparse_block"] = sparse_block
    surf.update(pos, rad)
    d = surf.diagnostics()
    out["fluid_hash"] = hashlib.sha1(surf.fluid.numpy().tobytes() + surf.counts_numpy().tobytes()).hexdigest()
    out.update(
        voxels=list(surf.shape),
        wetted_bytes=surf.nbytes,
        lamp_bytes=grid.nbytes,
        rounds=d.rounds,
        crossings=int(sum(c.sum() for c in d.crossings.values())) * 2,
        loaded_all=int(d.surface.sum()),
        loaded_first=int(lamp.diagnostics().surface.sum()),
        force_sum=(d.counts.sum(axis=0)).tolist(),
        # Issue 19's counters (absent from older checkouts, which this script also times).
        uncertain=getattr(d, "uncertain", None),
        rescued=getattr(d, "rescued", None),
        thin=getattr(d, "thin", None),
    )
    if device.is_cuda:
        first = capture(device, lambda: lamp.update(pos, rad, in_frame=True))
        first_moving = capture(
            device, lambda: (lamp.update(moved, rad, in_frame=True), lamp.update(pos, rad, in_frame=True))
        )
        out["first_replay_s"] = time_median_events(lambda: wp.capture_launch(first), device, repeats=repeats)
        out["first_moving_s"] = time_median_events(lambda: wp.capture_launch(first_moving), device, repeats=repeats) / 2
        graphs = {s: capture(device, lambda s=s: surf._update(pos, rad, None, stop=s)) for s in surf.STAGES}
        moving = capture(device, lambda: (surf.update(moved, rad), surf.update(pos, rad)))
        prev = 0.0
        for s in surf.STAGES:
            t = time_median_events(lambda g=graphs[s]: wp.capture_launch(g), device, repeats=repeats)
            out[f"all_{s}_s"] = t - prev
            prev = t
        out["all_replay_s"] = prev
        out["all_moving_s"] = time_median_events(lambda: wp.capture_launch(moving), device, repeats=repeats) / 2
    else:
        out["first_eager_s"] = time_median_events(
            lambda: lamp.update(pos, rad, in_frame=True), device, repeats=repeats, warmup=1
        )
        prev = 0.0
        for s in surf.STAGES:
            t = time_median_events(lambda s=s: surf._update(pos, rad, None, stop=s), device, repeats=repeats, warmup=1)
            out[f"all_{s}_s"] = t - prev
            prev = t
        out["all_eager_s"] = prev
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--device", default=None)
    ap.add_argument("--quick", action="store_true", help="small scenes (a CPU smoke run)")
    ap.add_argument("--repeats", type=int, default=None, help="timed repeats (default 50 on CUDA, 5 on the CPU)")
    ap.add_argument("--rho-diameters", type=float, nargs="*", default=[0.5], help="rho in mean diameters")
    ap.add_argument("--only", nargs="*", default=None, help="scenes to run: specimen, lattice, slot (default all)")
    ap.add_argument("--queue", type=int, nargs="*", default=[None], help="exact tests queued: 1, or not: 0 (A/B)")
    ap.add_argument("--cross-list", type=int, default=None, help="crossings listed: 1, or not: 0 (A/B)")
    ap.add_argument("--sparse-block", type=int, default=None, help="threads per block of the sparse launches (A/B)")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    device = wp.get_device(args.device)
    rows = []
    for name, scene, cell in scenes(args.quick):
        if args.only and name not in args.only:
            continue
        for rho_d in args.rho_diameters:
            for queue in args.queue:
                repeats = args.repeats or (50 if device.is_cuda else 5)
                row = bench_scene(name, scene, cell, rho_d, device, repeats, queue, args.cross_list, args.sparse_block)
                rows.append(row)
                keys = [k for k in row if k.endswith("_s")]
                times = ", ".join(f"{k[:-2]} {row[k] * 1e3:.3f} ms" for k in keys)
                print(
                    f"{name} (rho = {rho_d:g} d, queue {queue}, {row['voxels']} voxels, {row['rounds']} rounds, "
                    f"{row['uncertain']} tested, {row['fluid_hash'][:8]}): {times}",
                    flush=True,
                )
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
    except OSError:
        commit = None
    result = {"device": str(device), "name": getattr(device, "name", ""), "host": platform.node(), "commit": commit}
    result["rows"] = rows
    if args.out:
        with open(args.out, "w") as f:
            json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
