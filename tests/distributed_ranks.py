"""One rank of the distributed checks (``distributed_cases.py``): over MPI, ``mpiexec -n P python
tests/distributed_ranks.py --json OUT``; over torch.distributed's Gloo, P processes started with ``--gloo STORE
--rank R --size P`` (a file store). Every rank runs every case on the CPU; rank 0 writes every rank's results to OUT
and the exit status is 0 only when all ranks passed every case."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import warp as wp

wp.config.quiet = True

import distributed_cases  # noqa: E402

from warp_lamp.distributed import MPICollective, TorchCollective  # noqa: E402


class _MPIGlue:
    """Gather and minimum of Python objects over MPI, and the library's name."""

    def __init__(self):
        from mpi4py import MPI

        self.mpi = MPI
        self.comm = MPI.COMM_WORLD

    def collective(self, device):
        return MPICollective(self.comm, device)

    def gather(self, obj):
        return self.comm.gather(obj, root=0)

    def all_min(self, value: int) -> int:
        return self.comm.allreduce(value, op=self.mpi.MIN)

    def library(self) -> str:
        return self.mpi.Get_library_version().splitlines()[0].strip()

    def close(self) -> None:
        pass


class _GlooGlue:
    """The same over torch.distributed's Gloo process group (file store: no TCP port to collide on)."""

    def __init__(self, store: str, rank: int, size: int):
        import torch.distributed as dist

        self.dist = dist
        dist.init_process_group("gloo", init_method=Path(store).resolve().as_uri(), rank=rank, world_size=size)

    def collective(self, device):
        return TorchCollective(None, device)

    def gather(self, obj):
        out = [None] * self.dist.get_world_size()
        self.dist.all_gather_object(out, obj)
        return out

    def all_min(self, value: int) -> int:
        out = [None] * self.dist.get_world_size()
        self.dist.all_gather_object(out, value)
        return min(out)

    def library(self) -> str:
        import torch

        return f"torch {torch.__version__} Gloo"

    def close(self) -> None:
        # Every rank leaves together: a rank that exits while another still talks to it fails that one's exit.
        self.dist.barrier()
        self.dist.destroy_process_group()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--json", help="where rank 0 writes the results")
    parser.add_argument("--quick", action="store_true", help="two splits of the lamp and porosity cases")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--gloo", metavar="STORE", help="torch.distributed's Gloo with this file store, not MPI")
    parser.add_argument("--rank", type=int, default=0, help="with --gloo: this process's rank")
    parser.add_argument("--size", type=int, default=1, help="with --gloo: the number of ranks")
    args = parser.parse_args()
    glue = _GlooGlue(args.gloo, args.rank, args.size) if args.gloo else _MPIGlue()
    coll = glue.collective(args.device)
    t0 = time.perf_counter()
    results = distributed_cases.all_cases(coll, quick=args.quick)
    seconds = time.perf_counter() - t0
    everyone = glue.gather({"rank": coll.rank, "seconds": seconds, "results": results})
    ok = all(r["ok"] for r in results)
    ok = bool(glue.all_min(int(ok)))
    if coll.rank == 0:
        summary = {
            "library": glue.library(),
            "ranks": coll.size,
            "device": args.device,
            "cases_per_rank": len(results),
            "failed": sum(not r["ok"] for part in everyone for r in part["results"]),
            "ok": ok,
            "seconds": max(part["seconds"] for part in everyone),
            "per_rank": everyone,
        }
        if args.json:
            Path(args.json).write_text(json.dumps(summary, indent=1))
        print(
            f"{coll.size} ranks, {len(results)} cases per rank, {summary['failed']} failed, "
            f"{summary['seconds']:.1f} s ({summary['library']})"
        )
    glue.close()
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
