"""Shining-lamp pressure boundary (Potyondy, PFC3D memo): Python API over the kernels in ``kernels/lamp.py``."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_lamp.grid import LampGrid
from warp_lamp.kernels import lamp as lamp_kernels
from warp_lamp.validate import (
    check_device_match,
    check_force_range,
    check_integer,
    check_mask,
    check_particles,
    check_positions,
    check_positive,
    check_pressure,
    check_vec3,
)

__all__ = [
    "LAMPS",
    "LampDiagnostics",
    "ShiningLamp",
    "lamp_forces",
    "lamp_mask",
    "lamp_names",
    "lamp_owner_maps",
    "lamp_update",
    "pressure_area",
]

#: Lamp names in bit order: "-x" is the lamp at minus infinity on x, shining toward +x.
LAMPS = ("-x", "+x", "-y", "+y", "-z", "+z")
_EMPTY = np.uint64(0xFFFFFFFFFFFFFFFF)


def lamp_names(lamps) -> tuple[str, ...]:
    """The lamps that are on, as a tuple of names from :data:`LAMPS`: ``"all"``, one name, or any iterable of names.

    The iterable is read once, here, so that a generator is not consumed by validation and then seen empty.
    """
    if isinstance(lamps, str):
        lamps = LAMPS if lamps == "all" else (lamps,)
    if not isinstance(lamps, Iterable):
        raise ValueError(f"lamps: expected 'all' or names from {LAMPS}, got {lamps!r}")
    names = tuple(lamps)
    for name in names:
        if name not in LAMPS:
            raise ValueError(f"lamps: unknown lamp {name!r}; expected 'all' or names from {LAMPS}")
    return names


def lamp_mask(lamps) -> int:
    """Bit mask of the lamps that are on (bit k for ``LAMPS[k]``); ``lamps`` as for :func:`lamp_names`."""
    mask = 0
    for name in lamp_names(lamps):
        mask |= 1 << LAMPS.index(name)
    return mask


def _check_criterion(criterion) -> int:
    if criterion not in (0, 1) or isinstance(criterion, bool):
        raise ValueError(f"criterion: expected 0 (cell overlaps disk) or 1 (cell centre ray), got {criterion!r}")
    return int(criterion)


def _round26(x: np.ndarray) -> np.ndarray:
    t = x * 134217729.0
    return t - (t - x)


def pressure_area(pressure, grid: LampGrid) -> np.ndarray:
    """Force per lit cell on each axis [N], shape (3,): P_a times the cell area of grid a.

    Rounded to 26 significant bits (relative change below 1.5e-8), so that P_a A_a times any cell count is
    exact in float64: the forces of all particles then sum to exactly zero, in any order of summation. A
    simulator that needs that exact float64 sum from a :class:`ShiningLamp` (whose forces are float32) computes
    ``lamp.counts_numpy() * pressure_area(P, lamp.grid)``.

    Raises:
        ValueError: when P_a A_a leaves the range where this is exact (above about 1e291 N, or nonzero below the
            smallest normal float64), naming ``pressure``.
    """
    p = check_pressure(pressure)
    check_force_range(p, grid.cell_area, grid.counts[:, 0] * grid.counts[:, 1])
    return _round26(p * grid.cell_area)


def _decode_depth(keys: np.ndarray) -> np.ndarray:
    b = (keys >> np.uint64(32)).astype(np.uint32)
    bits = np.where(b & np.uint32(0x80000000), b ^ np.uint32(0x80000000), ~b)
    return bits.view(np.float32).astype(np.float64)


def lamp_owner_maps(keys: np.ndarray, grid: LampGrid) -> tuple[dict, dict]:
    """Decode a lamp key array (two uint64 keys per cell, as ``ShiningLamp.keys``) into per-lamp maps.

    Returns:
        ``(owners, depths)``: per lamp name, the owner of each cell ``[i, j]`` (-1 where unlit), shape (n_u, n_v),
        and the global coordinate along the lamp's axis where its ray meets its owner [m] (NaN where unlit).
    """
    owners, depths = {}, {}
    for a in range(3):
        nu, nv = (int(x) for x in grid.counts[a])
        first = int(grid.offsets[a])
        for side in range(2):
            name = LAMPS[2 * a + side]
            k = keys[2 * first + side : 2 * (first + nu * nv) : 2]
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
        counts: Signed lit-cell counts per particle and axis, shape (N, 3), int64 (+1 per low-lamp cell,
            -1 per high-lamp cell).
        surface: Whether each particle is lit by any lamp that is on, shape (N,).
        owners: Per lamp name, the owner of each cell ``[i, j]`` (-1 where unlit), shape (n_u, n_v).
        depths: Per lamp name, the global coordinate along the lamp's axis where its ray meets its owner [m]
            (NaN where unlit), shape (n_u, n_v).
        lit: Per lamp name, the number of lit cells.
        invalid: Particles skipped as invalid (non-finite position or radius, radius <= 0).
        outside: Particles whose projected disk pokes outside at least one grid.
        force: Resultant force [N], shape (3,), when a pressure was given.
        moment: Resultant moment about ``moment_origin`` [N m], shape (3,), when positions and pressure were given.
        moment_origin: Point the moment is taken about [m] (the mean active particle centre by default).
    """

    counts: np.ndarray
    surface: np.ndarray
    owners: dict
    depths: dict
    lit: dict
    invalid: int
    outside: int
    force: np.ndarray | None = None
    moment: np.ndarray | None = None
    moment_origin: np.ndarray | None = None


#: Threads the depth pass aims for when it splits a small body's footprints: about what an H100 holds resident
#: (132 SMs x 2048).
_TARGET_THREADS = 1 << 18
#: Most threads per (sphere, axis): a footprint at 16 cells per diameter spans about 17 rows.
_MAX_SPLIT = 16
#: Particles from which the automatic choices treat a body as large.
_LARGE_BODY = 1 << 16


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


class ShiningLamp:
    """Shining-lamp pressure boundary for Warp particle simulators: arrays in, forces added in place.

    ``update`` finds which particle each lamp cell lights and stores signed cell counts per particle. It starts
    from the last update's owners, re-evaluated at the new positions, so that a slowly moving body costs little
    more than reading its footprint; the result does not depend on that history (an atomic minimum).
    ``add_forces`` adds P_a A_a count into a simulator's force array; ``apply`` does both. ``update`` takes world
    positions (the lamp subtracts ``float32(grid.origin)``) unless told ``in_frame=True``. None of them
    allocates (after the first update at a given particle count, or after :meth:`reserve`), synchronises or
    reads device data on the host, so they can be recorded in a CUDA graph with ``wp.ScopedCapture``. Invalid
    particles (non-finite, radius <= 0) are skipped and counted in :meth:`diagnostics`, never raised.

    With all six lamps on, the counts of each axis sum to exactly zero. The float32 forces that ``add_forces``
    writes are each the correctly rounded value of an exact float64 force, so they balance only to float32
    rounding (a net force of 1e-10 to 1e-9 of the summed force magnitudes on the SphereTest specimen at 2 to 8
    cells per diameter), not exactly; the exact float64 forces, whose sum is exactly zero,
    are ``lamp.counts_numpy() * warp_lamp.lamp.pressure_area(P, lamp.grid)`` (as :func:`lamp_forces` returns them).
    With a subset of lamps (``lamps``), the balance holds only on axes whose two lamps are both on.

    ``add_forces`` before any ``update`` raises RuntimeError naming ``update``: there are no counts yet. A captured
    graph cannot record that state, because capture needs an eager update (or :meth:`reserve` and an update
    earlier in the same capture) first.
    """

    def __init__(
        self,
        grid: LampGrid,
        *,
        criterion: int = 1,
        lamps="all",
        device=None,
        split: int | str = "auto",
        order: bool | str = "auto",
    ):
        """Allocate the per-cell arrays of ``grid`` on ``device``.

        Args:
            grid: The lamp grids.
            criterion: 1, a cell is lit where its centre ray meets the sphere (depth where the ray enters for
                the low lamp, leaves for the high lamp); 0, where the cell rectangle meets the projected disk
                (depth of the sphere centre on both sides). The memo's ``sl_ic``.
            lamps: "all", or names from :data:`LAMPS`.
            device: Warp device; the current default when None.
            split: How the depth pass shares out its work: 0, one thread per sphere for its three axes (the v4
                pass of ``bench/NOTES.md``); s >= 1, s threads per (sphere, axis), taking its rows in turn;
                ``"auto"`` chooses from the particle count when room is made for them (:meth:`reserve`), so that a
                small body still fills a GPU (0 on the CPU, where one thread runs the launch). The result does not
                depend on it.
            order: With a split, sort the work of each axis by the cell under each particle (a device radix
                sort), so that a warp's particles read the same rows: at the first update outside a capture, and
                again whenever :meth:`reorder` is called. ``"auto"``: on a GPU. The result does not depend on it;
                a body that moves far from where it was sorted only loses speed.
        """
        if not isinstance(grid, LampGrid):
            raise TypeError(f"grid: expected a LampGrid, got {type(grid).__name__}")
        if order not in ("auto", True, False):
            raise ValueError(f"order: expected 'auto', True or False, got {order!r}")
        if split != "auto" and (isinstance(split, bool) or not isinstance(split, (int, np.integer)) or split < 0):
            raise ValueError(f"split: expected 'auto' or an integer >= 0, got {split!r}")
        self.grid = grid
        self.criterion = _check_criterion(criterion)
        self.lamp_mask = lamp_mask(lamps)
        self.device = wp.get_device(device)
        self._split = split
        self.split = 0
        self._order = order
        self.order = wp.empty(0, dtype=wp.int32, device=self.device)
        self._no_order = self.order
        self._order_keys = wp.empty(0, dtype=wp.int32, device=self.device)
        self._order_ids = wp.empty(0, dtype=wp.int32, device=self.device)
        self._ordered_n = -1
        self._params = {False: grid.params(), True: grid.params(in_frame=True)}
        self._area = wp.vec3d(*grid.cell_area)
        d = self.device
        self.keys = wp.full(2 * grid.n_cells, value=_EMPTY, dtype=wp.uint64, device=d)
        self.diag = wp.zeros(lamp_kernels.N_DIAG, dtype=wp.int32, device=d)
        self.counts = wp.zeros(0, dtype=wp.int32, device=d)
        self._no_active = wp.empty(0, dtype=wp.int32, device=d)
        self._no_pressure = wp.empty(0, dtype=wp.float32, device=d)
        self.n = 0
        self._inputs = None

    def reserve(self, n: int) -> None:
        """Make room for ``n`` particles now, so that a later captured update need not allocate; this also fixes
        the depth pass's ``split`` for them.

        Args:
            n: Particle count, an integer >= 0.
        """
        n = check_integer("n", n)
        if 3 * n > self.counts.shape[0]:
            if self.device.is_capturing:
                raise RuntimeError(
                    f"positions: {n} particles exceed the {self.counts.shape[0] // 3} reserved; call "
                    "ShiningLamp.reserve(n) or one eager update before wp.ScopedCapture"
                )
            self.counts = wp.zeros(3 * n, dtype=wp.int32, device=self.device)
            self.split = _auto_split(n, self.device) if self._split == "auto" else int(self._split)
            sort = _auto_order(n, self.device) if self._order == "auto" else self._order
            if sort and self.split > 0:
                self.order = wp.empty(3 * n, dtype=wp.int32, device=self.device)
                self._order_keys = wp.empty(2 * n, dtype=wp.int32, device=self.device)
                self._order_ids = wp.empty(2 * n, dtype=wp.int32, device=self.device)
                self._ordered_n = -1

    def forget(self) -> None:
        """Drop the last update's owners, so that the next update runs cold (for benchmarks; results are equal)."""
        wp.launch(lamp_kernels.lamp_forget, dim=self.keys.shape[0], outputs=[self.keys], device=self.device)

    def _check_array(self, name, arr, dtype, n=None):
        if not isinstance(arr, wp.array):
            raise TypeError(f"{name}: expected a warp array of {dtype.__name__}, got {type(arr).__name__}")
        if arr.dtype != dtype:
            raise TypeError(f"{name}: expected dtype {dtype.__name__}, got {getattr(arr.dtype, '__name__', arr.dtype)}")
        if arr.ndim != 1:
            raise ValueError(f"{name}: expected a 1-D array, got shape {arr.shape}")
        if arr.device != self.device:
            raise ValueError(f"{name}: on device {arr.device}, the lamp is on {self.device}")
        if n is not None and arr.shape[0] < n:
            raise ValueError(f"{name}: has {arr.shape[0]} entries, need {n}")
        if not arr.is_contiguous:
            raise ValueError(f"{name}: must be contiguous")

    def update(self, positions: wp.array, radii: wp.array, active: wp.array | None = None, *, in_frame=False) -> None:
        """Recompute which particle each cell lights, and each particle's signed cell counts.

        Runs :meth:`launch_seed`, :meth:`launch_depth` and :meth:`launch_scatter` on these inputs.

        Args:
            positions: Particle centres [m], warp array of vec3 (float32), shape (N,), on the lamp's device: world
                coordinates, from which the lamp subtracts ``float32(grid.origin)``.
            radii: Particle radii [m], warp array of float32, shape (N,).
            active: Optional warp array of int32, shape (N,): 0 makes a particle invisible (no shadow, no force).
            in_frame: ``positions`` are already in frame coordinates (world minus ``grid.origin``, computed by the
                caller, e.g. in float64 before the cast to float32), so the lamp subtracts nothing.
        """
        self._check_array("positions", positions, wp.vec3)
        n = positions.shape[0]
        self._check_array("radii", radii, wp.float32, n)
        if active is None:
            active = self._no_active
        else:
            self._check_array("active", active, wp.int32, n)
        self.reserve(n)
        self.n = n
        particles = lamp_kernels.LampParticles()
        particles.positions = positions
        particles.radii = radii
        particles.active = active
        particles.n = n
        self._inputs = (self._params[bool(in_frame)], particles)
        if self.order.shape[0] and self._ordered_n != n and not self.device.is_capturing:
            self.reorder()
        self.launch_seed()
        self.launch_depth()
        self.launch_scatter()

    def reorder(self) -> None:
        """Sort the depth pass's work on each axis by the cell under each particle, at the last update's positions
        (a device radix sort; not inside a capture). Only a lamp with a split and ``order`` on keeps an order."""
        if not self.order.shape[0] or self._inputs is None:
            return
        grid, particles = self._inputs
        n = self.n
        for a in range(3):
            wp.launch(
                lamp_kernels.lamp_order_keys,
                dim=n,
                inputs=[grid, particles, a],
                outputs=[self._order_keys, self._order_ids],
                device=self.device,
            )
            wp.utils.radix_sort_pairs(self._order_keys, self._order_ids, n)
            wp.copy(self.order, self._order_ids, dest_offset=a * n, src_offset=0, count=n)
        self._ordered_n = n

    # The three steps of an update, on the inputs of the last update: named so that benchmarks can time them.

    def launch_seed(self) -> None:
        """Update step 1: clear the counts, and re-evaluate each cell's last owner at the current positions."""
        grid, particles = self._inputs
        d = self.device
        wp.launch(
            lamp_kernels.lamp_seed,
            dim=max(self.grid.n_cells, self.n, lamp_kernels.N_DIAG),
            inputs=[grid, particles, self.criterion],
            outputs=[self.keys, self.counts, self.diag],
            device=d,
        )

    def launch_depth(self) -> None:
        """Update step 2: every sphere offers its depth to every cell it covers."""
        grid, particles = self._inputs
        if self.n == 0:
            return
        wp.launch(
            lamp_kernels.lamp_depth if self.split else lamp_kernels.lamp_depth_sphere,
            dim=self.n * (3 * self.split if self.split else 1),
            inputs=[grid, particles, self.criterion, self.lamp_mask, self.split, 1, self._launch_order()],
            outputs=[self.keys, self.diag],
            device=self.device,
            block_dim=lamp_kernels.DEPTH_BLOCK_DIM,
        )

    def launch_scatter(self) -> None:
        """Update step 3: each lit cell adds its +1 / -1 to its owners' counts."""
        if self.n == 0:
            return
        wp.launch(
            lamp_kernels.lamp_scatter,
            dim=self.grid.n_cells,
            inputs=[self._inputs[0], self.keys],
            outputs=[self.counts],
            device=self.device,
        )

    def _launch_order(self) -> wp.array:
        # An order sorted for another particle count would skip particles: run unordered until the next reorder.
        return self.order if self._ordered_n == self.n else self._no_order

    def add_forces(self, forces: wp.array, pressure) -> None:
        """Add P_a A_a count[i, a] to ``forces[i]`` for the particles of the last update.

        Args:
            forces: Simulator force array [N], warp array of vec3 (float32), shape (>= N,); added to, not cleared.
            pressure: Fluid pressure [Pa]: a plain number, three numbers (Px, Py, Pz), or a warp float32 array of 1
                or 3 values on the device (read when the kernel runs, so a captured graph sees its current value;
                a device value is not range-checked, since reading it would synchronise).

        Raises:
            RuntimeError: before any ``update`` (eager, or earlier in the same capture).
            ValueError: a constant pressure whose P A count leaves float32's range, or the exact range.
        """
        if self._inputs is None:
            raise RuntimeError("add_forces: no counts yet; call ShiningLamp.update (or apply) first")
        self._check_array("forces", forces, wp.vec3, self.n)
        const = wp.vec3d(0.0, 0.0, 0.0)
        arr = self._no_pressure
        if isinstance(pressure, wp.array):
            self._check_array("pressure", pressure, wp.float32)
            if pressure.shape[0] not in (1, 3):
                raise ValueError(f"pressure: a device array must hold 1 or 3 values, got {pressure.shape[0]}")
            arr = pressure
        else:
            p = check_pressure(pressure)
            check_force_range(p, self.grid.cell_area, self.grid.counts[:, 0] * self.grid.counts[:, 1], float32=True)
            const = wp.vec3d(*p)
        if self.n > 0:
            wp.launch(
                lamp_kernels.lamp_add_forces,
                dim=self.n,
                inputs=[self.counts, self._area, const, arr],
                outputs=[forces],
                device=self.device,
            )

    def apply(self, positions: wp.array, radii: wp.array, forces: wp.array, pressure, *, active=None) -> None:
        """``update`` then ``add_forces``; arguments as there."""
        self.update(positions, radii, active)
        self.add_forces(forces, pressure)

    def counts_numpy(self) -> np.ndarray:
        """Signed lit-cell counts of the last update, shape (N, 3), int64 (copies to the host)."""
        return self.counts.numpy()[: 3 * self.n].reshape(self.n, 3).astype(np.int64)

    def diagnostics(self, positions=None, pressure=None, *, moment_origin=None) -> LampDiagnostics:
        """Surface flags, owner and depth maps, lit cells, skip counters, and resultants (host copies).

        Args:
            positions: Particle centres [m], shape (N, 3) with N of the last update (numpy, or warp on any device),
                world coordinates, for the resultant moment.
            pressure: Pressure [Pa] (a number or three), for the resultant force and moment.
            moment_origin: Point for the moment [m]; the mean centre of the lit particles by default.
        """
        if positions is not None:
            positions = check_positions("positions", positions, self.n)
        if pressure is not None:
            pressure = check_pressure(pressure)
        if moment_origin is not None:
            moment_origin = check_vec3("moment_origin", moment_origin)
        diag = self.diag.numpy()
        counts = self.counts_numpy()
        owners, depths = lamp_owner_maps(self.keys.numpy(), self.grid)
        surface = np.zeros(self.n, dtype=bool)
        lit = {}
        for name, own in owners.items():
            hit = own >= 0
            lit[name] = int(hit.sum())
            surface[own[hit]] = True
        out = LampDiagnostics(
            counts,
            surface,
            owners,
            depths,
            lit,
            int(diag[lamp_kernels.DIAG_INVALID]),
            int(diag[lamp_kernels.DIAG_OUTSIDE]),
        )
        if pressure is not None:
            f = counts * pressure_area(pressure, self.grid)
            out.force = f.sum(axis=0)
            if positions is not None:
                x = positions
                if moment_origin is None:
                    moment_origin = x[surface].mean(axis=0) if surface.any() else np.zeros(3)
                out.moment_origin = np.asarray(moment_origin, dtype=np.float64)
                out.moment = np.cross(x - out.moment_origin, f).sum(axis=0)
        return out


def lamp_update(
    centers,
    radii,
    *,
    grid: LampGrid | None = None,
    cells_per_diameter: float = 4,
    criterion: int = 1,
    lamps="all",
    active=None,
    device=None,
) -> ShiningLamp:
    """One lamp update on host data; returns the lamp, for its counts and :meth:`ShiningLamp.diagnostics`.

    The positions are taken relative to ``grid.origin`` in float64 before the cast to float32, so a body far from
    the origin gets the same result as near it; pass ``centers`` to ``diagnostics`` for the moment.

    Warp arrays are accepted on any device: they are read to the host once (to validate them and subtract the
    origin in float64), and the update then runs on the device where they live, unless ``device`` names another,
    which is refused.

    Args:
        centers: Particle centres [m], shape (N, 3): NumPy or a sequence (float64 welcome), or a warp ``vec3`` /
            ``vec3d`` array on any device.
        radii: Particle radii [m], shape (N,), or one number for all (NumPy, or a warp array).
        grid: Lamp grids; by default :meth:`LampGrid.enclosing` with ``cells_per_diameter`` (a placeholder
            one-cell grid when there are no particles).
        cells_per_diameter: Cells per mean particle diameter for the default grid.
        criterion: 1, cell-centre ray (default); 0, cell rectangle meets the projected disk.
        lamps: "all", or names from :data:`LAMPS` ("-x" is the lamp at minus infinity, pushing toward +x).
        active: Optional mask, shape (N,), booleans or numbers (nonzero: active): inactive particles are
            invisible (no shadow, no force).
        device: Warp device; by default where warp-array inputs live, else the current default.
    """
    device = check_device_match(device, centers=centers, radii=radii, active=active)
    c, r = check_particles(centers, radii)
    criterion = _check_criterion(criterion)
    lamps = lamp_names(lamps)
    cells_per_diameter = check_positive("cells_per_diameter", cells_per_diameter)
    n = c.shape[0]
    mask = None if active is None else check_mask("active", active, n)
    if grid is None:
        grid = (
            LampGrid([0.0] * 3, [1.0] * 3, 1.0)
            if n == 0
            else LampGrid.enclosing(c, r, cells_per_diameter=cells_per_diameter)
        )
    elif not isinstance(grid, LampGrid):
        raise TypeError(f"grid: expected a LampGrid, got {type(grid).__name__}")
    lamp = ShiningLamp(grid, criterion=criterion, lamps=lamps, device=device)
    pos = wp.array((c - grid.origin).astype(np.float32).reshape(n, 3), dtype=wp.vec3, device=device)
    rad = wp.array(r.astype(np.float32), dtype=wp.float32, device=device)
    act = None if mask is None else wp.array(mask, dtype=wp.int32, device=device)
    lamp.update(pos, rad, act, in_frame=True)
    return lamp


def lamp_forces(centers, radii, pressure, **options) -> np.ndarray:
    """Shining-lamp forces on a body of spheres under fluid pressure.

    Each cell of the three lamp grids shines from both ends of its axis; the first sphere its ray meets takes
    P_a A_cell along the ray, at its centre. Opposite lamps light the same cells, so with all six lamps on the
    forces sum to exactly zero on every axis; with a subset of lamps only axes whose two lamps are on balance.

    The float64 forces returned are exact multiples of the rounded P_a A_a (see :func:`pressure_area`), so they
    sum to exactly zero on every balanced axis, in any order of summation (``math.fsum`` and a plain ``sum``
    agree). :class:`ShiningLamp`'s float32 forces are these, rounded once each.

    Args:
        centers: Particle centres [m], shape (N, 3), float64 welcome: the grid origin is subtracted in float64
            before the cast to float32, so a body far from the origin gets the same forces as near it. A warp
            array on any device is read to the host once and the work runs on its device (see
            :func:`lamp_update`).
        radii: Particle radii [m], shape (N,), or one number for all.
        pressure: Fluid pressure [Pa]: a plain number, or (Px, Py, Pz) for polyaxial loading. Compression is
            positive: the forces push the body inward.
        **options: The keyword arguments of :func:`lamp_update`: ``grid``, ``cells_per_diameter``,
            ``criterion``, ``lamps``, ``active``, ``device``.

    Returns:
        Forces [N] (units of pressure times length squared), shape (N, 3), float64.

    Raises:
        ValueError: bad data or options, naming the argument (and the first bad index), or a pressure whose
            P A leaves the exact range.
    """
    p = check_pressure(pressure)
    lamp = lamp_update(centers, radii, **options)
    return lamp.counts_numpy() * pressure_area(p, lamp.grid)
