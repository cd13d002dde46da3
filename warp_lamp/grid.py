"""The lamp grids: three axis-aligned 2D grids, one per global axis, each lit from both ends of its axis."""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_lamp.kernels.grid import LampGridParams
from warp_lamp.validate import (
    DEFAULT_MAX_BYTES,
    check_box,
    check_grid_cells,
    check_particles,
    check_positive,
    check_vec3,
)

__all__ = ["BYTES_PER_CELL", "LampGrid"]

#: Bytes a cell needs on the device: one uint64 key per lamp, two lamps per cell.
BYTES_PER_CELL = 16


def _read_only(arr: np.ndarray) -> np.ndarray:
    arr = np.array(arr)
    arr.flags.writeable = False
    return arr


class LampGrid:
    """Three lamp grids, in the memo's general form.

    Grid ``a`` looks along global axis ``a`` and spans the transverse axes ``u = (a+1)%3`` and ``v = (a+2)%3``.
    Its cell ``(i, j)`` is ``[corner[a,0] + i cell[a,0], ... + cell[a,0]) x [corner[a,1] + j cell[a,1], ...)`` in
    global coordinates. Build it with ``LampGrid(lower, upper, cell_size)``, :meth:`from_grids` (the memo's 18
    numbers) or :meth:`enclosing`. Its memory (:attr:`nbytes`) is checked against ``max_bytes`` before anything is
    allocated, and its arrays are read-only, so that the check cannot be bypassed.
    """

    def __init__(self, lower, upper, cell_size, *, max_bytes: int = DEFAULT_MAX_BYTES):
        """Box form: every grid covers the box, cells start at ``lower`` and are exactly ``cell_size`` wide.

        Args:
            lower: Lower corner of the box [m], 3 values.
            upper: Upper corner of the box [m], 3 values; the grid reaches ``ceil((upper-lower)/cell_size)``
                cells, so it may end a little past ``upper``.
            cell_size: Cell edge [m], a scalar or one per global axis.
            max_bytes: Budget for the per-cell arrays [bytes]; a larger grid raises ValueError.
        """
        lower, upper = check_box(lower, upper)
        h = check_vec3("cell_size", cell_size, positive=True)
        with np.errstate(over="ignore"):
            n = np.maximum(np.ceil((upper - lower) / h), 1.0)
        axes = [((a + 1) % 3, (a + 2) % 3) for a in range(3)]
        corner = np.array([[lower[u], lower[v]] for u, v in axes])
        cell = np.array([[h[u], h[v]] for u, v in axes])
        counts = np.array([[n[u], n[v]] for u, v in axes])
        check_grid_cells("cell_size", counts, max_bytes, BYTES_PER_CELL)
        self._setup(corner, cell, counts, max_bytes, origin=lower)

    @classmethod
    def from_grids(cls, corners, lengths, counts, *, max_bytes: int = DEFAULT_MAX_BYTES) -> LampGrid:
        """The memo's form: each grid with its own corner, lengths and cell counts (3 x 6 = 18 numbers).

        Args:
            corners: Lower-left corner of grid a in its (u, v) axes [m], shape (3, 2).
            lengths: Extent of grid a along (u, v) [m], shape (3, 2).
            counts: Number of cells of grid a along (u, v), shape (3, 2), integers >= 1.
            max_bytes: Budget for the per-cell arrays [bytes].
        """
        corners = np.asarray(corners, dtype=np.float64)
        lengths = np.asarray(lengths, dtype=np.float64)
        counts_f = np.asarray(counts, dtype=np.float64)
        for name, arr in (("corners", corners), ("lengths", lengths), ("counts", counts_f)):
            if arr.shape != (3, 2):
                raise ValueError(f"{name}: expected shape (3, 2), got {arr.shape}")
            if not np.isfinite(arr).all():
                k = int(np.flatnonzero(~np.isfinite(arr).ravel())[0])
                raise ValueError(f"{name}: must be finite; flat index {k} is {arr.ravel()[k]!r}")
        for name, arr in (("lengths", lengths), ("counts", counts_f)):
            if np.any(arr <= 0):
                k = int(np.flatnonzero((arr <= 0).ravel())[0])
                raise ValueError(f"{name}: must be > 0; flat index {k} is {arr.ravel()[k]!r}")
        if np.any(counts_f != np.round(counts_f)):
            raise ValueError("counts: must be integers")
        check_grid_cells("counts", counts_f, max_bytes, BYTES_PER_CELL)
        origin = np.array([min(corners[(a + 2) % 3, 0], corners[(a + 1) % 3, 1]) for a in range(3)])
        self = cls.__new__(cls)
        self._setup(corners, lengths / counts_f, counts_f, max_bytes, origin=origin)
        return self

    @classmethod
    def enclosing(
        cls,
        centers,
        radii,
        *,
        cells_per_diameter: float = 4,
        margin: float | None = None,
        max_bytes: int = DEFAULT_MAX_BYTES,
    ) -> LampGrid:
        """A box grid around the particles, cell size = mean diameter / ``cells_per_diameter``.

        Args:
            centers: Particle centres [m], shape (N, 3), N >= 1.
            radii: Particle radii [m], shape (N,).
            cells_per_diameter: Cells per mean particle diameter (the memo studies 2 ... 16).
            margin: Free space around the particles' bounding box [m]; defaults to one mean diameter, so that
                particles can move a little between refits without poking out.
            max_bytes: Budget for the per-cell arrays [bytes].
        """
        centers, radii = check_particles(centers, radii)
        if len(radii) == 0:
            raise ValueError("centers: need at least one particle to fit a grid")
        cells_per_diameter = check_positive("cells_per_diameter", cells_per_diameter)
        diameter = 2.0 * float(np.mean(radii))
        margin = diameter if margin is None else check_positive("margin", margin, allow_zero=True)
        lo = np.min(centers - radii[:, None], axis=0) - margin
        hi = np.max(centers + radii[:, None], axis=0) + margin
        h = diameter / cells_per_diameter
        # With lower = min(c - r) - margin, or with the body centred, the extreme spheres can touch a cell edge
        # exactly whenever the body's extent is a whole number of cells: a tie that float32 rounding decides.
        # Shift the body by a golden-ratio fraction of the slack instead: irrational, so no whole-cell extent
        # can bring an extreme onto an edge.
        with np.errstate(over="ignore", divide="ignore"):
            n = np.floor((hi - lo) / h) + 1.0
        check_grid_cells(
            "cells_per_diameter", [[n[(a + 1) % 3], n[(a + 2) % 3]] for a in range(3)], max_bytes, BYTES_PER_CELL
        )
        lower = lo - 0.3819660112501051 * (n * h - (hi - lo))
        return cls(lower, lower + n * h, h, max_bytes=max_bytes)

    def _setup(self, corner, cell, counts, max_bytes, *, origin):
        counts = check_grid_cells("grid", counts, max_bytes, BYTES_PER_CELL)
        self._origin = _read_only(np.asarray(origin, dtype=np.float64))
        self._corner = _read_only(np.asarray(corner, dtype=np.float64))
        self._cell = _read_only(np.asarray(cell, dtype=np.float64))
        self._counts = _read_only(counts.astype(np.int64))

    @property
    def origin(self) -> np.ndarray:
        """Frame origin [m], shape (3,), float64: ``lower`` in the box form.

        :func:`~warp_lamp.lamp_forces` subtracts it in float64 before casting to float32, so precision follows
        the body, not its distance from zero. :class:`~warp_lamp.ShiningLamp` takes float32 positions and
        subtracts ``float32(origin)`` on the device; it agrees bitwise with ``lamp_forces`` when float32 holds the
        origin exactly.
        """
        return self._origin

    @property
    def corner(self) -> np.ndarray:
        """Lower-left corner of each grid in its (u, v) axes [m], shape (3, 2), float64."""
        return self._corner

    @property
    def cell(self) -> np.ndarray:
        """Cell size of each grid along (u, v) [m], shape (3, 2), float64."""
        return self._cell

    @property
    def counts(self) -> np.ndarray:
        """Cells of each grid along (u, v), shape (3, 2), int64."""
        return self._counts

    @property
    def n_cells(self) -> int:
        """Cells of the three grids together."""
        return int(np.sum(self.counts[:, 0] * self.counts[:, 1]))

    @property
    def nbytes(self) -> int:
        """Device memory of the per-cell arrays [bytes], known before anything is allocated."""
        return self.n_cells * BYTES_PER_CELL

    @property
    def offsets(self) -> np.ndarray:
        """First cell of each grid in the flat cell numbering, shape (3,)."""
        sizes = self.counts[:, 0] * self.counts[:, 1]
        return np.concatenate([[0], np.cumsum(sizes)[:2]]).astype(np.int64)

    @property
    def cell_area(self) -> np.ndarray:
        """Cell area of each grid [m^2], shape (3,)."""
        return self.cell[:, 0] * self.cell[:, 1]

    def params(self, *, in_frame: bool = False) -> LampGridParams:
        """The grid as the kernels take it, in frame coordinates (global minus :attr:`origin`).

        Args:
            in_frame: The kernels will receive positions already in frame coordinates (so they subtract nothing);
                otherwise they subtract ``float32(origin)`` from world positions.
        """
        local = self.corner - np.array([[self.origin[(a + 1) % 3], self.origin[(a + 2) % 3]] for a in range(3)])
        p = LampGridParams()
        p.origin = wp.vec3(0.0, 0.0, 0.0) if in_frame else wp.vec3(*self.origin.astype(np.float32))
        p.corner_u = wp.vec3(*local[:, 0])
        p.corner_v = wp.vec3(*local[:, 1])
        p.h_u = wp.vec3(*self.cell[:, 0])
        p.h_v = wp.vec3(*self.cell[:, 1])
        p.n_u = wp.vec3i(*(int(x) for x in self.counts[:, 0]))
        p.n_v = wp.vec3i(*(int(x) for x in self.counts[:, 1]))
        p.offset = wp.vec3i(*(int(x) for x in self.offsets))
        p.n_cells = self.n_cells
        return p

    def cell_centers(self, axis: int) -> tuple[np.ndarray, np.ndarray]:
        """Global coordinates of the cell centres of grid ``axis`` along its u and v axes [m]."""
        (cu, cv), (hu, hv), (nu, nv) = self.corner[axis], self.cell[axis], self.counts[axis]
        return cu + (np.arange(nu) + 0.5) * hu, cv + (np.arange(nv) + 0.5) * hv

    def __repr__(self) -> str:
        return (
            f"LampGrid(origin={self.origin.tolist()}, cells={self.counts.tolist()}, "
            f"cell={self.cell.tolist()}, {self.nbytes:,} bytes)"
        )
