"""One MPI rank of the distributed checks (``distributed_cases.py``), for ``mpiexec -n P python
tests/distributed_ranks.py --json OUT``: every rank runs every case on the CPU; rank 0 writes every rank's results
to OUT and the exit status is 0 only when all ranks passed every case."""

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
from mpi4py import MPI  # noqa: E402

from warp_lamp.distributed import MPICollective  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--json", help="where rank 0 writes the results")
    parser.add_argument("--quick", action="store_true", help="two splits of the lamp and porosity cases")
    parser.add_argument("--device", default="cpu")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    coll = MPICollective(comm, args.device)
    t0 = time.perf_counter()
    results = distributed_cases.all_cases(coll, quick=args.quick)
    seconds = time.perf_counter() - t0
    everyone = comm.gather({"rank": coll.rank, "seconds": seconds, "results": results}, root=0)
    ok = all(r["ok"] for r in results)
    ok = bool(comm.allreduce(int(ok), op=MPI.MIN))
    if coll.rank == 0:
        summary = {
            "library": MPI.Get_library_version().splitlines()[0].strip(),
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
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
