"""The lamp and porosity on particles split across processes and devices, through an existing collective library.

Each rank (a process, usually one per GPU) holds some of the particles, each with a **global id**: an integer in
[0, 2^31 - 1), unique across ranks. The caller starts the processes and passes its communicator; the library never
starts processes. Three collective libraries are wrapped (imported lazily, ``pip install ".[distributed]"``):

- **MPI** through mpi4py (:class:`MPICollective`): reduces host memory, so a CUDA lamp stages its keys through the
  host (a synchronisation, not capturable in a CUDA graph). The CPU path reduces the lamp's own arrays in place.
- **NCCL** through CuPy's ``cupy.cuda.nccl`` (:class:`NCCLCollective`): reduces device memory on Warp's stream, so
  :meth:`DistributedLamp.update` can be recorded in a CUDA graph (``wp.ScopedCapture``).
- **torch.distributed** (:class:`TorchCollective`): NCCL for CUDA tensors, Gloo for CPU tensors, on Warp's stream;
  capture is off by default (``capturable=True`` asks for it; ``bench/gpu/parts/distributed.sh`` tests it).

The lamp (criteria 0, 1 and ``"area"``) keeps, per cell and lamp, the minimum of packed (depth, id) keys. A minimum is
associative and commutative, so each rank runs the lamp's own depth pass on its particles, writes global ids into
its keys, and an all-reduce MIN combines them; each rank then scatters counts to its own particles. The counts, and
so the forces, are **bitwise equal** to one device holding all particles in global-id order, for any split. Two
details make that hold:

- Ties go to the lowest id. A rank sorts its particles by global id before its depth pass (a permutation fixed at
  :meth:`DistributedLamp.set_ids`, skipped when the caller's order is already ascending), so that its local index
  order is the global order.
- A rank's keys keep local indices (its last update's owners seed the next update, as ``ShiningLamp`` does; they are
  always the rank's own particles, so seeding needs nothing from other ranks). After the reduction, a cell belongs
  to this rank exactly when the reduced key equals the rank's own key with its global id: no map from global ids
  back to local indices is needed (no array of N_global entries, no search).

**The reach** (criteria 0 and 1 without walls or ``follow``; ``reach="auto"``, the default): a rank's particles
light only some cells, so each rank seeds, converts and scatters only a rectangle of cells per grid (its particles'
footprint box, widened by ``reach_margin`` cells), and all-reduces only the cells that two or more ranks'
rectangles hold: a cell that one rank alone can reach has that rank's key as its reduced key. A rank of an x-slab
still reduces the whole x grid (every slab lights it) but only the strips of the y and z grids it shares with its
neighbours. The rectangles are agreed (an all-gather of 12 integers per rank) by the first update after
:meth:`DistributedLamp.set_ids` and by :meth:`DistributedLamp.agree_reach`, both outside any capture: a captured
update replays fixed-size kernels and one fixed-size all-reduce, never a host synchronisation. Each update counts,
on the device, the particles whose footprint left their rank's rectangle (moved more than the margin, or the
frame's pose changed); :meth:`DistributedLamp.reach_escapes` reads the count, and after any escape the forces are
not guaranteed until the reach is agreed again. Where every rank reaches everything (a random split), every cell is
shared and the result is the whole-grid reduction's.

The distributed lamp is the lamp's pipeline (:mod:`warp_lamp.pipeline`) with two stages swapped for distributed
variants, not a second lamp: :class:`AgreedFrame` reduces the following grid's box over the ranks, and the
estimators :class:`DistributedFirstHit` and :class:`DistributedAreaSplit` run the one-device seed and depth pass,
then their own steps (keys to global ids, the reduction, the scatter to the rank's own particles).
:class:`DistributedLamp` is a :class:`~warp_lamp.ShiningLamp` built from them; its forces are the pipeline's.

Not distributed: the wetted surface (``surfaces="all"``, see :data:`WETTED_REFUSAL`) and frame averaging
(:data:`FRAMES_REFUSAL`).

Porosity (:func:`porosity_distributed`): the sum methods add int64 fixed-point units per cell (integer sums do not
depend on the order or the split) and reduce them by SUM; the union methods mark a sub-cell bitmap per rank and
reduce it by bitwise OR, which works for any split (a halo of particles would need a spatial split).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_lamp.estimators import AreaSplit, FirstHit, LampDiagnostics
from warp_lamp.grid import LampGrid
from warp_lamp.kernels import distributed as dist_kernels
from warp_lamp.kernels import lamp as lamp_kernels
from warp_lamp.lamp import LampOptions, ShiningLamp
from warp_lamp.pipeline import LampFrame, LampInput, lamp_input
from warp_lamp.porosity import (
    POROSITY_METHODS,
    count_bitmap,
    porosity_mark_union,
    porosity_plan,
)
from warp_lamp.validate import (
    DEFAULT_MAX_BYTES,
    check_budget,
    check_integer,
    check_particles,
    check_positive,
    format_bytes,
    lamp_mask,
    lamp_rotation,
)

__all__ = [
    "FIXED_POINT_BITS",
    "FRAMES_REFUSAL",
    "WETTED_REFUSAL",
    "AgreedFrame",
    "Collective",
    "DistributedAreaSplit",
    "DistributedDiagnostics",
    "DistributedFirstHit",
    "DistributedLamp",
    "LocalCollective",
    "MPICollective",
    "NCCLCollective",
    "TorchCollective",
    "as_collective",
    "enclosing_grid",
    "porosity_distributed",
    "porosity_fixed_units",
]

#: Why the wetted surface is not distributed, and the plan.
WETTED_REFUSAL = (
    "surfaces='all' (the wetted surface) is not distributed: its fluid region is a flood fill from outside over the "
    "whole grid's probe-dilated voxels, and a crossing's load goes to the nearest sphere of any rank. Plan: (1) each "
    "rank marks its spheres' dilated voxels and a bitwise-OR all-reduce gives every rank the global occupancy; (2) "
    "each rank runs the connectivity solve on it redundantly (deterministic, so all agree); (3) each crossing's "
    "nearest sphere is a MIN over packed (distance, global id) keys, all-reduced as the lamp's keys are; (4) each "
    "rank scatters the loads of its own spheres. Use surfaces='first'"
)

#: Why frame averaging is not distributed, and what to do instead.
FRAMES_REFUSAL = (
    "frames: frame averaging is not distributed; build one DistributedLamp per frame grid (grid.rotated(R) for R in "
    "frames.lamp_frame_rotations(K)) and average their forces"
)

#: Fractional bits of the fixed-point porosity sums: units of 2^-40 of a cell's volume.
FIXED_POINT_BITS = 40

#: Largest global id: ids go into the low 32 bits of a key as int32.
_MAX_ID = (1 << 31) - 2
_TOP = np.uint64(0x8000000000000000)

_OPS = ("min", "max", "sum", "bor")
_WP_DTYPES = {
    np.dtype(np.uint64): wp.uint64,
    np.dtype(np.int64): wp.int64,
    np.dtype(np.uint32): wp.uint32,
    np.dtype(np.int32): wp.int32,
    np.dtype(np.float32): wp.float32,
    np.dtype(np.float64): wp.float64,
}


# --- collectives ------------------------------------------------------------------------------------------------


class Collective:
    """What the distributed lamp needs of a collective library: in-place all-reduces and all-gathers of 1-D warp
    arrays on the device, and small host reductions for setup (built on the device ones by default).

    Attributes:
        name: The library ("mpi", "nccl", "torch", "local").
        rank: This process's rank.
        size: Number of ranks.
        device: The Warp device of this rank's arrays.
        capturable: Whether the device collectives can be recorded in a CUDA graph on Warp's stream.
        flip_keys: uint64 arrays are reduced as int64 (the library has no unsigned 64-bit reduction): callers xor
            the top bit of each key before and after, which turns unsigned order into signed order.
    """

    name = "abstract"
    capturable = False
    flip_keys = False

    def __init__(self, rank: int, size: int, device):
        self.rank = int(rank)
        self.size = int(size)
        self.device = wp.get_device(device)

    def allreduce(self, arr: wp.array, op: str) -> None:
        """Reduce ``arr`` in place across ranks, on ``arr``'s device and Warp's stream.

        Args:
            arr: A contiguous 1-D warp array of uint64, int64, uint32, int32, float32 or float64.
            op: "min", "max", "sum" or "bor" (bitwise OR, for integer arrays).
        """
        raise NotImplementedError

    def allgather(self, send: wp.array, recv: wp.array) -> None:
        """recv[r * len(send) : (r + 1) * len(send)] = rank r's ``send``, for every rank r."""
        raise NotImplementedError

    def _check(self, arr, op):
        if op not in _OPS:
            raise ValueError(f"op: expected one of {_OPS}, got {op!r}")
        if not isinstance(arr, wp.array) or arr.ndim != 1 or not arr.is_contiguous:
            raise ValueError("arr: expected a contiguous 1-D warp array")

    def allreduce_host(self, x, op: str) -> np.ndarray:
        """A reduced copy of the host array ``x`` (setup only: it synchronises). uint64 are reduced as unsigned."""
        x = np.ascontiguousarray(x)
        flat = x.reshape(-1)
        flip = self.flip_keys and flat.dtype == np.uint64 and op in ("min", "max")
        if flip:
            flat = flat ^ _TOP
        arr = wp.array(flat, dtype=_WP_DTYPES[flat.dtype], device=self.device)
        self.allreduce(arr, op)
        out = arr.numpy()
        if flip:
            out = out ^ _TOP
        return out.reshape(x.shape)

    def allgather_host(self, x) -> list[np.ndarray]:
        """Every rank's 1-D host array ``x`` (lengths may differ), as a list by rank (setup only)."""
        x = np.ascontiguousarray(x).reshape(-1)
        lengths = self._gather_fixed(np.array([len(x)], dtype=np.int64))
        longest = int(lengths.max())
        padded = np.zeros(max(longest, 1), dtype=x.dtype)
        padded[: len(x)] = x
        table = self._gather_fixed(padded).reshape(self.size, -1)
        return [table[r, : int(lengths[r])].copy() for r in range(self.size)]

    def _gather_fixed(self, x: np.ndarray) -> np.ndarray:
        send = wp.array(x, dtype=_WP_DTYPES[x.dtype], device=self.device)
        recv = wp.empty(self.size * len(x), dtype=send.dtype, device=self.device)
        self.allgather(send, recv)
        return recv.numpy()

    def _or_by_gather(self, arr: wp.array) -> None:
        """Bitwise OR for libraries without one: gather every rank's words, OR them with a kernel. A scratch buffer
        of ``size`` times the array is kept per length, made on first use (not inside a capture)."""
        if arr.dtype not in (wp.uint32, wp.int32):
            raise TypeError("arr: bitwise OR by gathering takes uint32 or int32 words")
        scratch = getattr(self, "_or_scratch", {})
        self._or_scratch = scratch
        n = arr.shape[0]
        if n not in scratch:
            if arr.device.is_capturing:
                raise RuntimeError(
                    f"{self.name}: a bitwise OR of {n} words needs a gather buffer, made by one call before the capture"
                )
            scratch[n] = wp.empty(self.size * n, dtype=wp.uint32, device=arr.device)
        words = arr if arr.dtype == wp.uint32 else arr.view(wp.uint32)
        self.allgather(words, scratch[n])
        wp.launch(
            dist_kernels.dist_or_gathered, dim=n, inputs=[scratch[n], self.size], outputs=[words], device=arr.device
        )


class LocalCollective(Collective):
    """One rank and no library: every reduction is the identity. ``DistributedLamp`` on it is one process holding all
    particles; :func:`porosity_distributed` on it is the single-process result its distributed runs equal."""

    name = "local"
    capturable = True

    def __init__(self, device=None):
        super().__init__(0, 1, device)

    def allreduce(self, arr: wp.array, op: str) -> None:
        self._check(arr, op)

    def allgather(self, send: wp.array, recv: wp.array) -> None:
        wp.copy(recv, send, count=send.shape[0])


_MPI_TYPES = {
    wp.uint64: "UINT64_T",
    wp.int64: "INT64_T",
    wp.uint32: "UINT32_T",
    wp.int32: "INT32_T",
    wp.float32: "FLOAT",
    wp.float64: "DOUBLE",
}


class MPICollective(Collective):
    """MPI through mpi4py. Host memory: a CPU lamp's arrays are reduced in place; a CUDA lamp's are copied to the
    host and back (a synchronisation, so not capturable; a CUDA-aware MPI would still need the stream synchronised,
    since MPI calls are not stream-ordered)."""

    name = "mpi"

    def __init__(self, comm, device=None):
        from mpi4py import MPI  # the ``distributed`` extra

        self.MPI = MPI
        self.comm = comm
        super().__init__(comm.Get_rank(), comm.Get_size(), device)

    def _buffer(self, host: np.ndarray, dtype):
        return [host, getattr(self.MPI, _MPI_TYPES[dtype])]

    def _op(self, op):
        return {"min": self.MPI.MIN, "max": self.MPI.MAX, "sum": self.MPI.SUM, "bor": self.MPI.BOR}[op]

    def _host_view(self, arr: wp.array):
        if arr.device.is_cuda:
            if arr.device.is_capturing:
                raise RuntimeError(
                    "mpi: MPI reduces host memory, which a CUDA graph cannot record; use NCCL (NCCLCollective) to "
                    "capture a distributed update, or update eagerly"
                )
            return arr.numpy(), True
        return arr.numpy(), False  # a view of the CPU array's memory

    def allreduce(self, arr: wp.array, op: str) -> None:
        self._check(arr, op)
        host, staged = self._host_view(arr)
        self.comm.Allreduce(self.MPI.IN_PLACE, self._buffer(host, arr.dtype), op=self._op(op))
        if staged:
            arr.assign(host)

    def allgather(self, send: wp.array, recv: wp.array) -> None:
        src, _ = self._host_view(send)
        dst, staged = self._host_view(recv)
        self.comm.Allgather(self._buffer(src, send.dtype), self._buffer(dst, recv.dtype))
        if staged:
            recv.assign(dst)

    def allreduce_host(self, x, op: str) -> np.ndarray:
        x = np.ascontiguousarray(x)
        out = np.empty_like(x)
        dtype = _WP_DTYPES[x.dtype]
        self.comm.Allreduce(self._buffer(x, dtype), self._buffer(out, dtype), op=self._op(op))
        return out

    def allgather_host(self, x) -> list[np.ndarray]:
        return [np.asarray(part) for part in self.comm.allgather(np.ascontiguousarray(x).reshape(-1))]


def _stream_handle(device) -> int:
    """The CUDA stream Warp launches on for ``device`` (0 on the CPU, where only a stand-in library runs)."""
    return wp.get_stream(device).cuda_stream if device.is_cuda else 0


class NCCLCollective(Collective):
    """NCCL through CuPy (``cupy.cuda.nccl.NcclCommunicator``): device buffers reduced by raw pointer on Warp's
    stream, so a CUDA graph records them. NCCL has uint64 MIN; it has no bitwise OR, which is done by an
    all-gather and a kernel (``size`` times the bytes).

    Args:
        comm: An ``NcclCommunicator`` (one per process and device).
        device: The rank's Warp device; by default ``cuda:<comm.device_id()>``.
        nccl: The module with the NCCL constants (``cupy.cuda.nccl`` by default; tests pass a stand-in).
    """

    name = "nccl"
    capturable = True

    def __init__(self, comm, device=None, *, nccl=None):
        if nccl is None:
            from cupy.cuda import nccl  # the GPU machines' CuPy; imported only here
        self.nccl = nccl
        self.comm = comm
        if device is None:
            device = f"cuda:{comm.device_id()}"
        super().__init__(comm.rank_id(), comm.size(), device)
        self._types = {
            wp.uint64: nccl.NCCL_UINT64,
            wp.int64: nccl.NCCL_INT64,
            wp.uint32: nccl.NCCL_UINT32,
            wp.int32: nccl.NCCL_INT32,
            wp.float32: nccl.NCCL_FLOAT32,
            wp.float64: nccl.NCCL_FLOAT64,
        }
        self._ops = {"min": nccl.NCCL_MIN, "max": nccl.NCCL_MAX, "sum": nccl.NCCL_SUM}

    def allreduce(self, arr: wp.array, op: str) -> None:
        self._check(arr, op)
        if op == "bor":
            self._or_by_gather(arr)
            return
        stream = _stream_handle(arr.device)
        self.comm.allReduce(arr.ptr, arr.ptr, arr.shape[0], self._types[arr.dtype], self._ops[op], stream)

    def allgather(self, send: wp.array, recv: wp.array) -> None:
        stream = _stream_handle(send.device)
        self.comm.allGather(send.ptr, recv.ptr, send.shape[0], self._types[send.dtype], stream)


class TorchCollective(Collective):
    """torch.distributed on its default (or a given) process group: NCCL for CUDA arrays, Gloo for CPU arrays. The
    arrays are handed over without copies (``wp.to_torch``); on CUDA the collective is issued on Warp's stream.
    torch reduces no uint64, so keys are reduced as int64 with their top bit flipped (:attr:`flip_keys`).

    Args:
        group: A process group, or None for the default one.
        device: The rank's Warp device (Warp's default when None).
        capturable: Allow :meth:`allreduce` inside ``wp.ScopedCapture``. Off by default: whether torch's NCCL
            process group records into a graph begun on Warp's stream depends on the torch version;
            ``bench/gpu/parts/distributed.sh`` checks it.
    """

    name = "torch"
    flip_keys = True

    def __init__(self, group=None, device=None, *, capturable: bool = False):
        import torch.distributed as dist  # imported only here

        self.dist = dist
        self.group = group
        self.capturable = bool(capturable)
        super().__init__(dist.get_rank(group), dist.get_world_size(group), device)

    def _tensor(self, arr: wp.array):
        view = {wp.uint64: wp.int64, wp.uint32: wp.int32}.get(arr.dtype)
        return wp.to_torch(arr if view is None else arr.view(view))

    def _stream(self, device):
        import torch

        if not device.is_cuda:
            import contextlib

            return contextlib.nullcontext()
        return torch.cuda.stream(wp.stream_to_torch(wp.get_stream(device)))

    def _refuse_capture(self, device):
        if device.is_capturing and not self.capturable:
            raise RuntimeError(
                "torch: collectives inside a CUDA graph capture are off (TorchCollective(capturable=True) turns them "
                "on where the torch version records them); use NCCLCollective, or update eagerly"
            )

    def allreduce(self, arr: wp.array, op: str) -> None:
        self._check(arr, op)
        self._refuse_capture(arr.device)
        if op == "bor":
            self._or_by_gather(arr)
            return
        ops = {"min": self.dist.ReduceOp.MIN, "max": self.dist.ReduceOp.MAX, "sum": self.dist.ReduceOp.SUM}
        with self._stream(arr.device):
            self.dist.all_reduce(self._tensor(arr), op=ops[op], group=self.group)

    def allgather(self, send: wp.array, recv: wp.array) -> None:
        self._refuse_capture(send.device)
        src = self._tensor(send)
        dst = self._tensor(recv)
        with self._stream(send.device):
            self.dist.all_gather(list(dst.chunk(self.size)), src, group=self.group)


def as_collective(comm, device=None) -> Collective:
    """The :class:`Collective` for a caller's communicator.

    Args:
        comm: A :class:`Collective`; an mpi4py communicator; a CuPy ``NcclCommunicator``; ``"torch"`` (the default
            process group) or a torch process group; or None (one process, :class:`LocalCollective`).
        device: The rank's Warp device (for NCCL, by default the communicator's).
    """
    if isinstance(comm, Collective):
        if device is not None and wp.get_device(device) != comm.device:
            raise ValueError(f"device: {wp.get_device(device)}, but the collective's arrays live on {comm.device}")
        return comm
    if comm is None:
        return LocalCollective(device)
    kind = type(comm).__module__ + "." + type(comm).__name__
    if kind.startswith("mpi4py."):
        return MPICollective(comm, device)
    if type(comm).__name__ == "NcclCommunicator":
        return NCCLCollective(comm, device)
    if isinstance(comm, str) and comm == "torch":
        return TorchCollective(None, device)
    if kind.startswith("torch."):
        return TorchCollective(comm, device)
    raise TypeError(
        f"comm: expected an mpi4py communicator, a cupy NcclCommunicator, 'torch' or a torch process group, a "
        f"Collective, or None; got {kind}"
    )


def _agree(coll: Collective, error: Exception | None, what: str) -> None:
    """Raise on every rank if any rank failed a check, so that no rank enters a collective the others left."""
    failed = coll.allreduce_host(np.array([0 if error is None else 1], dtype=np.int32), "sum")[0]
    if error is not None:
        raise error
    if failed:
        raise RuntimeError(f"{what}: {int(failed)} other rank(s) refused their input (their error says why)")


def _fingerprint(*parts) -> np.ndarray:
    """A 62-bit digest of the setup, as int64 (d, -d): MIN of both equal on every rank iff all agree."""
    h = hashlib.sha256()
    for p in parts:
        h.update(np.ascontiguousarray(p).tobytes() if isinstance(p, np.ndarray) else repr(p).encode())
    d = int.from_bytes(h.digest()[:8], "little") >> 2
    return np.array([d, -d], dtype=np.int64)


def _check_ids(global_ids, n: int | None = None) -> np.ndarray | wp.array:
    if isinstance(global_ids, wp.array):
        if global_ids.dtype != wp.int32 or global_ids.ndim != 1:
            raise TypeError("global_ids: expected a 1-D warp array of int32")
        if n is not None and global_ids.shape[0] != n:
            raise ValueError(f"global_ids: has {global_ids.shape[0]} entries, the rank has {n} particles")
        return global_ids
    ids = np.asarray(global_ids)
    if ids.ndim != 1 or not (ids.dtype.kind in "iu" or ids.size == 0):
        raise ValueError(f"global_ids: expected a 1-D array of integers, got {ids.dtype} of shape {ids.shape}")
    if n is not None and len(ids) != n:
        raise ValueError(f"global_ids: has {len(ids)} entries, the rank has {n} particles")
    bad = (ids < 0) | (ids > _MAX_ID)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"global_ids: must be in [0, {_MAX_ID}]; index {k} is {ids[k]}")
    return ids.astype(np.int32)


# --- the lamp: the pipeline's stages, distributed -------------------------------------------------------------------


@dataclass
class DistributedDiagnostics:
    """What the last distributed update found (a collective call builds it).

    Attributes:
        lamp: The rank's :class:`~warp_lamp.LampDiagnostics`: its own particles' counts and surface flags; owners
            as global ids and depths of the reduced keys (the whole grid's); lit cells of the whole grid; invalid
            and outside particles summed over ranks; the walls' counts (the whole grid's, the same on every rank);
            with a pressure, the resultant of the rank's own particles.
        ranks: Number of ranks.
        n_global: Particles over all ranks.
        reduction_bytes: Bytes each rank hands to the collective library per update (:attr:`DistributedLamp.
            reduction_bytes`).
    """

    lamp: LampDiagnostics
    ranks: int
    n_global: int
    reduction_bytes: int


class AgreedFrame(LampFrame):
    """The lamp's frame on one rank: with ``follow``, the body's box is reduced over the ranks between the box and
    the move (``LampFrame.launch_agree_bounds``), so that every rank moves the grid alike."""

    def __init__(self, grid: LampGrid, device, comm: Collective, **options):
        super().__init__(grid, device, **options)
        self.comm = comm
        #: Bytes handed to the collective per update: the box's six float32.
        self.reduction_bytes = 24 if self.follow else 0

    def launch_agree_bounds(self) -> None:
        """The box over all ranks: the maxima negated, one all-reduce MIN of the six, negated back."""
        wp.launch(dist_kernels.dist_negate_upper, dim=3, outputs=[self._bounds], device=self.device)
        self.comm.allreduce(self._bounds, "min")
        wp.launch(dist_kernels.dist_negate_upper, dim=3, outputs=[self._bounds], device=self.device)


def _reduction_budget(grid: LampGrid, depth_slots: int, area: bool, max_bytes) -> None:
    """Refuse, before anything is allocated, keys whose reduction buffers exceed ``max_bytes``."""
    samples = grid.n_samples if area else grid.n_cells
    n_keys = 2 * depth_slots * samples
    # The rank's keys, their global-id copy (sent, then reduced in place), and for the area criterion the merged
    # lists and one round's buffer.
    need = 2 * n_keys * 8 + (n_keys * 8 + 2 * samples * 8 if area else 0)
    check_budget(
        need,
        max_bytes,
        f"grid: {n_keys:,} keys per rank and their reduction buffers need {format_bytes(need)}",
        "use larger cells",
    )


class _RankSteps:
    """What the distributed estimators add to the one-device ones, mixed in before :class:`FirstHit` or
    :class:`AreaSplit` (whose seed, depth pass and owner maps they reuse): the rank's particles named by global ids
    and put in id order before the steps, the keys rewritten with global ids (:meth:`launch_to_global`), and the
    diagnostics of the reduced keys. Subclasses add the reduction and the scatter to the rank's own particles."""

    #: The steps: the one-device seed and depth pass on the rank's particles, then the collective ones.
    steps = ("seed", "depth", "to_global", "reduce", "scatter")
    #: Whether :meth:`launch_to_global` flips the keys' top bit for a library that reduces int64 (the area
    #: criterion's merge flips its own offers instead).
    _flips_keys = True

    def _init_ranks(self, comm: Collective) -> None:
        self.comm = comm
        d = self.device
        self._flip = 1 if comm.flip_keys else 0
        self._no_int = wp.empty(0, dtype=wp.int32, device=d)
        #: Global id of each particle in id order (the depth pass's local index order), set by :meth:`place`.
        self.gids = self._no_int
        #: The caller's row of each particle in id order; empty where the caller's order is already ascending.
        self.caller = self._no_int
        self.n_global = 0
        self._sorted = None
        #: The keys with global ids: what this rank sends; for criteria 0 and 1, after the reduction, the reduced
        #: keys of all ranks.
        self.reduced = wp.empty(self.keys.shape[0], dtype=wp.uint64, device=d)
        self.nbytes += self.reduced.shape[0] * 8

    def place(self, gids: wp.array, caller: wp.array, n_global: int) -> None:
        """The rank's particles, named (``DistributedLamp.set_ids``; not inside a capture): their global ids in id
        order, the caller's rows, and the ids' span over all ranks. Makes room for them (as ``reserve``)."""
        n = gids.shape[0]
        self.gids, self.caller, self.n_global = gids, caller, n_global
        # FirstHit.reserve only grows its buffers: start again, so that the split and order fit these particles.
        self.counts = wp.zeros(0, dtype=wp.int64, device=self.device)
        self.order = self._no_order
        self.reserve(n)
        self._ordered_n = -1
        if caller.shape[0]:
            d = self.device
            self._sorted = (
                wp.empty(n, dtype=wp.vec3, device=d),
                wp.empty(n, dtype=wp.float32, device=d),
                wp.empty(n, dtype=wp.int32, device=d),
            )

    def update(self, inp: LampInput) -> None:
        """The particles in global-id order (so that ties go to the lowest id, as on one device), then the steps."""
        super().update(self._in_id_order(inp))

    def _in_id_order(self, inp: LampInput) -> LampInput:
        if not self.caller.shape[0] or inp.n == 0:
            return inp
        pos, rad, act = self._sorted
        p = inp.particles
        wp.launch(
            dist_kernels.dist_gather_particles,
            dim=inp.n,
            inputs=[p.positions, p.radii, p.active, self.caller],
            outputs=[pos, rad, act],
            device=self.device,
        )
        sorted_particles = lamp_kernels.LampParticles()
        sorted_particles.positions, sorted_particles.radii = pos, rad
        sorted_particles.active = p.active if inp.active is None else act  # an empty mask stays empty
        sorted_particles.n = inp.n
        return LampInput(sorted_particles, inp.n, inp.in_frame, inp.active)

    def launch_to_global(self) -> None:
        """Update step: the rank's keys with global ids, into :attr:`reduced`."""
        wp.launch(
            dist_kernels.dist_keys_to_global,
            dim=self.keys.shape[0],
            inputs=[self.keys, self.gids, self._flip if self._flips_keys else 0],
            outputs=[self.reduced],
            device=self.device,
        )

    def _surface(self, owners: dict) -> np.ndarray:
        # The owners are global ids: a particle is lit where its id owns a cell; its flag goes to its caller row.
        surface = np.zeros(self.n, dtype=bool)
        if self.n:
            lit = np.unique(np.concatenate([own[own >= 0].ravel() for own in owners.values()]))
            rows = self.caller.numpy() if self.caller.shape[0] else np.arange(self.n)
            surface[rows[np.isin(self.gids.numpy(), lit)]] = True
        return surface

    def diagnostics(self) -> LampDiagnostics:
        """The one-device diagnostics of the reduced keys, with the skip counters summed over ranks (collective)."""
        out = super().diagnostics()
        skipped = self.comm.allreduce_host(self.diag.numpy()[:2].astype(np.int64), "sum")
        out.invalid, out.outside = int(skipped[0]), int(skipped[1])
        return out


class DistributedFirstHit(_RankSteps, FirstHit):
    """Criteria 0 and 1 on a rank's share of the particles: seed and depth pass on its own particles (local
    indices), keys to global ids, an all-reduce MIN, and the scatter to the cells whose reduced key is the rank's
    own (walls decided from the reduced key, the same on every rank)."""

    name = "first hit, distributed"

    def __init__(
        self,
        frame: LampFrame,
        lamp_mask: int,
        comm: Collective,
        *,
        criterion,
        split,
        order,
        max_bytes,
        reach: str = "all",
        reach_margin: int = 0,
    ):
        _reduction_budget(frame.grid, 1, False, max_bytes)
        super().__init__(frame, lamp_mask, criterion=criterion, split=split, order=order, max_bytes=max_bytes)
        self._init_ranks(comm)
        #: Whether the rank works on its reach only (criteria 0 and 1 without walls or a following grid).
        self.windowed = reach == "auto" and not frame.n_walls and not frame.follow
        self.reach_margin = int(reach_margin)
        #: The agreed reach: None until the first update after ``place`` (or :meth:`agree_reach`).
        self.window = None
        d = self.device
        self._escapes = wp.zeros(1, dtype=wp.int32, device=d)
        self._shared = wp.empty(0, dtype=wp.uint64, device=d)
        self._shared_cells = self._no_int
        self._slot_of = self._no_int
        #: Cells of the three grids in the rank's window, and cells two or more ranks' windows share.
        self.window_cells = self.grid.n_cells
        self.shared_cells = self.grid.n_cells

    @property
    def reduction_bytes(self) -> int:
        """The whole key array, 16 bytes per cell; with a reach, 16 bytes per shared cell."""
        if self.windowed:
            return 16 * self.shared_cells
        return 8 * self.reduced.shape[0]

    def place(self, gids: wp.array, caller: wp.array, n_global: int) -> None:
        """As the criteria's; the reach is agreed again by the next update."""
        super().place(gids, caller, n_global)
        self.window = None

    def update(self, inp: LampInput) -> None:
        """As :meth:`_RankSteps.update`; with a reach and none agreed yet, agree it first (collective: every rank
        is in this update; not inside a capture)."""
        if self.windowed and self.window is None:
            if self.device.is_capturing:
                raise RuntimeError(
                    "update: the ranks' reach is agreed by the first update after set_ids, which synchronises; run "
                    "one update (or agree_reach) before capturing"
                )
            self._agree_reach(inp)
        super().update(inp)

    def _agree_reach(self, inp: LampInput) -> None:
        """Each rank's footprint box per grid (cells, with ``reach_margin``), all-gathered; the cells two or more
        boxes share, listed; the keys emptied (cells outside the new window must hold none)."""
        d = self.device
        grid = self.grid
        self._input = inp
        big = np.iinfo(np.int32).max
        box = wp.array(np.array([big, -1, big, -1] * 3, dtype=np.int32), dtype=wp.int32, device=d)
        if inp.n:
            wp.launch(
                dist_kernels.dist_reach,
                dim=inp.n,
                inputs=[self._rays(), inp.particles, self._ray, self.lamp_mask],
                outputs=[box],
                device=d,
            )
        mine = _window_rects(box.numpy(), grid.counts, self.reach_margin)
        rects = [r.reshape(3, 4) for r in self.comm.allgather_host(mine.reshape(-1))]
        self.window = _window_struct(rects[self.comm.rank], self._rays())
        self.window_cells = int(self.window.n_cells)
        cells = _shared_cells(rects, grid.counts)
        self.shared_cells = len(cells)
        self._shared_cells = wp.array(cells, dtype=wp.int32, device=d) if len(cells) else self._no_int
        slot_of = np.full(grid.n_cells, -1, dtype=np.int32)
        slot_of[cells] = np.arange(len(cells), dtype=np.int32)
        self._slot_of = wp.array(slot_of, dtype=wp.int32, device=d)
        self._shared = wp.empty(2 * max(len(cells), 1), dtype=wp.uint64, device=d)
        self._escapes.zero_()
        self.forget()

    def agree_reach(self) -> None:
        """Agree the ranks' reach again at the last update's positions (collective; not inside a capture)."""
        if self.windowed and self._input is not None:
            self._agree_reach(self._input)

    def reach_escapes(self) -> int:
        """Particles (summed over ranks and updates) whose footprint left their rank's window since the reach was
        agreed (collective; synchronises). Counts of updates with escapes may differ from one device."""
        if not self.windowed:
            return 0
        return int(self.comm.allreduce_host(self._escapes.numpy().astype(np.int64), "sum")[0])

    def launch_seed(self) -> None:
        """Update step 1: the lamp's seed, on the rank's window only with a reach (and its escapes counted)."""
        if not self.windowed:
            super().launch_seed()
            return
        grid, particles = self._rays(), self._input.particles
        wp.launch(
            dist_kernels.dist_seed_window,
            dim=max(self.window_cells, self.n, self.diag.shape[0]),
            inputs=[grid, self.window, particles, self._ray],
            outputs=[self.keys, self.counts, self.diag],
            device=self.device,
        )
        if self.n:
            wp.launch(
                dist_kernels.dist_escapes,
                dim=self.n,
                inputs=[grid, self.window, particles, self._ray, self.lamp_mask],
                outputs=[self._escapes],
                device=self.device,
            )

    def launch_to_global(self) -> None:
        """Update step: the rank's keys with global ids (with a reach: of the shared cells only, packed)."""
        if not self.windowed:
            super().launch_to_global()
            return
        if self.shared_cells:
            wp.launch(
                dist_kernels.dist_pack,
                dim=self.shared_cells,
                inputs=[self.keys, self.gids, self._shared_cells, self._flip],
                outputs=[self._shared],
                device=self.device,
            )

    def launch_reduce(self) -> None:
        """Update step: the all-reduce MIN of :attr:`reduced` (with a reach: of the shared cells' keys), and the top
        bit flipped back where the library reduced int64, so that it holds the keys one device holding every
        particle would."""
        target = self.reduced
        if self.windowed:
            if not self.shared_cells:
                return
            target = self._shared[: 2 * self.shared_cells]
        self.comm.allreduce(target, "min")
        if self._flip:
            wp.launch(dist_kernels.dist_unflip, dim=target.shape[0], outputs=[target], device=self.device)

    def launch_scatter(self) -> None:
        """Update step: +1 / -1 to the rank's own particles where the reduced key is theirs; with walls, the walls'
        counts too (every rank counts them all)."""
        if self.windowed:
            if self.n and self.window_cells:
                wp.launch(
                    dist_kernels.dist_scatter_window,
                    dim=self.window_cells,
                    inputs=[self._cells(), self.window, self.keys, self.gids, self.caller, self._slot_of, self._shared],
                    outputs=[self.counts],
                    device=self.device,
                )
            return
        inputs = [self._cells(), self.keys, self.gids, self.caller]
        if self.frame.n_walls:
            # Whether the body rests on a wall is the whole body's: the smallest gap over every rank's particles.
            self.launch_contact()
            self.comm.allreduce(self.frame.wall_gap, "min")
            self.wall_counts.zero_()
            wp.launch(
                dist_kernels.dist_scatter_walls,
                dim=self.grid.n_cells,
                inputs=[*inputs, self.reduced, self.frame.walls_view(self._input.in_frame), self.lamp_mask],
                outputs=[self.counts, self.wall_counts],
                device=self.device,
            )
            return
        if self.n == 0:
            return
        wp.launch(
            dist_kernels.dist_scatter,
            dim=self.grid.n_cells,
            inputs=[*inputs, 0, self.reduced],  # 0: launch_reduce flipped the keys back
            outputs=[self.counts],
            device=self.device,
        )

    def _owner_keys(self) -> wp.array:
        if self.windowed:
            # The whole grid's reduced keys (diagnostics; collective): every rank's keys are empty outside its window.
            _RankSteps.launch_to_global(self)
            self.comm.allreduce(self.reduced, "min")
            if self._flip:
                n = self.reduced.shape[0]
                wp.launch(dist_kernels.dist_unflip, dim=n, outputs=[self.reduced], device=self.device)
        return self.reduced


def _window_rects(box: np.ndarray, counts: np.ndarray, margin: int) -> np.ndarray:
    """Per grid, (i0, ni, j0, nj) of the footprint box ``box`` (4 per grid, from ``dist_reach``) widened by
    ``margin`` cells and clamped to the grid; (0, 0, 0, 0) for a grid the rank does not reach."""
    out = np.zeros((3, 4), dtype=np.int64)
    for a in range(3):
        i_lo, i_hi, j_lo, j_hi = (int(x) for x in box[4 * a : 4 * a + 4])
        if i_lo > i_hi or j_lo > j_hi:
            continue
        nu, nv = (int(x) for x in counts[a])
        i0, i1 = max(i_lo - margin, 0), min(i_hi + margin, nu - 1)
        j0, j1 = max(j_lo - margin, 0), min(j_hi + margin, nv - 1)
        out[a] = (i0, i1 - i0 + 1, j0, j1 - j0 + 1)
    return out


def _window_bounds(i0: int, ni: int, n: int, h: float) -> tuple[float, float]:
    """Float32 bounds [lo, hi] (from the grid's corner) on a particle's extent along one axis of a grid that keep
    every cell the exact test may count inside cells [i0, i0 + ni): two cells in from each window edge, rounded
    inwards; unbounded at an edge the grid shares (the exact test clamps there), empty for an empty window."""
    if ni <= 0:
        return math.inf, -math.inf
    lo = -math.inf if i0 <= 0 else float(np.float32((i0 + 2) * h))
    hi = math.inf if i0 + ni >= n else float(np.float32((i0 + ni - 2) * h))
    if i0 > 0 and lo < (i0 + 2) * h:
        lo = float(np.nextafter(np.float32(lo), np.float32(np.inf)))
    if i0 + ni < n and hi > (i0 + ni - 2) * h:
        hi = float(np.nextafter(np.float32(hi), np.float32(-np.inf)))
    return lo, hi


def _window_struct(rect: np.ndarray, params=None) -> dist_kernels.ReachWindow:
    """The window's struct; ``params`` (the grid's LampGridParams) sets the escape test's bounds (none: every
    particle takes the exact test)."""
    win = dist_kernels.ReachWindow()
    sizes = rect[:, 1] * rect[:, 3]
    first = np.concatenate([[0], np.cumsum(sizes)[:2]])
    win.i0 = wp.vec3i(*(int(x) for x in rect[:, 0]))
    win.ni = wp.vec3i(*(int(x) for x in rect[:, 1]))
    win.j0 = wp.vec3i(*(int(x) for x in rect[:, 2]))
    win.nj = wp.vec3i(*(int(x) for x in rect[:, 3]))
    win.first = wp.vec3i(*(int(x) for x in first))
    win.n_cells = int(sizes.sum())
    bounds = np.array([[math.inf] * 3, [-math.inf] * 3] * 2)  # rows lo_u, hi_u, lo_v, hi_v: every test fails
    if params is not None:
        for a in range(3):
            i0, ni, j0, nj = (int(x) for x in rect[a])
            bounds[0, a], bounds[1, a] = _window_bounds(i0, ni, int(params.n_u[a]), float(params.h_u[a]))
            bounds[2, a], bounds[3, a] = _window_bounds(j0, nj, int(params.n_v[a]), float(params.h_v[a]))
    win.lo_u, win.hi_u, win.lo_v, win.hi_v = (wp.vec3(*(float(x) for x in row)) for row in bounds)
    return win


def _shared_cells(rects: list[np.ndarray], counts: np.ndarray) -> np.ndarray:
    """Flat cells (ascending) that two or more ranks' windows hold: the only cells whose keys need the reduction."""
    out = []
    offset = 0
    for a in range(3):
        nu, nv = (int(x) for x in counts[a])
        cover = np.zeros((nv, nu), dtype=np.int32)
        for rect in rects:
            i0, ni, j0, nj = (int(x) for x in rect[a])
            cover[j0 : j0 + nj, i0 : i0 + ni] += 1
        out.append(offset + np.flatnonzero(cover.reshape(-1) >= 2))
        offset += nu * nv
    return np.concatenate(out).astype(np.int32)


class DistributedAreaSplit(_RankSteps, AreaSplit):
    """The area criterion on a rank's share: the D-slot lists merged over ranks (D rounds of MIN), the geometry of
    every particle gathered into a table indexed by global id (an integer SUM of bit patterns), and the area kernel
    on the whole grid with that table; each rank keeps its own particles' units."""

    name = "area split, distributed"
    _flips_keys = False

    def __init__(self, frame: LampFrame, lamp_mask: int, comm: Collective, *, depth_slots, **options):
        _reduction_budget(frame.grid, depth_slots, True, options["max_bytes"])
        super().__init__(frame, lamp_mask, depth_slots=depth_slots, **options)
        self._init_ranks(comm)
        d = self.device
        #: The merged D-slot lists (global ids), and one merge round's keys.
        self.merged = wp.empty(self.keys.shape[0], dtype=wp.uint64, device=d)
        self._round = wp.empty(2 * self.grid.n_samples, dtype=wp.uint64, device=d)
        self.nbytes += self.merged.shape[0] * 8 + self._round.shape[0] * 8

    @property
    def reduction_bytes(self) -> int:
        """D rounds of 16 bytes per corner sample, and 16 bytes per particle of the whole body."""
        return 8 * self.keys.shape[0] + 16 * self.n_global

    def place(self, gids: wp.array, caller: wp.array, n_global: int) -> None:
        """As the criteria's, and the table of every particle (positions, radii, counts by global id)."""
        super().place(gids, caller, n_global)
        d = self.device
        self._table_positions = wp.zeros(n_global, dtype=wp.vec3, device=d)
        self._table_radii = wp.zeros(n_global, dtype=wp.float32, device=d)
        self._table_counts = wp.zeros(3 * n_global, dtype=wp.int64, device=d)
        table = lamp_kernels.LampParticles()
        table.positions = self._table_positions
        table.radii = self._table_radii
        table.active = self._no_int
        table.n = n_global
        self._table = table
        # int32 views of the table, for the integer SUM of its bit patterns (they alias the table's memory).
        self._table_words = (
            wp.array(ptr=self._table_positions.ptr, dtype=wp.int32, shape=(3 * n_global,), device=d),
            self._table_radii.view(wp.int32),
        )

    def launch_reduce(self) -> None:
        """Update step: the lists merged over ranks, and the table of every particle's geometry."""
        d = self.device
        lists = self._round.shape[0]
        for k in range(self.depth_slots):
            wp.launch(
                dist_kernels.dist_merge_offer,
                dim=lists,
                inputs=[self.reduced, self.merged, self.depth_slots, k, self._flip],
                outputs=[self._round],
                device=d,
            )
            self.comm.allreduce(self._round, "min")
            wp.launch(
                dist_kernels.dist_merge_take,
                dim=lists,
                inputs=[self._round, self.depth_slots, k, self._flip],
                outputs=[self.merged],
                device=d,
            )
        self._table_positions.zero_()
        self._table_radii.zero_()
        if self.n:
            wp.launch(
                dist_kernels.dist_table_fill,
                dim=self.n,
                inputs=[self._input.particles.positions, self._input.particles.radii, self.gids],
                outputs=[self._table_positions, self._table_radii],
                device=d,
            )
        # Integer sums of bit patterns: only the owning rank's entry is nonzero, and x + 0 = x exactly.
        for words in self._table_words:
            self.comm.allreduce(words, "sum")

    def launch_scatter(self) -> None:
        """Update step: the area kernel on the whole grid, every particle's units by global id; the rank keeps its
        own, in the caller's rows."""
        self._table_counts.zero_()
        self._launch_area_cells(self._table, self.merged, self._table_counts)
        if self.n:
            wp.launch(
                dist_kernels.dist_counts_gather,
                dim=self.n,
                inputs=[self._table_counts, self.gids, self.caller],
                outputs=[self.counts],
                device=self.device,
            )

    def _owner_keys(self) -> wp.array:
        return self.merged


class DistributedLamp(ShiningLamp):
    """The shining lamp on particles split across ranks: each rank passes its own particles and their global ids,
    and gets its own particles' counts and forces, bitwise equal to one device holding all particles.

    A :class:`~warp_lamp.ShiningLamp` whose pipeline has two distributed stages (``_stages``): its frame
    (:class:`AgreedFrame`) agrees the following grid's box over the ranks, and its estimator
    (:class:`DistributedFirstHit`, :class:`DistributedAreaSplit`) adds the reduction over the ranks to the one-device
    steps; the forces are the pipeline's own stage. Everything else (``add_forces``, ``apply``, ``force_factors``,
    ``forces_numpy``, ``wall_forces_numpy``, the pose arrays, the estimator's buffers and steps) is the lamp's.

    Collective calls (every rank must make them, in the same order): the constructor, :meth:`set_ids`,
    :meth:`update` (and ``apply``), :meth:`diagnostics`. ``add_forces``, ``counts_numpy`` and ``forces_numpy`` are
    local.

    Construction checks that every rank passed the same grid and options (a digest, all-reduced). :meth:`set_ids`
    (whenever the rank's particles change: migration) sorts the ids on the device, checks them and makes room for
    the particles; :meth:`update` then allocates nothing, reads nothing back and does not synchronise, so with a
    capturable collective (:class:`NCCLCollective`) it can be recorded in a CUDA graph.

    Per update each rank hands the library one all-reduce MIN of ``2 x 8`` bytes per cell that two or more ranks
    reach (criteria 0 and 1 with the reach; every cell with walls, ``follow`` or ``reach="all"``), or ``D`` rounds
    of ``2 x 8`` bytes per corner sample and one SUM of ``16`` bytes per particle of the whole body (``"area"``),
    plus 24 bytes with ``follow``: :attr:`reduction_bytes`. With the reach, the first update after :meth:`set_ids`
    agrees it (a synchronisation): run one update before capturing.
    """

    def __new__(cls, *args, **kwargs):
        # ShiningLamp.__new__ turns frames=K into a FrameAveragedLamp; here frames are refused by __init__.
        return object.__new__(cls)

    def __init__(
        self,
        grid: LampGrid,
        comm,
        *,
        criterion: int | str = 1,
        lamps="all",
        device=None,
        depth_slots: int = 3,
        resolver: str = "subpoints",
        subpoints: int = 8,
        follow: bool = False,
        split: int | str = "auto",
        order: bool | str = "auto",
        surfaces: str = "first",
        walls=None,
        frames: int = 1,
        reach: str = "auto",
        reach_margin: int = 4,
        max_bytes: int = DEFAULT_MAX_BYTES,
    ):
        """Allocate the rank's per-cell arrays and check that all ranks agree on the setup (collective).

        Args:
            grid: The lamp grids, the same on every rank (:func:`enclosing_grid` agrees one).
            comm: The communicator (:func:`as_collective`: mpi4py, CuPy NCCL, torch.distributed, or None for one
                process).
            criterion: 0, 1 or ``"area"``, as :class:`~warp_lamp.ShiningLamp`.
            lamps: "all", or names from :data:`~warp_lamp.LAMPS`.
            device: The rank's Warp device (by default the collective's, else Warp's default).
            depth_slots: Area criterion: spheres kept per corner ray and lamp, 1 to 6.
            resolver: Area criterion: ``"subpoints"`` or ``"exact"``.
            subpoints: Area criterion, sub-point resolver: points per cell edge, 1 to 16.
            follow: Move the grid with the body by whole cells; the body's box is reduced across ranks (MIN/MAX
                of 6 float32), so every rank moves the grid alike.
            split: The depth pass's work split, as :class:`~warp_lamp.ShiningLamp` (the result does not depend on
                it).
            order: Sort the depth pass's work by cell, as :class:`~warp_lamp.ShiningLamp`.
            surfaces: ``"first"`` only: ``"all"`` is refused (:data:`WETTED_REFUSAL`).
            walls: Walls that bound the fluid, as :class:`~warp_lamp.ShiningLamp` (criteria 0 and 1): each ray's
                wall is decided from the reduced key, the same on every rank, and every rank holds the walls'
                counts (``wall_forces_numpy``).
            frames: 1 only: frame averaging is refused (:data:`FRAMES_REFUSAL`).
            reach: ``"auto"``: criteria 0 and 1 without walls or ``follow`` seed, reduce and scatter only the cells
                the rank's particles can reach (see the class); ``"all"``: every cell of the three grids.
            reach_margin: Cells added on every side of each rank's footprint box when the reach is agreed, so that
                particles can move that far before it must be agreed again (:meth:`agree_reach`).
            max_bytes: Budget for the rank's per-cell arrays [bytes].
        """
        if not isinstance(grid, LampGrid):
            raise TypeError(f"grid: expected a LampGrid, got {type(grid).__name__}")
        if surfaces == "all":
            raise ValueError(WETTED_REFUSAL)
        if frames != 1:
            raise ValueError(FRAMES_REFUSAL)
        options = LampOptions.checked(
            criterion=criterion,
            lamps=lamps,
            depth_slots=depth_slots,
            resolver=resolver,
            subpoints=subpoints,
            follow=follow,
            split=split,
            order=order,
            surfaces=surfaces,
            max_bytes=max_bytes,
            walls=walls,
        )
        if reach not in ("auto", "all"):
            raise ValueError(f"reach: expected 'auto' or 'all', got {reach!r}")
        self._reach = (reach, check_integer("reach_margin", reach_margin, minimum=0))
        self.comm = as_collective(comm, device)
        digest = _fingerprint(
            grid.corner, grid.cell, grid.counts, grid.origin, grid.rotation, repr(options.criterion),
            lamp_mask(options.lamps), options.depth_slots, options.resolver, options.subpoints, options.follow,
            options.walls, self._reach,
        )  # fmt: skip
        if not np.array_equal(self.comm.allreduce_host(digest, "min"), digest):
            raise ValueError(
                "grid: the ranks passed different grids or options (criterion, lamps, depth_slots, resolver, "
                "subpoints, follow, walls, reach, reach_margin); agree them first (enclosing_grid reduces the bounds)"
            )
        self.choice = None
        self._setup(grid, options, self.comm.device)
        #: Particles over all ranks, and the span of their ids (set by :meth:`set_ids`).
        self.n_total = 0
        self.n_global = 0
        self._ids_set = False

    def _stages(self, grid: LampGrid, options: LampOptions, device) -> tuple[LampFrame, FirstHit]:
        frame = AgreedFrame(grid, device, self.comm, follow=options.follow, walls=options.walls)
        mask = lamp_mask(options.lamps)
        shared = dict(split=options.split, order=options.order, max_bytes=options.max_bytes)
        if options.criterion == "area":
            if options.gather != "front":
                raise ValueError("gather: the distributed lamp gathers the front slots only (gather='front')")
            area = dict(depth_slots=options.depth_slots, resolver=options.resolver, subpoints=options.subpoints)
            return frame, DistributedAreaSplit(frame, mask, self.comm, **area, **shared)
        reach, margin = self._reach
        return frame, DistributedFirstHit(
            frame, mask, self.comm, criterion=options.criterion, reach=reach, reach_margin=margin, **shared
        )

    def __repr__(self) -> str:
        return (
            f"DistributedLamp({self.estimator.name}, rank {self.comm.rank} of {self.comm.size} over "
            f"{self.comm.name}, {self.grid!r}, device={self.device})"
        )

    # --- particles ---------------------------------------------------------------------------------------------

    def set_ids(self, global_ids) -> None:
        """Name the rank's particles (collective): row i of the positions that :meth:`update` gets is the particle
        with global id ``global_ids[i]``. Call it again whenever the rank's particles change (migration).

        Sorts the ids on the device (a radix sort), checks them (a synchronisation), and makes room for the
        particles, so that :meth:`update` allocates nothing.

        Args:
            global_ids: This rank's global ids, shape (N,): integers in [0, 2^31 - 2], unique over all ranks (a
                duplicate within a rank is refused; across ranks only a total over the largest id is caught);
                numpy, or a warp int32 array on the lamp's device.

        Raises:
            ValueError: a bad id (naming the first bad index), on every rank when any rank has one.
        """
        d = self.device
        error = None
        try:
            ids = _check_ids(global_ids)
            if isinstance(ids, wp.array) and ids.device != d:
                raise ValueError(f"global_ids: on device {ids.device}, the lamp is on {d}")
        except (TypeError, ValueError) as e:
            error = e
        _agree(self.comm, error, "global_ids")
        n = ids.shape[0]
        if not isinstance(ids, wp.array):
            ids = wp.array(ids, dtype=wp.int32, device=d)
        sort_keys = wp.empty(2 * max(n, 1), dtype=wp.int32, device=d)
        sort_values = wp.empty(2 * max(n, 1), dtype=wp.int32, device=d)
        stats = wp.array([0, 0, 0, -1], dtype=wp.int32, device=d)
        if n:
            wp.launch(dist_kernels.dist_iota, dim=n, inputs=[ids, n], outputs=[sort_keys, sort_values], device=d)
            wp.utils.radix_sort_pairs(sort_keys, sort_values, n)
            wp.launch(
                dist_kernels.dist_check_ids,
                dim=n,
                inputs=[sort_keys, sort_values],
                outputs=[stats],
                device=d,
            )
        negative, repeated, moved, largest = (int(x) for x in stats.numpy())
        error = None
        if negative or repeated or largest > _MAX_ID:
            host = ids.numpy()
            if negative or largest > _MAX_ID:
                k = int(np.flatnonzero((host < 0) | (host > _MAX_ID))[0])
                error = ValueError(f"global_ids: must be in [0, {_MAX_ID}]; index {k} is {host[k]}")
            else:
                _, first = np.unique(host, return_index=True)
                k = int(np.setdiff1d(np.arange(n), first)[0])
                error = ValueError(f"global_ids: index {k} repeats id {host[k]} of an earlier particle")
        _agree(self.comm, error, "global_ids")
        total = int(self.comm.allreduce_host(np.array([n], dtype=np.int64), "sum")[0])
        top = int(self.comm.allreduce_host(np.array([largest], dtype=np.int64), "max")[0])
        n_global = top + 1
        if total > n_global:
            raise ValueError(
                f"global_ids: the ranks hold {total} particles but the largest id is {top}: some id is on two ranks"
            )
        no_int = self.estimator._no_int
        gids = wp.clone(sort_keys[:n]) if n else no_int
        self.estimator.place(gids, wp.clone(sort_values[:n]) if moved else no_int, n_global)
        self.n = n
        self.n_global = n_global
        self.n_total = total
        self._ids_set = True
        self._input = None

    def reserve(self, n: int) -> None:
        """:meth:`set_ids` makes room for the rank's particles; ``n`` must be their number."""
        if check_integer("n", n) != self.n:
            raise ValueError(f"n: set_ids named {self.n} particles; call set_ids with the new particles' ids")

    @property
    def reduction_bytes(self) -> int:
        """Bytes this rank hands to the collective library per update (the payload of its all-reduces; a ring
        all-reduce sends about 2 (P - 1) / P times that per rank)."""
        return self.estimator.reduction_bytes + self.frame.reduction_bytes

    # --- the update --------------------------------------------------------------------------------------------

    def update(self, positions: wp.array, radii: wp.array, active: wp.array | None = None, *, in_frame=False) -> None:
        """Recompute the owners of every cell over all ranks, and this rank's particles' counts (collective).

        Args:
            positions: The rank's particle centres [m], warp array of vec3 (float32), shape (N,), rows as the ids
                given to :meth:`set_ids`, world coordinates (or frame coordinates with ``in_frame``).
            radii: Particle radii [m], warp array of float32, shape (N,).
            active: Optional warp array of int32, shape (N,): 0 makes a particle invisible.
            in_frame: ``positions`` are already in frame coordinates (``grid.to_frame``).
        """
        if not self._ids_set:
            raise RuntimeError("update: no particles named yet; call DistributedLamp.set_ids(global_ids) first")
        inp = lamp_input(positions, radii, active, self.device, self._no_active, in_frame=in_frame)
        if inp.n != self.n:
            raise ValueError(
                f"positions: {inp.n} particles, but set_ids named {self.n}; call set_ids with the new particles' ids"
            )
        self._update(inp)

    def agree_reach(self) -> None:
        """Agree each rank's reach again at its last update's positions (collective; outside a capture): after
        particles moved more than ``reach_margin`` cells, or the frame's pose changed (:meth:`reach_escapes`). The
        next update runs cold (the keys are emptied); its result is the same."""
        if self._input is None:
            raise RuntimeError("agree_reach: no update yet")
        if getattr(self.estimator, "windowed", False):
            self.estimator.agree_reach()

    def reach_escapes(self) -> int:
        """Particle footprints, summed over ranks and updates, that left their rank's agreed reach since it was
        agreed (collective; synchronises): 0 means every update since was bitwise equal to one device; otherwise
        call :meth:`agree_reach` and update again."""
        return self.estimator.reach_escapes() if getattr(self.estimator, "windowed", False) else 0

    def reduced_keys_numpy(self) -> np.ndarray:
        """The reduced keys of the last update (global ids), as ``ShiningLamp.keys``: criteria 0 and 1, two per
        cell; area criterion, the merged D-slot lists (collective with a reach: the whole grid is reduced)."""
        return self.estimator._owner_keys().numpy().copy()

    def diagnostics(self, positions=None, pressure=None, *, moment_origin=None) -> DistributedDiagnostics:
        """Owners, depths and lit cells of the whole grid, the rank's counts and surface flags, and the skip
        counters summed over ranks (collective: every rank must call it); arguments as
        :meth:`ShiningLamp.diagnostics` (the resultants are of the rank's own particles)."""
        if self._input is None:
            raise RuntimeError("diagnostics: no update yet")
        out = super().diagnostics(positions, pressure, moment_origin=moment_origin)
        return DistributedDiagnostics(out, self.comm.size, self.n_total, self.reduction_bytes)


# --- the agreed grid ------------------------------------------------------------------------------------------------


def enclosing_grid(
    comm,
    centers,
    radii,
    global_ids,
    *,
    cells_per_diameter: float = 4,
    margin: float | None = None,
    rotation=None,
    probe_radius: float = 0.0,
    mean_diameter: float | None = None,
    device=None,
    max_bytes: int = DEFAULT_MAX_BYTES,
) -> LampGrid:
    """:meth:`LampGrid.enclosing` of all ranks' particles, the same grid on every rank (collective).

    "Agreed" means bitwise equal to ``LampGrid.enclosing`` on all particles in global-id order: the box is the MIN
    of (c - r) and the MAX of (c + r) over ranks (exact in any order), and the cell is the mean diameter over
    cells_per_diameter, where the mean is NumPy's mean of all radii in global-id order, which every rank computes
    from an all-gather of (id, radius) pairs: 12 bytes per particle of the whole body, once. NumPy's pairwise sum
    depends on the order of its terms, so no per-rank partial sums would reproduce it bitwise. At scale, pass
    ``mean_diameter`` (e.g. from the material's size distribution) to skip the gather; the grid then equals
    ``LampGrid.enclosing`` only if that mean is bitwise the same.

    Args:
        comm: The communicator (:func:`as_collective`).
        centers: The rank's particle centres [m], world coordinates, shape (N, 3) (N may be 0 on some ranks).
        radii: The rank's radii [m], shape (N,).
        global_ids: The rank's global ids, shape (N,).
        cells_per_diameter: Cells per mean particle diameter.
        margin: Free space around the box [m] (default: one mean diameter plus ``probe_radius``).
        rotation: Orientation of the lamp frame.
        probe_radius: Wetted-surface probe radius [m], added to the default margin.
        mean_diameter: The body's mean particle diameter [m], if known: no all-gather.
        device: The rank's Warp device, for collectives that reduce device memory.
        max_bytes: Budget for the per-cell arrays [bytes].
    """
    coll = as_collective(comm, device)
    error = None
    try:
        c, r = check_particles(centers, radii)
        ids = _check_ids(global_ids, len(r))
        ids = ids.numpy() if isinstance(ids, wp.array) else ids
        cells_per_diameter = check_positive("cells_per_diameter", cells_per_diameter)
        rot = lamp_rotation(rotation)
        probe_radius = check_positive("probe_radius", probe_radius, allow_zero=True)
        if margin is not None:
            margin = check_positive("margin", margin, allow_zero=True)
        if mean_diameter is not None:
            mean_diameter = check_positive("mean_diameter", mean_diameter)
    except (TypeError, ValueError) as e:
        error = e
    _agree(coll, error, "enclosing_grid")
    n = len(r)
    if n:
        frame = c @ rot  # frame coordinates: R^T x for each row x, as LampGrid.enclosing
        lo_local = np.min(frame - r[:, None], axis=0)
        hi_local = np.max(frame + r[:, None], axis=0)
    else:
        lo_local, hi_local = np.full(3, np.inf), np.full(3, -np.inf)
    lo_core = coll.allreduce_host(lo_local, "min")
    hi_core = coll.allreduce_host(hi_local, "max")
    total = int(coll.allreduce_host(np.array([n], dtype=np.int64), "sum")[0])
    if total == 0:
        raise ValueError("centers: need at least one particle over all ranks to fit a grid")
    if mean_diameter is None:
        all_ids = np.concatenate(coll.allgather_host(ids.astype(np.int64)))
        all_r = np.concatenate(coll.allgather_host(r))
        diameter = 2.0 * float(np.mean(all_r[np.argsort(all_ids, kind="stable")]))
    else:
        diameter = mean_diameter
    margin = diameter + probe_radius if margin is None else margin
    # LampGrid.enclosing's arithmetic from here on, on the reduced box.
    lo = lo_core - margin
    hi = hi_core + margin
    h = diameter / cells_per_diameter
    with np.errstate(over="ignore", divide="ignore"):
        counts = np.floor((hi - lo) / h) + 1.0
    lower = lo - 0.3819660112501051 * (counts * h - (hi - lo))
    # Half a cell short, as LampGrid.enclosing (the box form's ceil then gives the same counts in any unit).
    return LampGrid(lower, lower + (counts - 0.5) * h, h, rotation=rot, max_bytes=max_bytes)


# --- porosity -----------------------------------------------------------------------------------------------------


def _fixed_scale(h) -> float:
    return 2.0**FIXED_POINT_BITS / float(np.prod(h))


def porosity_fixed_units(local, radii, h, shape, method: str, device) -> tuple[wp.array, wp.array]:
    """The sum methods' solid volume per cell as int64 units of 2^-40 of a cell's volume (one rank's spheres).

    Each sphere-cell volume is computed as ``porosity``'s kernels do, then rounded to a whole number of units and
    added as an integer, so that the sum is the same in every order and every split of the spheres.

    Args:
        local: Sphere centres relative to the box's lower corner [m], shape (N, 3), float64.
        radii: Radii [m], shape (N,), float64.
        h: Cell edges [m], 3 values.
        shape: Cells along x, y, z.
        method: ``"centroid"``, ``"polyhedron"`` or ``"exact"``.
        device: Warp device.

    Returns:
        (units, overflow): int64 units per cell, shape ``shape``; and one int32 counting adds that would have
        passed 2^63 (then left out).
    """
    device = wp.get_device(device)
    units = wp.zeros(shape, dtype=wp.int64, device=device)
    overflow = wp.zeros(1, dtype=wp.int32, device=device)
    if len(radii):
        code = {
            "centroid": dist_kernels.FIXED_CENTROID,
            "polyhedron": dist_kernels.FIXED_CUBE,
            "exact": dist_kernels.FIXED_EXACT,
        }[method]
        wp.launch(
            dist_kernels.porosity_fixed,
            dim=len(radii),
            inputs=[
                wp.array(local, dtype=wp.vec3d, device=device),
                wp.array(radii, dtype=wp.float64, device=device),
                wp.vec3d(*h),
                wp.vec3i(*shape),
                code,
                _fixed_scale(h),
            ],
            outputs=[units, overflow],
            device=device,
        )
    return units, overflow


def porosity_distributed(
    comm,
    centers,
    radii,
    lower,
    upper,
    shape,
    *,
    method: str = "voxel",
    subdivisions=8,
    device=None,
    midpoint_algorithm: int | None = None,
    max_bytes: int = DEFAULT_MAX_BYTES,
) -> np.ndarray:
    """:func:`~warp_lamp.porosity` of all ranks' spheres, returned on every rank (collective).

    Union methods (``"voxel"``, ``"midpoint"``): each rank marks its spheres on the sub-cell bitmap, a bitwise-OR
    all-reduce makes the union (``porosity_bitmap_bytes`` bytes per rank; NCCL, which has no OR, gathers ``size``
    times that), and every rank counts it: **bitwise equal** to ``porosity`` on all spheres, for any split. A halo
    of particles near each rank's region would send fewer bytes for a spatial split, but needs the split to be
    spatial; the bitmap works for any.

    Sum methods (``"centroid"``, ``"polyhedron"``, ``"exact"``): each sphere-cell volume is rounded to int64 units
    of 2^-40 of a cell's volume and summed as integers (:func:`porosity_fixed_units`), then all-reduced by SUM
    (8 bytes per cell): **bitwise equal for any split and any number of ranks** (an integer sum does not depend on
    its order), and 1 - units 2^-40. It is not bitwise equal to ``porosity``, whose float64 atomic sums depend on
    the order of the adds (on a GPU, from run to run): the two differ by at most 2^-41 per sphere-cell volume in a
    cell, plus ``porosity``'s own rounding (a few 1e-16 per add).

    The midpoint method's choice of algorithm (the paper's discriminant) uses the sum of the integer sub-cell radii
    cubed, exact over ranks; ``porosity`` sums 4/3 pi r^3 in float64, so the two could choose differently only where
    the discriminant's sides agree to about 1e-15 (pass ``midpoint_algorithm`` to fix it).

    Args:
        comm: The communicator (:func:`as_collective`).
        centers: The rank's sphere centres [m], shape (N, 3) (N may be 0).
        radii: The rank's radii [m], shape (N,).
        lower: Lower corner of the box [m], 3 values, the same on every rank.
        upper: Upper corner [m].
        shape: Cells along x, y, z.
        method: One of :data:`~warp_lamp.POROSITY_METHODS`.
        subdivisions: Sub-cells per cell edge (union methods).
        device: The rank's Warp device.
        midpoint_algorithm: Force Algorithm 1 or 2 of the midpoint method.
        max_bytes: Budget for the rank's device memory [bytes].

    Returns:
        Porosity, shape ``shape``, float64, on every rank.
    """
    coll = as_collective(comm, device)
    device = coll.device
    error = None
    try:
        c, r = check_particles(centers, radii)
        gathered = coll.name not in ("mpi", "local")  # the OR by gathering holds every rank's bitmap
        lo, hi, shape, s, h, sub = porosity_plan(
            lower, upper, shape, method, subdivisions, midpoint_algorithm, len(r), max_bytes,
            bitmaps=1 + coll.size if gathered else 1,
        )  # fmt: skip
        digest = _fingerprint(lo, hi, np.asarray(shape), np.asarray(s), method, midpoint_algorithm)
        if not np.array_equal(coll.allreduce_host(digest, "min"), digest):
            raise ValueError("lower: the ranks passed different boxes, shapes, methods or subdivisions")
    except (TypeError, ValueError) as e:
        error = e
    _agree(coll, error, "porosity_distributed")
    local = c - lo
    if POROSITY_METHODS[method] == "sum":
        units, overflow = porosity_fixed_units(local, r, h, shape, method, device)
        flat = units.flatten()
        coll.allreduce(flat, "sum")
        over = int(coll.allreduce_host(overflow.numpy(), "sum")[0])
        if over:
            raise ValueError(
                f"radii: {over} sphere-cell volumes overflowed the int64 fixed-point sums (a cell holding over 2^23 "
                "cell volumes of sphere); use larger cells"
            )
        return 1.0 - flat.numpy().reshape(shape).astype(np.float64) * 2.0**-FIXED_POINT_BITS
    hs = h / np.asarray(s)
    algorithm = midpoint_algorithm
    if method == "midpoint" and algorithm is None:
        algorithm = _agreed_midpoint_algorithm(coll, r, hs, sub)
    error = None
    try:
        bits = porosity_mark_union(method, local, r, hs, sub, device, algorithm=algorithm)
    except ValueError as e:
        error = e
    _agree(coll, error, "porosity_distributed")
    coll.allreduce(bits, "bor")
    counts = wp.zeros(shape, dtype=wp.int64, device=device)
    count_bitmap(bits, shape, s, counts)
    return 1.0 - counts.numpy().astype(np.float64) / float(s[0] * s[1] * s[2])


def _agreed_midpoint_algorithm(coll: Collective, radii, hs, sub) -> int:
    """The paper's discriminant over all ranks: 4/3 pi sum r^3 > 8 K R^3 with r the integer sub-cell radii (as
    ``porosity``'s ``_midpoint_spheres``), their cubes summed exactly as integers."""
    h = float(np.min(hs))
    rad = np.maximum(np.rint(np.asarray(radii, dtype=np.float64) / h), 1.0)
    values, repeats = np.unique(rad, return_counts=True)
    cubes = sum(int(v) ** 3 * int(m) for v, m in zip(values, repeats, strict=True))
    # Exact integer sum across ranks: int64 words of the Python integer, added as int64 base-2^31 limbs.
    limbs = np.array([(cubes >> (31 * k)) & ((1 << 31) - 1) for k in range(4)], dtype=np.int64)
    total_limbs = coll.allreduce_host(limbs, "sum")
    total = sum(int(x) << (31 * k) for k, x in enumerate(total_limbs))
    rmax = float(coll.allreduce_host(np.array([rad.max() if len(rad) else 0.0]), "max")[0])
    if total == 0:
        return 1
    k = float(sub[0] * sub[1] * sub[2])
    return 2 if 4.0 / 3.0 * math.pi * float(total) > 8.0 * k * rmax**3 else 1
