"""The distributed lamp's scale runs with the reach (each rank reduces only the cells ranks share), one process per
GPU, all GPUs the machine has in one launch:

    torchrun --standalone --nproc_per_node=G bench/gpu/parts/dist37_run.py --out $OUT/dist37.json
    mpiexec -n 2 python bench/gpu/parts/dist37_run.py --device cpu --n 12 --out /tmp/d.json   # CPU, tiny

Every rank first computes ``ShiningLamp`` on the whole body on its own GPU (the bitwise reference, and on rank 0
the one-GPU time, in the same run on the same kind of GPU). Then, each on its own sub-communicator of the first k
ranks (NCCL through CuPy on CUDA, MPI or Gloo on the CPU), the others waiting:

- strong scaling: the n^3 lattice box (27M at n = 300) in x-slabs on k = 1, 2, 4, ... ranks (up to G);
- weak scaling: n^3 spheres per rank, k slabs of the box side by side (108M on 4 GPUs at n = 300);
- the area criterion (a smaller box) and porosity (voxel and exact) across all G ranks, timed against one GPU.

Each run: graph replay and eager times of the update (the slowest rank), its steps, the bytes reduced per rank, the
cells in each rank's reach, the rank's memory, and its counts (after an eager update and after a cold replay)
compared bitwise with the reference rows, plus the reach's escape count (0). Rank 0 writes the JSON after every
run (a time limit that cuts the run short keeps what was done) and prints the table last, with markdown rows for
the README.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(Path(__file__).resolve().parent)]

import numpy as np  # noqa: E402

CELL = 0.25  # the benchmark's cell (warp-lamp bench), lattice spacing 1


class World:
    """The launcher's processes: torch.distributed (Gloo on the CPU) under torchrun, else mpi4py under mpiexec."""

    def __init__(self, device_kind: str):
        if "LOCAL_RANK" in os.environ or "TORCHELASTIC_RUN_ID" in os.environ:
            import torch.distributed as dist

            if device_kind == "cuda":
                import torch

                torch.cuda.set_device(int(os.environ.get("LOCAL_RANK", "0")))
            dist.init_process_group("gloo")
            self.kind, self.dist = "torch", dist
            self.rank, self.size = dist.get_rank(), dist.get_world_size()
            self.local = int(os.environ.get("LOCAL_RANK", "0"))
        else:
            from mpi4py import MPI

            self.kind, self.MPI, self.comm = "mpi", MPI, MPI.COMM_WORLD
            self.rank, self.size = self.comm.Get_rank(), self.comm.Get_size()
            self.local = self.rank

    def barrier(self):
        if self.kind == "torch":
            self.dist.barrier()
        else:
            self.comm.Barrier()

    def bcast(self, obj):
        if self.kind == "torch":
            box = [obj]
            self.dist.broadcast_object_list(box, src=0)
            return box[0]
        return self.comm.bcast(obj, root=0)

    def gather(self, obj) -> list:
        if self.kind == "torch":
            out = [None] * self.size
            self.dist.all_gather_object(out, obj)
            return out
        return self.comm.allgather(obj)

    def close(self):
        if self.kind == "torch":
            self.dist.destroy_process_group()


def sub_collective(world: World, device, k: int):
    """A collective over ranks 0 .. k-1 (None on the others; every rank must call it)."""
    if device.is_cuda:
        try:
            from cupy.cuda import nccl

            ok = bool(nccl.available)
        except Exception:
            ok = False
        if ok:
            import cupy

            from warp_lamp.distributed import NCCLCollective

            uid = world.bcast(nccl.get_unique_id() if world.rank == 0 else None)
            if world.rank >= k:
                return None
            cupy.cuda.Device(device.ordinal).use()
            comm = nccl.NcclCommunicator(k, uid, world.rank)
            return NCCLCollective(comm, device)
        from warp_lamp.distributed import TorchCollective

        group = world.dist.new_group(list(range(k)), backend="nccl")
        return TorchCollective(group, device) if world.rank < k else None
    if world.kind == "mpi":
        from warp_lamp.distributed import MPICollective

        sub = world.comm.Split(0 if world.rank < k else 1, world.rank)
        return MPICollective(sub, device) if world.rank < k else None
    from warp_lamp.distributed import TorchCollective

    group = world.dist.new_group(list(range(k)), backend="gloo")
    return TorchCollective(group, device) if world.rank < k else None


def lattice(n: int, copies: int):
    """The n^3 lattice box (warp-lamp bench's scene), ``copies`` of it side by side along x (spacing 1, so copy c
    is the box shifted by c n), as one body; its grid as ``warp_lamp.bench.lattice_grid`` makes it."""
    from warp_lamp import LampGrid
    from warp_lamp.scenes import scene_lattice_box

    base = scene_lattice_box((n, n, n))
    c, r = base.centers, base.radii
    if copies > 1:
        shift = np.zeros((copies, 1, 3))
        shift[:, 0, 0] = n * np.arange(copies)
        c = (c[None, :, :] + shift).reshape(-1, 3)
        r = np.tile(r, copies)
    lo = c.min(axis=0) - r.max() - CELL
    hi = c.max(axis=0) + r.max() + CELL
    return c, r, LampGrid(lo, hi, CELL)


def slab_rows(n_per_copy: int, copies: int, k: int, rank: int, centers) -> np.ndarray:
    """Rank ``rank``'s rows of k x-slabs: whole copies for weak scaling (k = copies), quantiles of x otherwise."""
    if copies == k and copies > 1:
        return np.arange(rank * n_per_copy, (rank + 1) * n_per_copy, dtype=np.int64)
    import distributed_cases

    return distributed_cases.split_rows("spatial", centers, rank, k).astype(np.int64)


def _used(device) -> int:
    """Bytes in use in Warp's memory pool on a GPU (0 on the CPU)."""
    import warp as wp

    return int(wp.get_mempool_used_mem_current(device)) if device.is_cuda and wp.is_mempool_enabled(device) else 0


def _time(fn, device, repeats):
    from warp_lamp.timing import time_median_events

    return time_median_events(fn, device, repeats=repeats)


def _graph(fn, device):
    import warp as wp

    with wp.ScopedCapture(device=device) as cap:
        fn()
    return cap.graph


def reference(centers, radii, grid, device, repeats, *, criterion=1, timed=False) -> dict:
    """ShiningLamp on the whole body on this GPU: its counts (host), and with ``timed`` its update times."""
    import warp as wp

    from warp_lamp import ShiningLamp

    lamp = ShiningLamp(grid, criterion=criterion, device=device)
    pos = wp.array((centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(radii.astype(np.float32), dtype=wp.float32, device=device)

    def update():
        lamp.update(pos, rad, in_frame=True)

    update()
    out = {"counts": lamp.counts_numpy()}
    if timed:
        out["eager_s"] = _time(update, device, repeats)
        if device.is_cuda:
            g = _graph(update, device)
            out["replay_s"] = _time(lambda: wp.capture_launch(g), device, repeats)
            del g
    wp.synchronize_device(device)
    return out


def distributed_run(coll, centers, radii, grid, rows, want, repeats, *, criterion=1) -> dict:
    """One rank's distributed update of its rows: times, steps, bytes, reach, memory, bitwise against ``want``."""
    import warp as wp

    from warp_lamp.distributed import DistributedLamp

    device = coll.device
    used0 = _used(device)
    frame = (centers[rows] - grid.origin).astype(np.float32)
    pos = wp.array(frame, dtype=wp.vec3, device=device)
    rad = wp.array(radii[rows].astype(np.float32), dtype=wp.float32, device=device)
    del frame
    lamp = DistributedLamp(grid, coll, criterion=criterion, device=device)
    t0 = time.perf_counter()
    lamp.set_ids(rows)
    set_ids_s = time.perf_counter() - t0

    def update():
        lamp.update(pos, rad, in_frame=True)

    t0 = time.perf_counter()
    update()  # agrees the reach
    wp.synchronize_device(device)
    first_s = time.perf_counter() - t0
    est = lamp.estimator
    out = {
        "n_rank": len(rows),
        "cells": grid.n_cells,
        "window_cells": getattr(est, "window_cells", grid.n_cells),
        "shared_cells": getattr(est, "shared_cells", grid.n_cells),
        "reduction_bytes": lamp.reduction_bytes,
        "set_ids_s": set_ids_s,
        "first_update_s": first_s,
        "eager_s": _time(update, device, repeats),
    }
    counts = lamp.counts_numpy()
    replayed = None
    if device.is_cuda and coll.capturable:
        g = _graph(update, device)
        out["replay_s"] = _time(lambda: wp.capture_launch(g), device, repeats)
        steps = {
            "seed_s": lamp.estimator.launch_seed,
            "depth_s": lamp.estimator.launch_depth,
            "to_global_s": lamp.estimator.launch_to_global,
            "reduce_s": lamp.estimator.launch_reduce,
            "scatter_s": lamp.estimator.launch_scatter,
        }
        for name, fn in steps.items():
            try:  # a step with nothing to do (one rank: nothing shared, nothing reduced) records an empty graph
                gs = _graph(fn, device)
                out[name] = _time(lambda gs=gs: wp.capture_launch(gs), device, max(5, repeats // 2))
            except Exception as e:
                out[name] = None
                out[f"{name}_error"] = f"{type(e).__name__}: {str(e)[:200]}"
        lamp.forget()  # a cold replay, checked as the eager update is
        wp.capture_launch(g)
        replayed = lamp.counts_numpy()
        update()
    # The rank's particles, its lamp and their buffers (the reference's arrays are freed by now).
    out["memory_bytes"] = _used(device) - used0 if device.is_cuda else None
    if device.is_cuda:
        out["mempool_high_bytes"] = int(wp.get_mempool_used_mem_high(device))
    out["lamp_bytes"] = int(lamp.nbytes)
    mine = want[rows]
    out["bitwise"] = bool(np.array_equal(counts, mine))
    if replayed is not None:
        out["bitwise_replay"] = bool(np.array_equal(replayed, mine))
        out["bitwise"] = out["bitwise"] and out["bitwise_replay"]
    out["escapes"] = lamp.reach_escapes()
    wp.synchronize_device(device)
    return out


def porosity_run(coll, centers, radii, rows, device, repeats) -> list[dict]:
    """porosity_distributed (voxel: bitwise against porosity; exact: fixed point, against one rank's) timed on the
    rank's rows, and porosity on the whole body on this GPU."""
    import warp as wp

    from warp_lamp import porosity
    from warp_lamp.distributed import porosity_distributed

    lower = centers.min(axis=0) - 0.5
    upper = centers.max(axis=0) + 0.5
    shape = tuple(int(x) for x in np.round(upper - lower))
    out = []
    for method in ("voxel", "exact"):
        opts = {"method": method, "subdivisions": 4, "device": device}

        def timed(fn):
            fn()
            wp.synchronize_device(device)
            times = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                got = fn()
                wp.synchronize_device(device)
                times.append(time.perf_counter() - t0)
            return got, float(np.median(times))

        mine_c, mine_r = centers[rows], radii[rows]
        got, dist_s = timed(
            lambda o=opts, c=mine_c, r=mine_r: porosity_distributed(coll, c, r, lower, upper, shape, **o)
        )
        if method == "voxel":
            want, one_s = timed(lambda o=opts: porosity(centers, radii, lower, upper, shape, **o))
        else:
            want, one_s = timed(lambda o=opts: porosity_distributed(None, centers, radii, lower, upper, shape, **o))
        out.append(
            {
                "method": method,
                "shape": list(shape),
                "n": len(radii),
                "n_rank": len(rows),
                "seconds": dist_s,
                "one_gpu_s": one_s,
                "bitwise": bool(np.array_equal(got, want)),
            }
        )
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True)
    parser.add_argument("--device", choices=("cuda", "cpu"), default="cuda")
    parser.add_argument("--n", type=int, default=300, help="spheres per axis of the strong box (27M at 300)")
    parser.add_argument("--area-n", type=int, default=200, help="spheres per axis of the area criterion's box")
    parser.add_argument("--porosity-n", type=int, default=100, help="spheres per axis of the porosity box")
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--skip", default="", help="comma list of: strong, weak, area, porosity")
    args = parser.parse_args()
    skip = set(filter(None, args.skip.split(",")))

    world = World(args.device)
    import warp as wp

    wp.config.quiet = True
    wp.init()
    device = wp.get_device(f"cuda:{world.local}" if args.device == "cuda" else "cpu")
    from warp_lamp.timing import run_header

    G = world.size
    ks = [k for k in (1, 2, 4, 8) if k <= G]
    report = {
        **run_header([device]),
        "gpus": G,
        "device": device.name,
        "nccl_nvls_enable": os.environ.get("NCCL_NVLS_ENABLE"),
        "launcher": world.kind,
        "n_per_axis": args.n,
        "runs": [],
    }
    t_start = time.perf_counter()

    def log(msg):
        if world.rank == 0:
            print(f"[{time.perf_counter() - t_start:7.1f} s] {msg}", flush=True)

    def save():
        if world.rank == 0:
            Path(args.out).write_text(json.dumps(report, indent=1))

    def record(kind, k, centers, radii, grid, rows_of, want, **extra):
        """Ranks 0 .. k-1 run; every rank gathers the rows of the run."""
        coll = sub_collective(world, device, k)
        row = None
        if coll is not None:
            rows = rows_of(coll.rank)
            row = distributed_run(coll, centers, radii, grid, rows, want, args.repeats, **extra)
            row["rank"] = coll.rank
        parts = [p for p in world.gather(row) if p is not None]
        slow = max(parts, key=lambda p: p.get("replay_s") or p["eager_s"])
        entry = {
            "kind": kind,
            "gpus": k,
            "n": len(radii),
            "bitwise": all(p["bitwise"] for p in parts),
            "escapes": sum(p["escapes"] for p in parts),
            "replay_s": slow.get("replay_s"),
            "eager_s": max(p["eager_s"] for p in parts),
            "per_rank": parts,
            **{k2: v for k2, v in extra.items() if k2 != "criterion"},
        }
        for step in ("seed_s", "depth_s", "to_global_s", "reduce_s", "scatter_s"):
            vals = [p[step] for p in parts if p.get(step) is not None]
            entry[step] = max(vals) if vals else None
        entry["reduction_bytes"] = max(p["reduction_bytes"] for p in parts)
        entry["memory_bytes"] = max((p["memory_bytes"] or 0) for p in parts) or None
        world.barrier()
        return entry

    # Strong scaling: the reference on every GPU (rank 0's timed: the one-GPU baseline), then k = 1, 2, 4 ...
    if "strong" not in skip or "weak" not in skip:
        log(f"lattice {args.n}^3")
        centers, radii, grid = lattice(args.n, 1)
        ref = reference(centers, radii, grid, device, args.repeats, timed=world.rank == 0)
        base = world.bcast({k: v for k, v in ref.items() if k != "counts"} if world.rank == 0 else None)
        report["one_gpu"] = {"case": "ShiningLamp", "n": len(radii), "cells": grid.n_cells, **base}
        save()
        log(f"one GPU: replay {base.get('replay_s')}, eager {base['eager_s']}")
        if "strong" not in skip:
            for k in ks:
                e = record(
                    "strong", k, centers, radii, grid, lambda r, k=k: slab_rows(0, 1, k, r, centers), ref["counts"]
                )
                t1 = base.get("replay_s") or base["eager_s"]
                e["ratio_to_one_gpu"] = (e["replay_s"] or e["eager_s"]) / t1
                if k > 1:
                    # The floor: ShiningLamp on rank 0's share alone, on the same grid and GPU (no communication,
                    # no reach). What one rank cannot beat; the rest of the ratio is what distributing costs.
                    share = None
                    if world.rank == 0:
                        rows = slab_rows(0, 1, k, 0, centers)
                        share = reference(centers[rows], radii[rows], grid, device, args.repeats, timed=True)
                        share = {"n": len(rows), **{k2: v for k2, v in share.items() if k2 != "counts"}}
                    e["share_on_one_gpu"] = world.bcast(share)
                    e["share_ratio"] = (e["share_on_one_gpu"].get("replay_s") or e["share_on_one_gpu"]["eager_s"]) / t1
                    log(f"strong k={k}: ShiningLamp on rank 0's share alone: ratio {e['share_ratio']:.3f}")
                report["runs"].append(e)
                save()
                log(f"strong k={k}: ratio {e['ratio_to_one_gpu']:.3f} bitwise {e['bitwise']}")
        n_copy = len(radii)
        del centers, radii, grid, ref
        # Weak scaling: k copies of the box side by side, one per rank.
        if "weak" not in skip:
            for k in [k for k in ks if k >= 2]:
                centers, radii, grid = lattice(args.n, k)
                ref = reference(centers, radii, grid, device, args.repeats)
                e = record(
                    "weak", k, centers, radii, grid, lambda r, k=k: slab_rows(n_copy, k, k, r, None), ref["counts"]
                )
                t1 = base.get("replay_s") or base["eager_s"]
                e["efficiency"] = t1 / (e["replay_s"] or e["eager_s"])
                report["runs"].append(e)
                save()
                log(f"weak k={k}: {len(radii):,} spheres, efficiency {e['efficiency']:.3f} bitwise {e['bitwise']}")
                del centers, radii, grid, ref
    # The area criterion on all G ranks (x-slabs), against ShiningLamp's area criterion on one GPU.
    if "area" not in skip:
        centers, radii, grid = lattice(args.area_n, 1)
        ref = reference(centers, radii, grid, device, args.repeats, criterion="area", timed=world.rank == 0)
        base = world.bcast({k: v for k, v in ref.items() if k != "counts"} if world.rank == 0 else None)
        e = record(
            "area", G, centers, radii, grid, lambda r: slab_rows(0, 1, G, r, centers), ref["counts"], criterion="area"
        )
        e["one_gpu"] = base
        t1 = base.get("replay_s") or base["eager_s"]
        e["ratio_to_one_gpu"] = (e["replay_s"] or e["eager_s"]) / t1
        report["runs"].append(e)
        save()
        log(f"area on {G}: ratio {e['ratio_to_one_gpu']:.3f} bitwise {e['bitwise']}")
        del centers, radii, grid, ref
    if "porosity" not in skip:
        centers, radii, _ = lattice(args.porosity_n, 1)
        coll = sub_collective(world, device, G)
        import distributed_cases

        rows = distributed_cases.split_rows("spatial", centers, coll.rank, G)
        res = porosity_run(coll, centers, radii, rows, device, max(3, args.repeats // 4))
        parts = world.gather(res)
        for m, row in enumerate(parts[0]):
            row["seconds"] = max(p[m]["seconds"] for p in parts)
            row["bitwise"] = all(p[m]["bitwise"] for p in parts)
            row["gpus"] = G
            row["kind"] = "porosity"
            report["runs"].append(row)
        save()
        log("porosity done")
    report["seconds"] = time.perf_counter() - t_start
    save()
    if world.rank == 0:
        print_table(report)
    world.barrier()
    world.close()
    return 0


def print_table(report: dict) -> None:
    def ms(x):
        return "-" if x is None else f"{1e3 * x:.3f}"

    one = report.get("one_gpu", {})
    lines = [
        f"device: {report['device']} x {report['gpus']}, NCCL_NVLS_ENABLE={report['nccl_nvls_enable']}",
        f"one GPU ShiningLamp {one.get('n', 0):,}: replay {ms(one.get('replay_s'))} ms, eager {ms(one.get('eager_s'))}",
        "| run | GPUs | N | replay ms | eager ms | ratio / efficiency | bitwise | escapes | reduced MB/rank | seed "
        "| depth | to-global | reduce | scatter | memory GB/rank |",
        "| --- | ---: | ---: | ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for e in report["runs"]:
        if e["kind"] == "porosity":
            lines.append(
                f"| porosity {e['method']} {'x'.join(map(str, e['shape']))} | {e['gpus']} | {e['n']:,} | | "
                f"{ms(e['seconds'])} | {e['seconds'] / e['one_gpu_s']:.3f} (1 GPU {ms(e['one_gpu_s'])}) | "
                f"{e['bitwise']} | | | | | | | | |"
            )
            continue
        ratio = e.get("ratio_to_one_gpu", e.get("efficiency"))
        mem = e.get("memory_bytes")
        lines.append(
            f"| {e['kind']} | {e['gpus']} | {e['n']:,} | {ms(e['replay_s'])} | {ms(e['eager_s'])} | "
            f"{ratio:.3f} | {e['bitwise']} | {e['escapes']} | {e['reduction_bytes'] / 1e6:.1f} | {ms(e['seed_s'])} | "
            f"{ms(e['depth_s'])} | {ms(e['to_global_s'])} | {ms(e['reduce_s'])} | {ms(e['scatter_s'])} | "
            f"{'-' if not mem else f'{mem / 2**30:.2f}'} |"
        )
    for e in report["runs"]:
        if e.get("share_on_one_gpu"):
            lines.append(
                f"floor, {e['gpus']} GPUs: ShiningLamp on rank 0's share alone ({e['share_on_one_gpu']['n']:,}) "
                f"{e['share_ratio']:.3f} of one GPU; distributed {e['ratio_to_one_gpu']:.3f}"
            )
    # The README's rows ("Past one GPU", scaling with the reach).
    lines += ["", "README rows:"]

    def n_str(n):
        return f"{n / 1e6:.0f}M" if n >= 1e6 else f"{n:,}"

    if one:
        t1 = ms(one.get("replay_s") or one["eager_s"])
        lines.append(f"| strong, `ShiningLamp` | 1 | {n_str(one['n'])} | {t1} | 1 | - | - | |")
    for e in report["runs"]:
        if e["kind"] == "porosity":
            lines.append(
                f"| porosity {e['method']} | {e['gpus']} | {n_str(e['n'])} | {ms(e['seconds'])} (1 GPU "
                f"{ms(e['one_gpu_s'])}) | {e['seconds'] / e['one_gpu_s']:.3f} | {'yes' if e['bitwise'] else 'NO'} | | |"
            )
            continue
        name = {"strong": "strong, x-slabs", "weak": "weak, 27M per GPU", "area": "area criterion, x-slabs"}[e["kind"]]
        if e["kind"] == "weak":
            name = f"weak, {n_str(e['n'] // e['gpus'])} per GPU"
        ratio = e.get("ratio_to_one_gpu", e.get("efficiency"))
        mem = e.get("memory_bytes")
        lines.append(
            f"| {name} | {e['gpus']} | {n_str(e['n'])} | {ms(e['replay_s'] or e['eager_s'])} | **{ratio:.3f}** | "
            f"{'yes' if e['bitwise'] and not e['escapes'] else 'NO'} | {e['reduction_bytes'] / 1e6:.1f} | "
            f"{'-' if not mem else f'{mem / 2**30:.2f}'} |"
        )
    print("\n".join(lines), flush=True)


if __name__ == "__main__":
    sys.exit(main())
