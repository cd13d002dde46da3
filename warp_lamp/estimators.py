"""The lamp's estimators: which particle each ray's pressure goes to (the pipeline's third stage).

Each implements :class:`~warp_lamp.pipeline.Estimator` (reserve, update on checked particles, counts in units,
diagnostics) and is picked by :class:`~warp_lamp.ShiningLamp` from its arguments:

- :class:`FirstHit`: criteria 0 and 1, the memo's lamp: the first sphere each cell's ray meets takes the cell.
- :class:`AreaSplit`: ``criterion="area"``: each cell's area is split among the spheres visible in it.
- :class:`WettedCrossings`: ``surfaces="all"``: every crossing of the fluid's boundary along a ray is loaded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_lamp.grid import LampGrid
from warp_lamp.kernels import area as area_kernels
from warp_lamp.kernels import lamp as lamp_kernels
from warp_lamp.kernels.footprint import RAY_CORNER
from warp_lamp.pipeline import Estimator, LampFrame, LampInput
from warp_lamp.validate import LAMPS, check_budget
from warp_lamp.wetted import WettedSurface

__all__ = ["AREA_GATHERS", "AreaSplit", "FirstHit", "LampDiagnostics", "WettedCrossings", "lamp_owner_maps"]

_EMPTY = np.uint64(0xFFFFFFFFFFFFFFFF)

#: The area criterion's fixed-point units per cell for the exact resolver (sub-points: S^2, one per point).
AREA_EXACT_UNIT = 4096
#: Resolvers of the area criterion.
AREA_RESOLVERS = ("subpoints", "exact")
#: Gathers of the area criterion: the front slots of the cell's corner rays, or ``"deep"`` (both lamps' slots after
#: the hidden-sphere rounds).
AREA_GATHERS = ("front", "deep")
#: Threads the depth pass aims for when it splits a small body's footprints: about what an H100 holds resident
#: (132 SMs x 2048).
_TARGET_THREADS = 1 << 18
#: Most threads per (sphere, axis): a footprint at 16 cells per diameter spans about 17 rows.
_MAX_SPLIT = 16
#: Particles from which the automatic choices treat a body as large.
_LARGE_BODY = 1 << 16
#: Diagnostics slots: the lamp's counters, then the area kernel's two.
_N_DIAG = lamp_kernels.N_DIAG + 2


def _decode_depth(keys: np.ndarray) -> np.ndarray:
    b = (keys >> np.uint64(32)).astype(np.uint32)
    bits = np.where(b & np.uint32(0x80000000), b ^ np.uint32(0x80000000), ~b)
    return bits.view(np.float32).astype(np.float64)


def lamp_owner_maps(keys: np.ndarray, grid: LampGrid, *, corners: bool = False) -> tuple[dict, dict]:
    """Decode a lamp key array (two uint64 keys per cell, as ``ShiningLamp.keys``) into per-lamp maps.

    Args:
        keys: uint64 keys, two per cell (or per corner sample).
        grid: The lamp grids.
        corners: The keys belong to the (n_u + 1) x (n_v + 1) corner samples (the area criterion's slot 0).

    Returns:
        ``(owners, depths)``: per lamp name, the owner of each cell ``[i, j]`` (-1 where unlit), shape (n_u, n_v),
        and the coordinate along the lamp's axis where its ray meets its owner, in the grid's frame [m] (NaN where
        unlit).
    """
    owners, depths = {}, {}
    counts = grid.counts + (1 if corners else 0)
    first = np.concatenate([[0], np.cumsum(counts[:, 0] * counts[:, 1])[:2]])
    for a in range(3):
        nu, nv = (int(x) for x in counts[a])
        for side in range(2):
            name = LAMPS[2 * a + side]
            k = keys[2 * first[a] + side : 2 * (first[a] + nu * nv) : 2]
            hit = k != _EMPTY
            own = np.where(hit, (k & np.uint64(0xFFFFFFFF)).astype(np.int64), -1)
            dep = _decode_depth(k) * (1.0 if side == 0 else -1.0) + grid.origin[a]
            owners[name] = own.reshape(nv, nu).T
            depths[name] = np.where(hit, dep, np.nan).reshape(nv, nu).T
    return owners, depths


@dataclass
class LampDiagnostics:
    """What the last update found; built on demand from device arrays, outside the hot path.

    Attributes:
        counts: Signed counts per particle and axis, shape (N, 3), int64: +1 per low-lamp cell and -1 per high-lamp
            cell for criteria 0 and 1; fixed-point units of ``unit`` per cell for the area criterion.
        unit: Counts per whole cell (1, or the area criterion's units).
        surface: Whether each particle is lit by any lamp that is on (for the area criterion: holds the first
            slot of some corner sample).
        owners: Per lamp name, the owner of each cell ``[i, j]`` (-1 where unlit), shape (n_u, n_v) (for the area
            criterion: of each corner sample's first slot, shape (n_u + 1, n_v + 1)).
        depths: Per lamp name, the coordinate along the lamp's axis where its ray meets its owner, in the grid's
            frame [m] (NaN where unlit), shaped as ``owners``.
        lit: Per lamp name, the number of lit cells (or corner samples).
        invalid: Particles skipped as invalid (non-finite position or radius, radius <= 0).
        outside: Particles whose projected disk pokes outside at least one grid.
        area_overflow: Area criterion: cells whose seeds were more than the kernel keeps (the front ones are kept).
        area_one_sided: Area criterion: cells where one lamp had units to give and the other nothing (neither pays).
        wall_counts: Signed counts per wall and axis, shape (W, 3), int64, as ``counts`` (the rays each wall
            stopped before any sphere).
        choice: What ``tolerance=`` chose (:class:`~warp_lamp.tolerance.LampChoice`), or None.
        wall_owners: With walls, per lamp name, the wall that took each cell (-1: none), shaped as ``owners``
            (which then hold only the cells a particle took).
        force: Resultant force in world coordinates [N], shape (3,), when a pressure was given.
        moment: Resultant moment about ``moment_origin`` [N m], shape (3,), when positions and pressure were given.
        moment_origin: Point the moment is taken about [m] (the mean lit particle centre by default).
        wall_forces: Force on each wall in world coordinates [N], shape (W, 3), when a pressure was given: the
            walls' reaction, which with the body's forces sums to P times the lamp window facing the fluid.
    """

    counts: np.ndarray
    unit: int
    surface: np.ndarray
    owners: dict
    depths: dict
    lit: dict
    invalid: int
    outside: int
    area_overflow: int = 0
    area_one_sided: int = 0
    wall_counts: np.ndarray | None = None
    wall_owners: dict | None = None
    choice: object = None
    force: np.ndarray | None = None
    moment: np.ndarray | None = None
    moment_origin: np.ndarray | None = None
    wall_forces: np.ndarray | None = None


def _auto_split(n: int, device) -> int:
    """The depth pass's split for n particles: 0 (one thread per sphere) on the CPU, where one thread runs the
    launch anyway; on a GPU at least one thread per (sphere, axis), and more until the launch holds about what the
    GPU holds resident."""
    if not device.is_cuda or n == 0:
        return 0
    return int(min(_MAX_SPLIT, max(1, -(-_TARGET_THREADS // (3 * n)))))


def _auto_order(n: int, device) -> bool:
    """Sorted work on a GPU for bodies large enough that warps of unrelated particles thrash the L2 cache."""
    return device.is_cuda and n >= _LARGE_BODY


class FirstHit(Estimator):
    """Criteria 0 and 1 (the memo's ``sl_ic``): each cell's two lamps light the first sphere their ray meets.

    Each cell keeps two packed (depth, particle) keys resolved by ``atomic_min`` (``kernels/keys.py``); the update
    is three steps: **seed** (clear the counts; re-evaluate each ray's last owner at the new positions, so that a
    slowly moving body finds almost every cell decided), **depth** (every sphere offers its depth to every ray it
    meets) and **scatter** (each lit cell adds +1 to its low owner's count and -1 to its high owner's).

    The depth pass's work can be shared (``split`` threads per (sphere, axis)) and sorted by cell (``order``); the
    result never depends on either.
    """

    name = "first hit"
    steps = ("seed", "depth", "scatter")
    #: Where the rays sit: ``None`` for the criterion's own (cell centres or rectangles).
    _ray_kind: int | None = None

    def __init__(self, frame: LampFrame, lamp_mask: int, *, criterion: int, split, order, max_bytes, depth_slots=1):
        super().__init__(frame, lamp_mask)
        self.criterion = criterion
        self.depth_slots = depth_slots
        self._ray = criterion if self._ray_kind is None else self._ray_kind
        self._corners = self._ray_kind is not None
        samples = self.grid.n_samples if self._corners else self.grid.n_cells
        self.nbytes = 2 * depth_slots * samples * 8
        check_budget(
            self.nbytes,
            max_bytes,
            f"depth_slots: {depth_slots} keys per lamp on {samples:,} rays need {self.nbytes:,} bytes",
            "raise max_bytes, lower depth_slots or use larger cells",
        )
        d = self.device
        self.keys = wp.full(2 * depth_slots * samples, value=_EMPTY, dtype=wp.uint64, device=d)
        self.diag = wp.zeros(_N_DIAG, dtype=wp.int32, device=d)
        # The depth pass's particle flags (the area criterion's hidden spheres; empty: none) and the counters it
        # adds to (a later pass over the same spheres adds to a scratch copy instead).
        self._no_flags = wp.empty(0, dtype=wp.int32, device=d)
        self._hidden_flags = self._no_flags
        self._depth_diag = self.diag
        self._split = split
        self.split = 0
        self._order = order
        self.order = wp.empty(0, dtype=wp.int32, device=d)
        self._no_order = self.order
        self._order_keys = wp.empty(0, dtype=wp.int32, device=d)
        self._order_ids = wp.empty(0, dtype=wp.int32, device=d)
        self._ordered_n = -1
        #: Signed counts per wall and axis (3 per wall), as the particles'.
        self.wall_counts = wp.zeros(3 * frame.n_walls, dtype=wp.int64, device=d)
        # With walls, a lamp's decision reads both ends of the body on its ray: keep both keys of a lit axis.
        self._depth_mask = self.lamp_mask
        if frame.n_walls:
            self._depth_mask = sum(3 << (2 * a) for a in range(3) if (self.lamp_mask >> (2 * a)) & 3)

    def reserve(self, n: int) -> None:
        """Counts for ``n`` particles; fixes the depth pass's ``split`` (and its sort buffers) for them."""
        if not self._check_room(n, self.counts.shape[0] // 3):
            return
        d = self.device
        self.counts = wp.zeros(3 * n, dtype=wp.int64, device=d)
        self.split = _auto_split(n, d) if self._split == "auto" else int(self._split)
        if self.depth_slots > 1:
            self.split = max(self.split, 1)  # the D-slot depth pass is compiled for shared work only
        sort = _auto_order(n, d) if self._order == "auto" else self._order
        if sort and self.split > 0:
            self.order = wp.empty(3 * n, dtype=wp.int32, device=d)
            self._order_keys = wp.empty(2 * n, dtype=wp.int32, device=d)
            self._order_ids = wp.empty(2 * n, dtype=wp.int32, device=d)
            self._ordered_n = -1

    def update(self, inp: LampInput) -> None:
        """Seed, depth pass, scatter: the :attr:`steps` in order (a subclass may add its own between them, as the
        distributed lamp's reduction across processes, ``distributed.py``)."""
        self._input = inp
        self.n = inp.n
        if self.order.shape[0] and self._ordered_n != inp.n and not self.device.is_capturing:
            self.reorder()
        for step in self.steps:
            getattr(self, f"launch_{step}")()

    def forget(self) -> None:
        """Empty every key, so that the next update runs cold (benchmarks; the result is the same)."""
        wp.launch(lamp_kernels.lamp_forget, dim=self.keys.shape[0], outputs=[self.keys], device=self.device)

    def reorder(self) -> None:
        """Sort the depth pass's work on each axis by the cell under each particle, at the last update's positions
        (a device radix sort; not inside a capture). Only with a split and ``order`` on."""
        if not self.order.shape[0] or self._input is None:
            return
        inp, n = self._input, self.n
        for a in range(3):
            wp.launch(
                lamp_kernels.lamp_order_keys,
                dim=n,
                inputs=[self._rays(), inp.particles, a],
                outputs=[self._order_keys, self._order_ids],
                device=self.device,
            )
            wp.utils.radix_sort_pairs(self._order_keys, self._order_ids, n)
            wp.copy(self.order, self._order_ids, dest_offset=a * n, src_offset=0, count=n)
        self._ordered_n = n

    def _rays(self):
        return self.frame.rays(self._input.in_frame, corners=self._corners)

    def _cells(self):
        return self.frame.rays(self._input.in_frame)

    def launch_seed(self) -> None:
        """Step 1: clear the counts, and re-evaluate each ray's last owners at the current positions."""
        rays = self._rays()
        kernel, inputs = lamp_kernels.lamp_seed, [rays, self._input.particles, self._ray]
        if self.depth_slots > 1:
            kernel, inputs = lamp_kernels.lamp_seed_slots, [*inputs, self.depth_slots]
        wp.launch(
            kernel,
            dim=max(rays.n_cells, self.n, _N_DIAG),
            inputs=inputs,
            outputs=[self.keys, self.counts, self.diag],
            device=self.device,
        )

    def launch_depth(self) -> None:
        """Step 2: every sphere offers its depth to every ray it meets."""
        if self.n == 0:
            return
        if self.depth_slots > 1:
            kernel = lamp_kernels.lamp_depth_slots
        else:
            kernel = lamp_kernels.lamp_depth if self.split else lamp_kernels.lamp_depth_sphere
        # An order sorted for another particle count would skip particles: run unordered until the next reorder.
        order = self.order if self._ordered_n == self.n else self._no_order
        wp.launch(
            kernel,
            dim=self.n * (3 * self.split if self.split else 1),
            inputs=[
                self._rays(),
                self._input.particles,
                self._ray,
                self._depth_mask,
                self.split,
                self.depth_slots,
                order,
                self._hidden_flags,
            ],
            outputs=[self.keys, self._depth_diag],
            device=self.device,
            block_dim=lamp_kernels.DEPTH_BLOCK_DIM,
        )

    def launch_scatter(self) -> None:
        """Step 3: each lit cell adds its +1 / -1 to its owners' counts (or to a wall's that stops its ray)."""
        if self.frame.n_walls:
            self.launch_contact()
            self.wall_counts.zero_()
            wp.launch(
                lamp_kernels.lamp_scatter_walls,
                dim=self.grid.n_cells,
                inputs=[self._cells(), self.keys, self.frame.walls_view(self._input.in_frame), self.lamp_mask],
                outputs=[self.counts, self.wall_counts],
                device=self.device,
            )
            return
        if self.n == 0:
            return
        wp.launch(
            lamp_kernels.lamp_scatter,
            dim=self.grid.n_cells,
            inputs=[self._cells(), self.keys],
            outputs=[self.counts],
            device=self.device,
        )

    def launch_contact(self) -> None:
        """Before a scatter with walls: each wall's smallest gap to the particles (whether the body rests on it)."""
        if self.n:
            wp.launch(
                lamp_kernels.walls_contact,
                dim=self.n,
                inputs=[self._cells(), self._input.particles, self.frame.walls_view(self._input.in_frame)],
                outputs=[self.frame.wall_gap],
                device=self.device,
            )

    def diagnostics(self) -> LampDiagnostics:
        """Counts, surface flags, owner and depth maps, lit cells and skip counters (host copies)."""
        diag = self.diag.numpy().copy()
        counts = self.counts.numpy()[: 3 * self.n].reshape(self.n, 3).copy()
        keys = self._owner_keys().numpy().copy()
        if self._corners:
            keys = keys.reshape(-1, self.depth_slots)[:, 0]
        owners, depths = lamp_owner_maps(keys, self.grid, corners=self._corners)
        wall_owners = self._walled_maps(owners, depths) if self.frame.n_walls and self._input is not None else None
        lit = {name: int((own >= 0).sum()) for name, own in owners.items()}
        surface = self._surface(owners)
        return LampDiagnostics(
            counts,
            self.unit,
            surface,
            owners,
            depths,
            lit,
            int(diag[lamp_kernels.DIAG_INVALID]),
            int(diag[lamp_kernels.DIAG_OUTSIDE]),
            int(diag[2]),
            int(diag[3]),
            self.wall_counts.numpy().reshape(-1, 3).copy(),
            wall_owners,
        )

    def _owner_keys(self) -> wp.array:
        """The keys the owner maps decode: the lamp's own (a hook: the distributed lamp's are reduced over ranks)."""
        return self.keys

    def _surface(self, owners: dict) -> np.ndarray:
        """Whether each particle owns a cell of the owner maps (a hook: the distributed lamp's owners are global
        ids, its particles held in the caller's rows)."""
        surface = np.zeros(self.n, dtype=bool)
        for own in owners.values():
            surface[own[own >= 0]] = True
        return surface

    def _walled_maps(self, owners: dict, depths: dict) -> dict:
        """Apply the walls to the owner and depth maps (in place), by the scatter's own decision; the walls' maps."""
        walled = wp.zeros(2 * self.grid.n_cells, dtype=wp.int32, device=self.device)
        recoils = wp.zeros(2 * self.grid.n_cells, dtype=wp.int32, device=self.device)
        wp.launch(
            lamp_kernels.lamp_walled_owners,
            dim=self.grid.n_cells,
            inputs=[self._cells(), self._owner_keys(), self.frame.walls_view(self._input.in_frame), self.lamp_mask],
            outputs=[walled, recoils],
            device=self.device,
        )
        who = walled.numpy()
        out = {}
        for a in range(3):
            nu, nv = (int(x) for x in self.grid.counts[a])
            first = int(self.grid.offsets[a])
            for side in range(2):
                name = LAMPS[2 * a + side]
                w = who[2 * first + side : 2 * (first + nu * nv) : 2].reshape(nv, nu).T
                owners[name] = np.where(w >= 0, owners[name], -1)
                depths[name] = np.where(w >= 0, depths[name], np.nan)
                out[name] = np.where(w <= -2, -2 - w, -1)
        return out


class AreaSplit(FirstHit):
    """``criterion="area"``: each cell's area is split among the spheres visible in it.

    The depth pass keeps, at every cell corner, the ``depth_slots`` nearest spheres per lamp; the scatter step is
    one thread per cell that gathers them, resolves each one's visible share of the cell (on S x S sub-points, or
    exactly) and pays both lamps the same integer number of units (:attr:`unit` per cell), so the forces still
    balance exactly.
    """

    name = "area split"
    _ray_kind = int(RAY_CORNER)

    def __init__(self, frame: LampFrame, lamp_mask: int, *, depth_slots, resolver, subpoints, split, order, max_bytes):
        super().__init__(
            frame, lamp_mask, criterion="area", split=split, order=order, max_bytes=max_bytes, depth_slots=depth_slots
        )
        self.resolver = resolver
        self.subpoints = subpoints
        self.unit = AREA_EXACT_UNIT if resolver == "exact" else subpoints**2
        #: Threads per block of the cell pass: a latency-bound pass of few cells spreads over more SMs in
        #: smaller blocks.
        self.block_dim = 256
        self._work = None
        self._hidden_rounds = 0
        self._hidden_buf = None
        #: Each lamp gathers its cell's seeds from both lamps' corner keys (off by default): the far side's D
        #: spheres along a corner ray are candidates too, which on a small body reaches the spheres buried
        #: below slot D (``bench/experiments/area_gather_study.py``); twice the candidates per cell.
        self.gather_both = False
        self._sides = None
        #: The side pass's sub-points of a decided cell seed by seed, with a mask of the points taken
        #: (``kernels/area.py`` ``subpoint_shares_rows``, S <= 8), instead of point by point. Bitwise the same.
        self.subpoint_rows = self.SUBPOINT_ROWS
        #: Each hidden round's depth pass starts from the previous keys less the flagged spheres' (``area_unhide``)
        #: instead of emptied slots (every offer then a chain of atomics). Bitwise the same keys.
        self.hidden_warm = self.HIDDEN_WARM
        if self.device.is_cuda:
            # Measured on the H100 (bench/NOTES.md, issue 22): the cell pass is set by its stragglers.
            self.block_dim = 64
            self.defer = True
        self.cell_pass = self.CELL_PASS or ("sides" if self.device.is_cuda else "cells")

    #: Deferred cells per cell of the grid: a cell whose order is undecided somewhere (1.4% of the SphereTest
    #: specimen's cell-lamps at 4 cells per diameter, a quarter of a strongly overlapping packing's) waits in a work
    #: list of n_cells / 16 entries; past that, the cell pass resolves it itself (slower, the same result).
    WORK_FRACTION = 16

    @property
    def defer(self) -> bool:
        """Undecided cells resolved by a thread per row of their points instead of one thread (``kernels/area.py``
        ``_area_kernels``): the cell pass's stragglers spread out. Bitwise the same result."""
        return self._work is not None

    @defer.setter
    def defer(self, on: bool) -> None:
        if bool(on) == self.defer:
            return
        self._work = None
        if on:
            from warp_lamp.kernels.area import SeedList, SideShares

            w = max(64, self.grid.n_cells // self.WORK_FRACTION)
            d = self.device
            self._work = {
                "seeds": wp.zeros(2 * w, dtype=SeedList, device=d),
                "shares": wp.zeros(2 * w, dtype=SideShares, device=d),
                "cells": wp.zeros(w, dtype=wp.int32, device=d),
                # The side pass's items: (lamp, cell) thread ids, one per undecided lamp (2 w of them).
                "items": wp.zeros(2 * w, dtype=wp.int32, device=d),
                "count": wp.zeros(1, dtype=wp.int32, device=d),
                "units": wp.zeros(2 * w * 16, dtype=wp.int32, device=d),
            }

    #: The cell pass new estimators start with (:attr:`cell_pass`; None: ``"sides"`` on CUDA, ``"cells"`` on the
    #: CPU), and whether the side pass's sub-points go seed by seed (:attr:`subpoint_rows`). Measured on an H200
    #: (``bench/results/h200-2026-11-28-cellpass.json``), the side pass with sub-points by seed took the specimen's
    #: cell pass at 4 cells per diameter from 0.322 to 0.210 ms (sub-points D3) and the 1M lattice's from 5.31 to
    #: 3.12 ms; on the CPU it gains nothing and costs its buffer.
    CELL_PASS = None
    SUBPOINT_ROWS = True
    #: Whether new estimators' hidden rounds start from the kept keys (:attr:`hidden_warm`).
    HIDDEN_WARM = True

    @property
    def cell_pass(self) -> str:
        """How the cell pass spreads over threads: ``"cells"``, one thread per cell running both lamps, or
        ``"sides"``, one thread per (lamp, cell) and a light kernel per cell that pays both lamps out (twice the
        threads, each with half the work; ``kernels/area.py`` ``_side_kernels``; a buffer of 144 bytes per
        (lamp, cell)). Bitwise the same result."""
        return "sides" if self._sides is not None else "cells"

    @cell_pass.setter
    def cell_pass(self, kind: str) -> None:
        if kind not in ("cells", "sides"):
            raise ValueError(f"cell_pass: expected 'cells' or 'sides', got {kind!r}")
        if kind == self.cell_pass:
            return
        self.nbytes -= self._sides.capacity if self._sides is not None else 0
        self._sides = None
        if kind == "sides":
            from warp_lamp.kernels.area import SideShares

            self._sides = wp.zeros(2 * self.grid.n_cells, dtype=SideShares, device=self.device)
            self.nbytes += self._sides.capacity

    @property
    def hidden_rounds(self) -> int:
        """Rounds of the hidden-sphere pass (0: off, the default). Each round flags the spheres that one sphere
        among a corner ray's D keys hides from a lamp (``kernels/area.py`` ``area_hidden``) and reruns the depth
        pass without them, so that the D slots go to spheres that can be seen: the lattice balls' see-through
        columns otherwise bury visible spheres below slot D (``bench/experiments/area_gather_study.py``). Costs a
        depth pass per round."""
        return self._hidden_rounds

    @hidden_rounds.setter
    def hidden_rounds(self, rounds: int) -> None:
        if not (isinstance(rounds, int) and 0 <= rounds <= 8):
            raise ValueError(f"hidden_rounds: expected an int in [0, 8], got {rounds!r}")
        self._hidden_rounds = rounds
        if rounds:
            self._hidden_diag = wp.zeros(self.diag.shape[0], dtype=wp.int32, device=self.device)
            self._hidden_buf = wp.zeros(self.counts.shape[0] // 3, dtype=wp.int32, device=self.device)

    def reserve(self, n: int) -> None:
        """As :meth:`FirstHit.reserve`, and the hidden-sphere flags for ``n`` particles."""
        super().reserve(n)
        if self._hidden_rounds and self._hidden_buf.shape[0] < self.counts.shape[0] // 3:
            self._hidden_buf = wp.zeros(self.counts.shape[0] // 3, dtype=wp.int32, device=self.device)

    def launch_depth(self) -> None:
        """Step 2: every sphere offers its depth to every corner ray it meets; then the hidden-sphere rounds."""
        self._hidden_flags = self._no_flags
        self._depth_diag = self.diag
        super().launch_depth()
        if not self._hidden_rounds or self.n == 0:
            return
        d = self.device
        flags = self._hidden_buf[: self.n]
        flags.zero_()
        for _ in range(self._hidden_rounds):
            wp.launch(
                area_kernels.area_hidden,
                dim=self.n,
                inputs=[
                    self._cells(),
                    self._input.particles,
                    self.keys,
                    self.depth_slots,
                    self._rays().offset,
                    self.lamp_mask,
                ],
                outputs=[flags],
                device=d,
            )
            if self.hidden_warm:
                # The flagged spheres' keys out, the rest kept: the rerun finds its lists nearly full (bitwise the
                # same keys as from emptied slots, ``area_unhide``).
                wp.launch(
                    area_kernels.area_unhide,
                    dim=self.keys.shape[0] // self.depth_slots,
                    inputs=[self._rays().offset, self.depth_slots, flags],
                    outputs=[self.keys],
                    device=d,
                )
            else:
                self.keys.fill_(_EMPTY)
            # The rerun counts invalid and outside particles again: into a scratch copy.
            self._hidden_flags = flags
            self._depth_diag = self._hidden_diag
            super().launch_depth()
        self._hidden_flags = self._no_flags
        self._depth_diag = self.diag

    def launch_scatter(self) -> None:
        """Step 3: each cell shares its units among the spheres visible in it."""
        if self.n == 0:
            return
        self._launch_area_cells(self._input.particles, self.keys, self.counts)

    def _launch_area_cells(self, particles, keys: wp.array, counts: wp.array) -> None:
        # The area kernel on given spheres, keys and counts (the distributed lamp passes every rank's spheres by
        # global id, the keys merged over ranks, and counts by global id).
        shared = [
            self._cells(),
            particles,
            keys,
            self.depth_slots,
            self._rays().offset,  # where each lamp's corner samples start among the keys
            self.lamp_mask | (int(area_kernels.GATHER_BOTH) if self.gather_both else 0),
            area_kernels.RESOLVER_EXACT if self.resolver == "exact" else area_kernels.RESOLVER_SUBPOINTS,
            self.subpoints,
            self.unit,
        ]
        if self._sides is not None:
            self._launch_sides(shared, counts)
            return
        if self._work is not None:
            self._launch_deferred(shared, counts)
            return
        wp.launch(
            area_kernels.area_cells,
            dim=self.grid.n_cells,
            inputs=shared,
            outputs=[counts, self.diag[2:]],
            device=self.device,
            block_dim=self.block_dim,
        )

    def _launch_deferred(self, shared: list, counts: wp.array) -> None:
        # The cell pass for decided cells, its undecided cells' rows of points, their payout (``defer``).
        w = self._work
        cells_k, rows_k, payout_k = area_kernels.AREA_DEFERRED[shared[6]]
        w["count"].zero_()
        w["units"].zero_()
        inputs = [*shared[:6], self.subpoints, self.unit]
        outputs = [counts, self.diag[2:], w["seeds"], w["shares"], w["cells"], w["count"]]
        d = self.device
        wp.launch(cells_k, dim=self.grid.n_cells, inputs=inputs, outputs=outputs, device=d, block_dim=self.block_dim)
        rows = self.subpoints if self.resolver == "subpoints" else int(area_kernels.RASTER)
        wp.launch(
            rows_k,
            dim=w["seeds"].shape[0] * rows,
            inputs=[shared[0], w["seeds"], w["shares"], w["cells"], w["count"], self.subpoints],
            outputs=[w["units"]],
            device=d,
        )
        wp.launch(
            payout_k,
            dim=w["cells"].shape[0],
            inputs=[shared[0], w["shares"], w["cells"], w["count"], w["units"], self.lamp_mask, self.unit],
            outputs=[counts, self.diag[2:]],
            device=d,
        )

    def _launch_sides(self, shared: list, counts: wp.array) -> None:
        # A thread per (lamp, cell), the undecided lamps' rows of points (``defer``), a payout per cell.
        sides_k, rows_k, payout_k = area_kernels.AREA_SIDES[shared[6]]
        d = self.device
        w = self._work
        if w is None:
            # No work list: every lamp is resolved by its own thread.
            seeds, items, count, units = self._no_work()
        else:
            seeds, items, count, units = w["seeds"], w["items"], w["count"], w["units"]
            count.zero_()
            units.zero_()
        inputs = [*shared[:6], self.subpoints, self.unit, int(self.subpoint_rows)]
        wp.launch(
            sides_k,
            dim=2 * self.grid.n_cells,
            inputs=inputs,
            outputs=[self._sides, seeds, items, count],
            device=d,
            block_dim=self.block_dim,
        )
        if w is not None:
            rows = self.subpoints if self.resolver == "subpoints" else int(area_kernels.RASTER)
            wp.launch(
                rows_k,
                dim=seeds.shape[0] * rows,
                inputs=[shared[0], seeds, items, count, self.subpoints],
                outputs=[units],
                device=d,
            )
        wp.launch(
            payout_k,
            dim=self.grid.n_cells,
            inputs=[shared[0], self._sides, units, self.lamp_mask, self.unit],
            outputs=[counts, self.diag[2:]],
            device=d,
        )

    def _no_work(self):
        # Empty work-list arrays for the side pass without ``defer`` (made once: no allocation in a capture).
        if getattr(self, "_empty_work", None) is None:
            from warp_lamp.kernels.area import SeedList

            d = self.device
            self._empty_work = (
                wp.empty(0, dtype=SeedList, device=d),
                wp.empty(0, dtype=wp.int32, device=d),
                wp.zeros(1, dtype=wp.int32, device=d),
                wp.empty(0, dtype=wp.int32, device=d),
            )
        return self._empty_work


class WettedCrossings(Estimator):
    """``surfaces="all"``: every crossing of the fluid's boundary along a cell-centre ray loads the nearest sphere
    (:class:`~warp_lamp.wetted.WettedSurface` on the lamp's voxel grid)."""

    name = "wetted surface"
    steps = ("wetted",)

    def __init__(self, frame: LampFrame, lamp_mask: int, *, lamps, probe_radius, max_rounds, max_bytes, skin=None):
        super().__init__(frame, lamp_mask)
        self.surface = WettedSurface(
            self.grid,
            probe_radius=probe_radius,
            lamps=lamps,
            max_rounds=max_rounds,
            device=self.device,
            max_bytes=max_bytes,
            walls=frame.wall_planes,
            skin=skin,
        )
        self.nbytes = self.surface.nbytes
        #: Signed counts per wall and axis (3 per wall), as the particles': the crossings each wall took.
        self.wall_counts = self.surface.wall_counts
        self._frame_positions = wp.zeros(0, dtype=wp.vec3, device=self.device)

    def reserve(self, n: int) -> None:
        """The surface's per-particle buffers, and room for the frame positions."""
        if not self._check_room(n, self.counts.shape[0] // 3):
            return
        self.surface.reserve(n)
        self.counts = self.surface.counts
        self._frame_positions = wp.zeros(n, dtype=wp.vec3, device=self.device)

    def update(self, inp: LampInput) -> None:
        """Move the positions into the frame (the voxels live there), then solve the wetted surface."""
        self._input = inp
        self.n = inp.n
        self.launch_wetted()

    def forget(self) -> None:
        """Drop the skin's kept decisions, so that the next update runs cold (benchmarks; the result is the same)."""
        self.surface.forget()

    def launch_wetted(self) -> None:
        """The one step: frame positions, then rasterise, connect, dilate and cross (``WettedSurface``)."""
        inp = self._input
        positions = inp.particles.positions
        if not inp.in_frame and self.n > 0:
            wp.launch(
                lamp_kernels.lamp_to_frame,
                dim=self.n,
                inputs=[self.frame.rays(False), inp.particles],
                outputs=[self._frame_positions],
                device=self.device,
            )
            positions = self._frame_positions[: self.n]
        # The walls as the frame placed them for this update (on the device for world positions).
        walls = self.frame.walls_view(inp.in_frame)
        self.surface.update(positions, inp.particles.radii, inp.active, walls=walls)

    def diagnostics(self):
        """The wetted surface's :class:`~warp_lamp.wetted.WettedDiagnostics`."""
        return self.surface.diagnostics()
