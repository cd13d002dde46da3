"""Stand-ins for collective libraries that this CPU machine lacks, for the distributed tests: ranks are threads of one
process, and the stand-in takes raw pointers as CuPy's NCCL communicator does, so that the NCCL code path (pointers,
counts, dtype and op codes, the stream handle, the gathered bitwise OR) runs as it does on GPUs."""

from __future__ import annotations

import ctypes
import threading
from types import SimpleNamespace

import numpy as np
import warp as wp

from warp_lamp.distributed import Collective, NCCLCollective

#: NCCL's enum values (nccl.h), under the names cupy.cuda.nccl gives them.
FAKE_NCCL = SimpleNamespace(
    NCCL_INT8=0,
    NCCL_UINT8=1,
    NCCL_INT32=2,
    NCCL_UINT32=3,
    NCCL_INT64=4,
    NCCL_UINT64=5,
    NCCL_FLOAT16=6,
    NCCL_FLOAT32=7,
    NCCL_FLOAT64=8,
    NCCL_SUM=0,
    NCCL_PROD=1,
    NCCL_MAX=2,
    NCCL_MIN=3,
)
_DTYPES = {2: np.int32, 3: np.uint32, 4: np.int64, 5: np.uint64, 7: np.float32, 8: np.float64}
_REDUCE = {0: np.add.reduce, 2: np.maximum.reduce, 3: np.minimum.reduce}


def _view(ptr: int, count: int, dtype) -> np.ndarray:
    nbytes = count * np.dtype(dtype).itemsize
    return np.frombuffer((ctypes.c_char * nbytes).from_address(ptr), dtype=dtype) if count else np.zeros(0, dtype)


class FakeWorld:
    """The shared state of ``size`` thread ranks: each collective deposits every rank's data, waits for all, and
    each rank reads the combined result."""

    def __init__(self, size: int):
        self.size = size
        self.barrier = threading.Barrier(size, timeout=120)
        self.slots = [None] * size
        self.calls = 0

    def exchange(self, rank: int, data: np.ndarray) -> list[np.ndarray]:
        self.slots[rank] = data.copy()
        self.barrier.wait()
        out = list(self.slots)
        self.barrier.wait()
        if rank == 0:
            self.calls += 1
        return out


class FakeNcclCommunicator:
    """``cupy.cuda.nccl.NcclCommunicator``'s methods that the library calls, on host pointers."""

    def __init__(self, world: FakeWorld, rank: int):
        self.world = world
        self.rank = rank
        self.streams = set()

    def rank_id(self) -> int:
        return self.rank

    def size(self) -> int:
        return self.world.size

    def device_id(self) -> int:
        return 0

    def allReduce(self, sendbuf, recvbuf, count, datatype, op, stream):
        self.streams.add(stream)
        dtype = _DTYPES[datatype]
        parts = self.world.exchange(self.rank, _view(sendbuf, count, dtype))
        _view(recvbuf, count, dtype)[:] = _REDUCE[op](np.stack(parts), axis=0)

    def allGather(self, sendbuf, recvbuf, count, datatype, stream):
        self.streams.add(stream)
        dtype = _DTYPES[datatype]
        parts = self.world.exchange(self.rank, _view(sendbuf, count, dtype))
        _view(recvbuf, count * self.world.size, dtype)[:] = np.concatenate(parts)


class Int64OnlyCollective(NCCLCollective):
    """The NCCL stand-in reducing uint64 as int64, as torch.distributed does: the keys go through the library's
    top-bit flip (``flip_keys``), which a wrong flip would turn into wrong owners."""

    name = "int64-only"
    flip_keys = True

    def allreduce(self, arr: wp.array, op: str) -> None:
        if arr.dtype == wp.uint64:
            arr = arr.view(wp.int64)
        super().allreduce(arr, op)


def fake_nccl_collectives(size: int, *, int64_only: bool = False) -> list[Collective]:
    """One NCCL-path collective per thread rank, on the CPU."""
    world = FakeWorld(size)
    kind = Int64OnlyCollective if int64_only else NCCLCollective
    return [kind(FakeNcclCommunicator(world, r), "cpu", nccl=FAKE_NCCL) for r in range(size)]


def run_ranks(collectives, fn) -> list:
    """fn(collective) on one thread per rank; the results by rank, re-raising the first rank's error."""
    results = [None] * len(collectives)
    errors = [None] * len(collectives)

    def body(r):
        try:
            results[r] = fn(collectives[r])
        except BaseException as e:
            errors[r] = e
            collectives[r].comm.world.barrier.abort()

    threads = [threading.Thread(target=body, args=(r,)) for r in range(len(collectives))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for e in errors:
        if e is not None and not isinstance(e, threading.BrokenBarrierError):
            raise e
    for e in errors:
        if e is not None:
            raise e
    return results
