"""One rank of the distributed lamp's GPU run (issue 23), started by torchrun, one process per GPU:

    torchrun --standalone --nproc_per_node=2 bench/gpu/parts/distributed_run.py run --out $OUT/ranks2.json
    python3 bench/gpu/parts/distributed_run.py table $OUT/ranks1.json $OUT/ranks2.json \
        --json $OUT/h100-x2-distributed.json

``run`` (``--part checks``, ``scale`` or ``all``): on 2 or more ranks, the correctness cases of
``tests/distributed_cases.py`` on CUDA (NCCL through CuPy, and through torch.distributed); on any number of ranks,
the lattice boxes (8M and 27M: strong scaling; 13.5M on one rank: weak scaling's base) split in slabs along x: the
update's eager and graph-replay times, its steps (the rank's depth pass, keys to global ids, the all-reduce alone,
the scatter), the all-reduce's bytes, and the rank's counts (eager, and after a cold graph replay) compared bitwise
with ``ShiningLamp`` holding every particle on the same GPU. A random split of the 8M box is checked bitwise too.
On one rank, ``ShiningLamp``'s own times are the baseline. ``--device cpu`` (Gloo) runs the same on the CPU at small
sizes, to test this script without GPUs.

``table``: the per-rank-count files combined into one result file and a table, with the ratio to one GPU.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import numpy as np  # noqa: E402

#: Lattice boxes (spheres per axis): strong scaling at 8M and 27M; weak scaling's one-rank base at 13.5M.
STRONG = ((200, 200, 200), (300, 300, 300))
WEAK_BASE = (300, 300, 150)
CELL = 0.25  # the benchmark's cell (warp-lamp bench)


def _init(device_kind: str):
    import torch
    import torch.distributed as dist
    import warp as wp

    local = int(os.environ.get("LOCAL_RANK", "0"))
    if device_kind == "cuda":
        torch.cuda.set_device(local)
        dist.init_process_group("cpu:gloo,cuda:nccl")
        device = f"cuda:{local}"
    else:
        dist.init_process_group("gloo")
        device = "cpu"
    wp.config.quiet = True
    wp.init()
    return dist, wp.get_device(device)


def _cupy_collective(dist, device):
    """NCCL through CuPy, its unique id sent over torch's Gloo group; None where CuPy's NCCL is missing."""
    try:
        import cupy
        from cupy.cuda import nccl

        if not nccl.available:
            return None, "cupy.cuda.nccl not available"
    except Exception as e:
        return None, f"{type(e).__name__}: {e}"
    from warp_lamp.distributed import NCCLCollective

    cupy.cuda.Device(device.ordinal).use()
    uid = [nccl.get_unique_id() if dist.get_rank() == 0 else None]
    dist.broadcast_object_list(uid, src=0, device="cpu")
    comm = nccl.NcclCommunicator(dist.get_world_size(), uid[0], dist.get_rank())
    return NCCLCollective(comm, device), f"nccl {nccl.get_version()}"


def _events_time(fn, device, repeats):
    from warp_lamp.timing import time_median_events

    return time_median_events(fn, device, repeats=repeats)


def _graph(fn, device):
    import warp as wp

    with wp.ScopedCapture(device=device) as cap:
        fn()
    return cap.graph


def _lattice(n3):
    from warp_lamp.bench import lattice_grid
    from warp_lamp.scenes import scene_lattice_box

    scene = scene_lattice_box(n3)
    return scene, lattice_grid(scene, CELL)


def _timings(coll, scene, grid, rows, repeats, label) -> dict:
    """The distributed update of the rank's rows: eager, replay, its steps, and bitwise against ShiningLamp."""
    import warp as wp

    from warp_lamp import ShiningLamp
    from warp_lamp.distributed import DistributedLamp

    device = coll.device
    frame = (scene.centers - grid.origin).astype(np.float32)
    pos = wp.array(frame[rows], dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii[rows].astype(np.float32), dtype=wp.float32, device=device)
    lamp = DistributedLamp(grid, coll, device=device)
    t0 = time.perf_counter()
    lamp.set_ids(rows)
    set_ids_s = time.perf_counter() - t0

    def update():
        lamp.update(pos, rad, in_frame=True)

    update()
    wp.synchronize_device(device)
    out = {
        "case": label,
        "n_rank": len(rows),
        "cells": grid.n_cells,
        "reduction_bytes": lamp.reduction_bytes,
        "set_ids_s": set_ids_s,
        "eager_s": _events_time(update, device, repeats),
    }
    if device.is_cuda and coll.capturable:
        g = _graph(update, device)
        out["replay_s"] = _events_time(lambda: wp.capture_launch(g), device, repeats)
        e0, e1 = wp.Event(device, enable_timing=True), wp.Event(device, enable_timing=True)
        wp.record_event(e0)
        for _ in range(repeats):
            wp.capture_launch(g)
        wp.record_event(e1)
        wp.synchronize_event(e1)
        out["replay_mean_s"] = wp.get_event_elapsed_time(e0, e1) / 1e3 / repeats
        steps = {
            "local_s": lambda: (lamp.launch_seed(), lamp.launch_depth()),
            "to_global_s": lamp.launch_to_global,
            "reduce_s": lamp.launch_reduce,
            "scatter_s": lamp.launch_scatter,
        }
        for name, fn in steps.items():
            gs = _graph(fn, device)
            out[name] = _events_time(lambda gs=gs: wp.capture_launch(gs), device, repeats)
        # A cold replay (the rank's keys dropped), checked below as the eager update is.
        lamp.forget()
        wp.capture_launch(g)
        replayed = lamp.counts_numpy()
    update()
    counts = lamp.counts_numpy()
    ref = ShiningLamp(grid, device=device)
    ref.update(
        wp.array(frame, dtype=wp.vec3, device=device),
        wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device),
        in_frame=True,
    )
    want = ref.counts_numpy()[rows]
    out["bitwise"] = bool(np.array_equal(counts, want))
    if "replay_s" in out:
        out["bitwise_replay"] = bool(np.array_equal(replayed, want))
        out["bitwise"] = out["bitwise"] and out["bitwise_replay"]
    out["lit_counts"] = int(np.abs(counts).sum())
    return out


def _baseline(scene, grid, device, repeats) -> dict:
    """ShiningLamp on one GPU, as warp-lamp bench times it (positions in the frame)."""
    import warp as wp

    from warp_lamp import ShiningLamp

    lamp = ShiningLamp(grid, device=device)
    pos = wp.array((scene.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)

    def update():
        lamp.update(pos, rad, in_frame=True)

    update()
    out = {
        "case": "ShiningLamp",
        "n_rank": scene.n,
        "cells": grid.n_cells,
        "eager_s": _events_time(update, device, repeats),
    }
    if device.is_cuda:
        g = _graph(update, device)
        out["replay_s"] = _events_time(lambda: wp.capture_launch(g), device, repeats)
    return out


def _scene_rows(scene, split, rank, size):
    import distributed_cases

    return distributed_cases.split_rows(split, scene.centers, rank, size).astype(np.int64)


def cmd_run(args) -> int:
    import distributed_cases
    import warp as wp

    from warp_lamp.distributed import TorchCollective
    from warp_lamp.timing import run_header

    dist, device = _init(args.device)
    rank, size = dist.get_rank(), dist.get_world_size()
    report = {**run_header([device]), "ranks": size, "device": device.name, "rank_results": {}}
    os.environ.setdefault("NCCL_NVLS_ENABLE", "0")
    report["nccl_nvls_enable"] = os.environ.get("NCCL_NVLS_ENABLE")
    collectives = {}
    if device.is_cuda:
        cupy_coll, why = _cupy_collective(dist, device)
        report["cupy_nccl"] = why
        if cupy_coll is not None:
            collectives["cupy-nccl"] = cupy_coll
    torch_coll = TorchCollective(None, device, capturable=False)
    collectives["torch"] = torch_coll
    main_name = "cupy-nccl" if "cupy-nccl" in collectives else "torch"
    coll = collectives[main_name]
    mine = {"checks": {}, "scale": []}
    if size >= 2 and args.part in ("all", "checks"):
        for name, c in collectives.items():
            t0 = time.perf_counter()
            results = distributed_cases.all_cases(c, quick=args.quick)
            mine["checks"][name] = {
                "cases": len(results),
                "failed": [r for r in results if not r["ok"]],
                "seconds": time.perf_counter() - t0,
            }
    sizes = [tuple(int(x) for x in s.split("x")) for s in args.sizes.split(",")] if args.sizes else list(STRONG)
    if size == 1 and not args.sizes:
        sizes.append(WEAK_BASE)
    if args.part == "checks":
        sizes = []
    for n3 in sizes:
        scene, grid = _lattice(n3)
        label = f"lattice {n3[0]}x{n3[1]}x{n3[2]}"
        if size == 1:
            row = _baseline(scene, grid, device, args.repeats)
            row.update(scene=label, n=scene.n, ranks=1)
            mine["scale"].append(row)
        rows = _scene_rows(scene, "spatial", rank, size)
        row = _timings(coll, scene, grid, rows, args.repeats, f"DistributedLamp ({main_name})")
        row.update(scene=label, n=scene.n, ranks=size, split="spatial")
        mine["scale"].append(row)
        if size >= 2 and n3 == sizes[0]:
            rows = _scene_rows(scene, "random", rank, size)
            row = _timings(coll, scene, grid, rows, max(3, args.repeats // 4), f"DistributedLamp ({main_name})")
            row.update(scene=label, n=scene.n, ranks=size, split="random")
            mine["scale"].append(row)
        del scene
        wp.synchronize_device(device)
    everyone = [None] * size
    dist.all_gather_object(everyone, mine)
    if rank == 0:
        report["collective"] = main_name
        report["rank_results"] = {str(r): everyone[r] for r in range(size)}
        Path(args.out).write_text(json.dumps(report, indent=1))
        failed = sum(len(c["failed"]) for part in everyone for c in part["checks"].values())
        print(f"{size} rank(s) on {device.name}: {failed} failed cases; wrote {args.out}")
    dist.barrier()
    dist.destroy_process_group()
    return 0


def cmd_capture(args) -> int:
    """Does torch's NCCL process group record into a CUDA graph begun on Warp's stream? Its own torchrun, last, so
    that a failure there cannot cost the other results."""
    dist, device = _init(args.device)
    got = _try_torch_capture(device, dist.get_world_size()) if device.is_cuda else {"captured": False, "error": "cpu"}
    everyone = [None] * dist.get_world_size()
    dist.all_gather_object(everyone, got)
    if dist.get_rank() == 0:
        Path(args.out).write_text(json.dumps({"ranks": dist.get_world_size(), "per_rank": everyone}, indent=1))
        print("torch capture:", json.dumps(everyone))
    dist.barrier()
    dist.destroy_process_group()
    return 0


def _try_torch_capture(device, size) -> dict:
    """A small distributed update recorded with TorchCollective(capturable=True): whether the graph was made and
    replays bitwise as eager."""
    import torch.distributed as dist
    import warp as wp

    from warp_lamp import LampGrid
    from warp_lamp.distributed import DistributedLamp, TorchCollective

    rng = np.random.default_rng(0)
    c, r = rng.uniform(0, 5, (2000, 3)), rng.uniform(0.2, 0.5, 2000)
    grid = LampGrid.enclosing(c, r)
    rows = np.arange(dist.get_rank(), len(r), size)
    lamp = DistributedLamp(grid, TorchCollective(None, device, capturable=True))
    lamp.set_ids(rows)
    pos = wp.array(c[rows].astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(r[rows].astype(np.float32), dtype=wp.float32, device=device)
    lamp.update(pos, rad)
    eager = lamp.counts_numpy()
    try:
        g = _graph(lambda: lamp.update(pos, rad), device)
        lamp.forget()
        wp.capture_launch(g)
        return {"captured": True, "replay_bitwise": bool(np.array_equal(lamp.counts_numpy(), eager))}
    except Exception as e:
        return {"captured": False, "error": f"{type(e).__name__}: {str(e)[:300]}"}


def cmd_table(args) -> int:
    loaded = [json.loads(Path(p).read_text()) for p in args.files]
    runs = [x for x in loaded if "rank_results" in x]
    captures = [x for x in loaded if "per_rank" in x]
    rows = []
    for run in runs:
        for r, part in run["rank_results"].items():
            for row in part["scale"]:
                rows.append({**row, "rank": int(r)})
    base = {}
    for row in rows:
        if row["case"] == "ShiningLamp":
            base[row["scene"]] = row
    merged = {}
    for row in rows:
        if row["case"] == "ShiningLamp":
            continue
        key = (row["scene"], row["ranks"], row["split"], row["case"])
        merged.setdefault(key, []).append(row)
    table = []
    for (scene, ranks, split, case), parts in sorted(merged.items(), key=lambda kv: (kv[0][0], kv[0][1], kv[0][2])):
        slow = max(parts, key=lambda p: p.get("replay_s") or p["eager_s"])

        def worst(k, parts=parts):
            vals = [p.get(k) for p in parts if p.get(k) is not None]
            return max(vals) if vals else None

        one = base.get(scene, {})
        entry = {
            "scene": scene,
            "n": slow["n"],
            "ranks": ranks,
            "split": split,
            "collective": case,
            "bitwise": all(p["bitwise"] for p in parts),
            "eager_s": worst("eager_s"),
            "replay_s": worst("replay_s"),
            "replay_mean_s": worst("replay_mean_s"),
            "local_s": worst("local_s"),
            "to_global_s": worst("to_global_s"),
            "reduce_s": worst("reduce_s"),
            "scatter_s": worst("scatter_s"),
            "reduction_bytes": slow["reduction_bytes"],
            "one_gpu_replay_s": one.get("replay_s"),
            "one_gpu_eager_s": one.get("eager_s"),
        }
        t = entry["replay_s"] or entry["eager_s"]
        ref = entry["one_gpu_replay_s"] or entry["one_gpu_eager_s"]
        entry["ratio_to_one_gpu"] = (t / ref) if (t and ref) else None
        table.append(entry)
    out = {
        "runs": [{k: v for k, v in run.items() if k != "rank_results"} for run in runs],
        "checks": {
            str(run["ranks"]): {r: part["checks"] for r, part in run["rank_results"].items()}
            for run in runs
            if any(part.get("checks") for part in run["rank_results"].values())
        },
        "torch_capture": captures,
        "one_gpu": list(base.values()),
        "table": table,
        "rows": rows,
    }

    def ms(x):
        return "-" if x is None else f"{1e3 * x:.3f}"

    lines = [
        "| scene | N | GPUs | split | bitwise | update replay ms | eager ms | 1-GPU replay ms | ratio | reduce ms "
        "| reduce MB | depth ms | to-global ms | scatter ms |",
        "| --- | ---: | ---: | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for b in base.values():
        lines.append(
            f"| {b['scene']} | {b['n']:,} | 1 | ShiningLamp | - | {ms(b.get('replay_s'))} | {ms(b['eager_s'])} "
            "| | | | | | | |"
        )
    for e in table:
        ratio = "-" if e["ratio_to_one_gpu"] is None else f"{e['ratio_to_one_gpu']:.3f}"
        lines.append(
            f"| {e['scene']} | {e['n']:,} | {e['ranks']} | {e['split']} | {e['bitwise']} | {ms(e['replay_s'])} | "
            f"{ms(e['eager_s'])} | {ms(e['one_gpu_replay_s'])} | {ratio} | {ms(e['reduce_s'])} | "
            f"{e['reduction_bytes'] / 1e6:.1f} | {ms(e['local_s'])} | {ms(e['to_global_s'])} | {ms(e['scatter_s'])} |"
        )
    print("\n".join(lines))
    for ranks, per_rank in out["checks"].items():
        for r, checks in per_rank.items():
            for name, c in checks.items():
                print(f"check {ranks} ranks, rank {r}, {name}: {c['cases']} cases, {len(c['failed'])} failed")
    weak = [b for b in base.values() if b["n"] * 2 in [e["n"] for e in table if e["ranks"] == 2]]
    for b in weak:
        for e in table:
            if e["ranks"] == 2 and e["n"] == 2 * b["n"] and e["split"] == "spatial":
                t, t1 = e["replay_s"] or e["eager_s"], b.get("replay_s") or b["eager_s"]
                print(f"weak scaling: {b['n']:,} on 1 GPU {ms(t1)} ms, {e['n']:,} on 2 GPUs {ms(t)} ms: {t / t1:.3f}")
                out.setdefault("weak", []).append({"one_gpu": b, "two_gpus": e, "efficiency": t1 / t})
    print("torch capture:", json.dumps(out["torch_capture"]))
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="cmd", required=True)
    run = sub.add_parser("run", help="one rank (under torchrun)")
    run.add_argument("--out", required=True)
    run.add_argument("--device", choices=("cuda", "cpu"), default="cuda")
    run.add_argument("--sizes", help="lattice sizes, e.g. 200x200x200,300x300x300 (default: 8M, 27M; +13.5M on 1)")
    run.add_argument("--repeats", type=int, default=20)
    run.add_argument("--quick", action="store_true", help="fewer correctness cases")
    run.add_argument(
        "--part", choices=("all", "checks", "scale"), default="all", help="the correctness cases, the timings, or both"
    )
    table = sub.add_parser("table", help="combine the runs' files")
    table.add_argument("files", nargs="+")
    table.add_argument("--json")
    cap = sub.add_parser("capture", help="torch.distributed inside a Warp graph capture (under torchrun)")
    cap.add_argument("--out", required=True)
    cap.add_argument("--device", choices=("cuda", "cpu"), default="cuda")
    args = parser.parse_args()
    return {"run": cmd_run, "table": cmd_table, "capture": cmd_capture}[args.cmd](args)


if __name__ == "__main__":
    sys.exit(main())
