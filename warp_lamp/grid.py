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
    format_value,
    lamp_rotation,
    unit_mixup_hint,
)

__all__ = ["BYTES_PER_CELL", "LampGrid", "LampGridSpec"]

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

    def __init__(self, lower, upper, cell_size, *, rotation=None, max_bytes: int = DEFAULT_MAX_BYTES):
        """Box form: every grid covers the box, cells start at ``lower`` and are exactly ``cell_size`` wide.

        Args:
            lower: Lower corner of the box [m], 3 values, in frame coordinates (see ``rotation``).
            upper: Upper corner of the box [m], 3 values; the grid reaches ``ceil((upper-lower)/cell_size)``
                cells, so it may end a little past ``upper``.
            cell_size: Cell edge [m], a scalar or one per frame axis.
            rotation: Orientation of the lamp frame: a 3 x 3 rotation matrix whose columns are the lamp axes in
                world coordinates, or a unit quaternion (x, y, z, w); the identity by default. A world point x has
                frame coordinates R^T x, and the box, cells and lamps live in the frame.
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
        self._setup(corner, cell, counts, max_bytes, origin=lower, rotation=rotation)

    @classmethod
    def from_grids(cls, corners, lengths, counts, *, rotation=None, max_bytes: int = DEFAULT_MAX_BYTES) -> LampGrid:
        """The memo's form: each grid with its own corner, lengths and cell counts (3 x 6 = 18 numbers).

        Args:
            corners: Lower-left corner of grid a in its (u, v) axes [m], shape (3, 2).
            lengths: Extent of grid a along (u, v) [m], shape (3, 2).
            counts: Number of cells of grid a along (u, v), shape (3, 2), integers >= 1.
            rotation: Orientation of the lamp frame, as for the box form.
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
                raise ValueError(f"{name}: must be finite; flat index {k} is {format_value(arr.ravel()[k])}")
        for name, arr in (("lengths", lengths), ("counts", counts_f)):
            if np.any(arr <= 0):
                k = int(np.flatnonzero((arr <= 0).ravel())[0])
                raise ValueError(f"{name}: must be > 0; flat index {k} is {format_value(arr.ravel()[k])}")
        if np.any(counts_f != np.round(counts_f)):
            raise ValueError("counts: must be integers")
        check_grid_cells("counts", counts_f, max_bytes, BYTES_PER_CELL)
        origin = np.array([min(corners[(a + 2) % 3, 0], corners[(a + 1) % 3, 1]) for a in range(3)])
        self = cls.__new__(cls)
        self._setup(corners, lengths / counts_f, counts_f, max_bytes, origin=origin, rotation=rotation)
        return self

    @classmethod
    def enclosing(
        cls,
        centers,
        radii,
        *,
        cells_per_diameter: float = 4,
        margin: float | None = None,
        rotation=None,
        probe_radius: float = 0.0,
        max_bytes: int = DEFAULT_MAX_BYTES,
    ) -> LampGrid:
        """A box grid around the particles, cell size = mean diameter / ``cells_per_diameter``.

        Args:
            centers: Particle centres [m], shape (N, 3), N >= 1.
            radii: Particle radii [m], shape (N,).
            cells_per_diameter: Cells per mean particle diameter (the memo studies 2 ... 16).
            margin: Free space around the particles' bounding box [m]; defaults to one mean diameter plus
                ``probe_radius``, so that particles can move a little between refits without poking out (and the
                wetted-surface mode's probe can come in from outside on every side).
            rotation: Orientation of the lamp frame (as for the box form): the box is fitted in that frame.
            probe_radius: The wetted-surface mode's probe radius [m], added to the default margin.
            max_bytes: Budget for the per-cell arrays [bytes].
        """
        centers, radii = check_particles(centers, radii)
        if len(radii) == 0:
            raise ValueError("centers: need at least one particle to fit a grid")
        cells_per_diameter = check_positive("cells_per_diameter", cells_per_diameter)
        rotation = lamp_rotation(rotation)
        centers = centers @ rotation  # frame coordinates: R^T x for each row x
        diameter = 2.0 * float(np.mean(radii))
        probe_radius = check_positive("probe_radius", probe_radius, allow_zero=True)
        margin = diameter + probe_radius if margin is None else check_positive("margin", margin, allow_zero=True)
        lo = np.min(centers - radii[:, None], axis=0) - margin
        hi = np.max(centers + radii[:, None], axis=0) + margin
        h = diameter / cells_per_diameter
        # With lower = min(c - r) - margin, or with the body centred, the extreme spheres can touch a cell edge
        # exactly whenever the body's extent is a whole number of cells: a tie that float32 rounding decides.
        # Shift the body by a golden-ratio fraction of the slack instead: irrational, so no whole-cell extent
        # can bring an extreme onto an edge.
        # The slack must not round to nothing: an extent a hair under a whole number of cells (39.9999... in metres,
        # 40 in millimetres) would leave the extremes on the edges, and the grid would depend on the unit.
        with np.errstate(over="ignore", divide="ignore"):
            n = np.floor((hi - lo) / h + 1e-3) + 1.0
        try:
            check_grid_cells(
                "cells_per_diameter", [[n[(a + 1) % 3], n[(a + 2) % 3]] for a in range(3)], max_bytes, BYTES_PER_CELL
            )
        except ValueError as e:
            # A grid far over the budget is, more often than not, centres and radii in different units.
            hint = unit_mixup_hint(centers, radii)
            if hint:
                raise ValueError(f"{e}; {hint}") from None
            raise
        lower = lo - 0.3819660112501051 * (n * h - (hi - lo))
        # Half a cell short of n cells: the box form's ceil then gives n in any unit (lower + n h could round a
        # hair over and add a row in metres but not in millimetres).
        return cls(lower, lower + (n - 0.5) * h, h, rotation=rotation, max_bytes=max_bytes)

    @classmethod
    def spec(
        cls,
        centers,
        radii,
        *,
        margin: float | None = None,
        rotation=None,
        probe_radius: float = 0.0,
        max_bytes: int = DEFAULT_MAX_BYTES,
    ) -> LampGridSpec:
        """An enclosing grid whose cells are still to be chosen (by ``ShiningLamp(spec, tolerance=...)``):
        :meth:`enclosing`'s arguments without ``cells_per_diameter``."""
        return LampGridSpec(
            centers, radii, margin=margin, rotation=rotation, probe_radius=probe_radius, max_bytes=max_bytes
        )

    def _setup(self, corner, cell, counts, max_bytes, *, origin, rotation):
        counts = check_grid_cells("grid", counts, max_bytes, BYTES_PER_CELL)
        self._rotation = _read_only(lamp_rotation(rotation))
        self._origin = _read_only(np.asarray(origin, dtype=np.float64))
        self._corner = _read_only(np.asarray(corner, dtype=np.float64))
        self._cell = _read_only(np.asarray(cell, dtype=np.float64))
        self._counts = _read_only(counts.astype(np.int64))

    @property
    def origin(self) -> np.ndarray:
        """Frame origin [m], shape (3,), float64, in frame coordinates: ``lower`` in the box form.

        A world point x sits at ``R^T x - origin`` in the grid's local coordinates (R = :attr:`rotation`).
        :func:`~warp_lamp.lamp_forces` does that in float64 before casting to float32, so precision follows the
        body, not its distance from zero. :class:`~warp_lamp.ShiningLamp` takes float32 world positions and does it
        on the device in float32 (with ``float32(R)`` and ``float32(R origin)``); with the identity it agrees
        bitwise with ``lamp_forces`` when float32 holds the origin exactly.
        """
        return self._origin

    @property
    def rotation(self) -> np.ndarray:
        """Orientation of the lamp frame: columns are the lamp axes in world coordinates, shape (3, 3), float64."""
        return self._rotation

    @property
    def world_origin(self) -> np.ndarray:
        """The frame origin in world coordinates [m], ``R origin``, shape (3,), float64."""
        return self._rotation @ self._origin

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

    @property
    def is_box(self) -> bool:
        """Whether the three grids tile one box with one cell size per frame axis (the box form), as the
        following grid and the wetted-surface mode need."""
        for a in range(3):
            for k, d in enumerate(((a + 1) % 3, (a + 2) % 3)):
                if self.corner[a, k] != self.origin[d]:
                    return False
                b = (d + 1) % 3  # another grid spanning axis d
                kb = [(b + 1) % 3, (b + 2) % 3].index(d)
                if self.cell[a, k] != self.cell[b, kb] or self.counts[a, k] != self.counts[b, kb]:
                    return False
        return True

    @property
    def box_cell(self) -> np.ndarray:
        """Cell size per frame axis [m], shape (3,), for the box form."""
        return np.array([self.cell[(d + 2) % 3, 0] for d in range(3)])

    @property
    def box_counts(self) -> np.ndarray:
        """Cells per frame axis, shape (3,), for the box form."""
        return np.array([int(self.counts[(d + 2) % 3, 0]) for d in range(3)])

    @property
    def n_samples(self) -> int:
        """Cell corners of the three grids together: the sample rays of the area criterion."""
        return int(np.sum((self.counts[:, 0] + 1) * (self.counts[:, 1] + 1)))

    def pose_arrays(self, device, *, in_frame: bool = False) -> tuple[wp.array, wp.array]:
        """The frame's pose as the kernels read it: (origin, rotation), one ``vec3`` and one ``mat33`` in float32 on
        ``device``: the frame origin in world coordinates and :attr:`rotation`, or zero and the identity where
        positions arrive ``in_frame`` (already ``R^T x - origin``)."""
        if in_frame:
            origin, rotation = np.zeros(3), np.eye(3)
        else:
            origin, rotation = self.world_origin, self.rotation
        return (
            wp.array([origin.astype(np.float32)], dtype=wp.vec3, device=device),
            wp.array([rotation.astype(np.float32)], dtype=wp.mat33, device=device),
        )

    def params(self, origin: wp.array, rotation: wp.array, *, corners: bool = False) -> LampGridParams:
        """The grid as the kernels take it, in frame coordinates, reading the frame's pose from ``origin`` and
        ``rotation`` (:meth:`pose_arrays`, or arrays a simulator updates between replays).

        Args:
            origin: The frame origin in world coordinates [m], warp array of one ``vec3``.
            rotation: The frame's orientation, warp array of one ``mat33``.
            corners: Describe the grid of the cells' corners instead ((n_u + 1) x (n_v + 1) samples per grid, the
                same corner and spacing), on which the area criterion's depth pass runs with ``RAY_CORNER``.
        """
        counts = self.counts + (1 if corners else 0)
        sizes = counts[:, 0] * counts[:, 1]
        local = self.corner - np.array([[self.origin[(a + 1) % 3], self.origin[(a + 2) % 3]] for a in range(3)])
        p = LampGridParams()
        p.origin = origin
        p.rotation = rotation
        p.corner_u = wp.vec3(*local[:, 0])
        p.corner_v = wp.vec3(*local[:, 1])
        p.h_u = wp.vec3(*self.cell[:, 0])
        p.h_v = wp.vec3(*self.cell[:, 1])
        p.n_u = wp.vec3i(*(int(x) for x in counts[:, 0]))
        p.n_v = wp.vec3i(*(int(x) for x in counts[:, 1]))
        p.offset = wp.vec3i(0, int(sizes[0]), int(sizes[0] + sizes[1]))
        p.n_cells = int(sizes.sum())
        return p

    def cell_centers(self, axis: int) -> tuple[np.ndarray, np.ndarray]:
        """Global coordinates of the cell centres of grid ``axis`` along its u and v axes [m]."""
        (cu, cv), (hu, hv), (nu, nv) = self.corner[axis], self.cell[axis], self.counts[axis]
        return cu + (np.arange(nu) + 0.5) * hu, cv + (np.arange(nv) + 0.5) * hv

    def rotated(self, rotation) -> LampGrid:
        """The grid turned by ``rotation`` (relative to its own frame): the smallest box in the frame
        ``self.rotation @ rotation`` that holds this grid's box, with the same (cubic) cells; this grid itself for
        the identity. Frame averaging builds its frames so."""
        r = lamp_rotation(rotation)
        if np.array_equal(r, np.eye(3)):
            return self
        h = self.box_cell
        if not self.is_box or np.ptp(h) > 0:
            raise ValueError("frames: turning a grid needs the box form with cubic cells")
        hi = self.origin + self.box_counts * h
        corners = np.array([[(self.origin, hi)[(k >> d) & 1][d] for d in range(3)] for k in range(8)])
        world = corners @ self.rotation.T
        frame = self.rotation @ r
        local = world @ frame
        lo, up = local.min(axis=0), local.max(axis=0)
        return LampGrid(lo, up, float(h[0]), rotation=frame, max_bytes=np.inf)

    def to_frame(self, centers) -> np.ndarray:
        """Local frame coordinates of world points [m], ``R^T (x - R origin)`` in float64 (the subtraction first,
        so that precision follows the body), shape (N, 3): what :func:`~warp_lamp.lamp_forces` casts to float32."""
        return (np.asarray(centers, dtype=np.float64) - self.world_origin) @ self._rotation

    def __repr__(self) -> str:
        rot = "" if np.array_equal(self.rotation, np.eye(3)) else f", rotation={self.rotation.tolist()}"
        return (
            f"LampGrid(origin={self.origin.tolist()}, cells={self.counts.tolist()}, "
            f"cell={self.cell.tolist()}{rot}, {self.nbytes:,} bytes)"
        )


class LampGridSpec:
    """An enclosing grid around particles whose cell size is not chosen yet (:meth:`LampGrid.spec`):
    ``ShiningLamp(spec, tolerance=...)`` chooses the cells per diameter, and :meth:`build` makes the grid."""

    def __init__(self, centers, radii, *, margin=None, rotation=None, probe_radius=0.0, max_bytes=DEFAULT_MAX_BYTES):
        """Args: as :meth:`LampGrid.enclosing`, without ``cells_per_diameter``."""
        self.centers, self.radii = check_particles(centers, radii)
        if len(self.radii) == 0:
            raise ValueError("centers: need at least one particle to fit a grid")
        self.margin = margin
        self.rotation = lamp_rotation(rotation)
        self.probe_radius = check_positive("probe_radius", probe_radius, allow_zero=True)
        self.max_bytes = max_bytes

    def build(self, cells_per_diameter: float = 4) -> LampGrid:
        """The grid with ``cells_per_diameter`` cells per mean particle diameter."""
        return LampGrid.enclosing(
            self.centers,
            self.radii,
            cells_per_diameter=cells_per_diameter,
            margin=self.margin,
            rotation=self.rotation,
            probe_radius=self.probe_radius,
            max_bytes=self.max_bytes,
        )

    def __repr__(self) -> str:
        return f"LampGridSpec({len(self.radii)} particles, margin={self.margin}, probe_radius={self.probe_radius})"
