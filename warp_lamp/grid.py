"""The lamp grids: three axis-aligned 2D grids, one per global axis, each lit from both ends of its axis."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["DEFAULT_MAX_BYTES", "LampGrid"]

#: Default budget for the per-cell key arrays of one grid set [bytes].
DEFAULT_MAX_BYTES = 2 << 30
#: Bytes a cell needs on the device: one uint64 key per lamp, two lamps per cell.
BYTES_PER_CELL = 16


def _vec3(name: str, value, *, positive: bool = False) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(3, float(arr))
    if arr.shape != (3,):
        raise ValueError(f"{name}: expected a scalar or 3 values, got shape {arr.shape}")
    bad = ~np.isfinite(arr) | ((arr <= 0) if positive else False)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        need = "finite and > 0" if positive else "finite"
        raise ValueError(f"{name}: must be {need}; index {k} is {arr[k]!r}")
    return arr


@dataclass(frozen=True, eq=False)
class LampGrid:
    """Three lamp grids, in the memo's general form.

    Grid ``a`` looks along global axis ``a`` and spans the transverse axes ``u = (a+1)%3`` and ``v = (a+2)%3``.
    Its cell ``(i, j)`` is ``[corner[a,0] + i h[a,0], ... + h[a,0]) x [corner[a,1] + j h[a,1], ...)`` in global
    coordinates. Build it with ``LampGrid(lower, upper, cell_size)``, :meth:`from_grids` (the memo's 18 numbers)
    or :meth:`enclosing`.

    Attributes:
        origin: Frame origin [m], shape (3,), float64: ``lower`` in the box form. :func:`lamp_forces` subtracts it
            in float64 before casting to float32, so precision follows the body, not its distance from zero.
            :class:`ShiningLamp` takes float32 positions and subtracts ``float32(origin)`` on the device; it
            agrees bitwise with :func:`lamp_forces` when float32 holds the origin exactly.
        corner: Lower-left corner of each grid in its (u, v) axes [m], shape (3, 2), float64.
        cell: Cell size of each grid along (u, v) [m], shape (3, 2), float64.
        counts: Cells of each grid along (u, v), shape (3, 2), int.
        max_bytes: Memory budget the grid was checked against [bytes].
    """

    origin: np.ndarray
    corner: np.ndarray
    cell: np.ndarray
    counts: np.ndarray
    max_bytes: int = DEFAULT_MAX_BYTES

    def __init__(self, lower, upper, cell_size, *, max_bytes: int = DEFAULT_MAX_BYTES):
        """Box form: every grid covers the box, cells start at ``lower`` and are exactly ``cell_size`` wide.

        Args:
            lower: Lower corner of the box [m], 3 values.
            upper: Upper corner of the box [m], 3 values; the grid reaches ``ceil((upper-lower)/cell_size)``
                cells, so it may end a little past ``upper``.
            cell_size: Cell edge [m], a scalar or one per global axis.
            max_bytes: Budget for the per-cell arrays [bytes]; a larger grid raises ValueError.
        """
        lower = _vec3("lower", lower)
        upper = _vec3("upper", upper)
        h = _vec3("cell_size", cell_size, positive=True)
        if np.any(upper <= lower):
            k = int(np.flatnonzero(upper <= lower)[0])
            raise ValueError(f"upper: must exceed lower on every axis; axis {k} has {upper[k]!r} <= {lower[k]!r}")
        n = np.maximum(np.ceil((upper - lower) / h), 1.0)
        axes = [((a + 1) % 3, (a + 2) % 3) for a in range(3)]
        corner = np.array([[lower[u], lower[v]] for u, v in axes])
        cell = np.array([[h[u], h[v]] for u, v in axes])
        counts = np.array([[n[u], n[v]] for u, v in axes])
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
        origin = np.array([min(corners[(a + 2) % 3, 0], corners[(a + 1) % 3, 1]) for a in range(3)])
        self = cls.__new__(cls)
        self._setup(corners, lengths / counts_f, counts_f, max_bytes, origin=origin)
        return self

    @classmethod
    def enclosing(
        cls,
        centers,
        radii,
        cells_per_diameter: float = 4,
        margin: float | None = None,
        *,
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
        from warp_lamp.validate import check_particles

        centers, radii = check_particles(centers, radii)
        if len(radii) == 0:
            raise ValueError("centers: need at least one particle to fit a grid")
        if not (np.isfinite(cells_per_diameter) and cells_per_diameter > 0):
            raise ValueError(f"cells_per_diameter: must be finite and > 0, got {cells_per_diameter!r}")
        diameter = 2.0 * float(np.mean(radii))
        margin = diameter if margin is None else float(margin)
        if not (np.isfinite(margin) and margin >= 0):
            raise ValueError(f"margin: must be finite and >= 0, got {margin!r}")
        lo = np.min(centers - radii[:, None], axis=0) - margin
        hi = np.max(centers + radii[:, None], axis=0) + margin
        h = diameter / cells_per_diameter
        # With lower = min(c - r) - margin, or with the body centred, the extreme spheres can touch a cell edge
        # exactly whenever the body's extent is a whole number of cells: a tie that float32 rounding decides.
        # Shift the body by a golden-ratio fraction of the slack instead: irrational, so no whole-cell extent
        # can bring an extreme onto an edge.
        n = np.floor((hi - lo) / h) + 1.0
        lower = lo - 0.3819660112501051 * (n * h - (hi - lo))
        return cls(lower, lower + n * h, h, max_bytes=max_bytes)

    def _setup(self, corner, cell, counts, max_bytes, *, origin):
        counts = np.asarray(counts, dtype=np.float64)
        cells = int(np.sum(counts[:, 0] * counts[:, 1]))
        need = cells * BYTES_PER_CELL
        if need > max_bytes or cells >= 2**31 // 2:
            raise ValueError(
                f"grid: {cells:,} cells need {need:,} bytes, over the budget of {int(max_bytes):,} bytes "
                f"(raise max_bytes or use larger cells)"
            )
        origin = np.asarray(origin, dtype=np.float64).copy()
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "corner", np.asarray(corner, dtype=np.float64).copy())
        object.__setattr__(self, "cell", np.asarray(cell, dtype=np.float64).copy())
        object.__setattr__(self, "counts", counts.astype(np.int64))
        object.__setattr__(self, "max_bytes", int(max_bytes))

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

    def frame(self) -> dict:
        """Grid parameters in frame coordinates (minus ``origin``), as the kernels take them."""
        local = self.corner - np.array([[self.origin[(a + 1) % 3], self.origin[(a + 2) % 3]] for a in range(3)])
        return {
            "corner_u": local[:, 0],
            "corner_v": local[:, 1],
            "h_u": self.cell[:, 0],
            "h_v": self.cell[:, 1],
            "n_u": self.counts[:, 0],
            "n_v": self.counts[:, 1],
            "offset": self.offsets,
        }

    def cell_centers(self, axis: int) -> tuple[np.ndarray, np.ndarray]:
        """Global coordinates of the cell centres of grid ``axis`` along its u and v axes [m]."""
        (cu, cv), (hu, hv), (nu, nv) = self.corner[axis], self.cell[axis], self.counts[axis]
        return cu + (np.arange(nu) + 0.5) * hu, cv + (np.arange(nv) + 0.5) * hv

    def __repr__(self) -> str:
        return (
            f"LampGrid(origin={self.origin.tolist()}, cells={self.counts.tolist()}, "
            f"cell={self.cell.tolist()}, {self.nbytes:,} bytes)"
        )
