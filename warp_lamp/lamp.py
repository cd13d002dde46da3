"""Shining-lamp pressure boundary (Potyondy, PFC3D memo): Python API over the kernels in ``kernels/lamp.py``."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_lamp.frames import lamp_force_factors, lamp_frame_rotations, lamp_pressure, pressure_area
from warp_lamp.grid import LampGrid
from warp_lamp.kernels import area as area_kernels
from warp_lamp.kernels import lamp as lamp_kernels
from warp_lamp.kernels.footprint import RAY_CORNER
from warp_lamp.validate import (
    DEFAULT_MAX_BYTES,
    LAMPS,
    check_budget,
    check_device_match,
    check_force_range,
    check_integer,
    check_mask,
    check_particle_arrays,
    check_particles,
    check_positions,
    check_positive,
    check_vec3,
    check_warp_array,
    lamp_mask,
    lamp_names,
)
from warp_lamp.wetted import DEFAULT_MAX_ROUNDS, WettedDiagnostics, WettedSurface

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

_EMPTY = np.uint64(0xFFFFFFFFFFFFFFFF)

#: The area criterion's fixed-point units per cell, per resolver (sub-points: S^2, one per sub-point).
AREA_EXACT_UNIT = 4096
#: Resolvers of the area criterion.
AREA_RESOLVERS = ("subpoints", "exact")


def _check_criterion(criterion) -> int | str:
    if isinstance(criterion, str) and criterion == "area":
        return "area"
    if criterion not in (0, 1) or isinstance(criterion, bool):
        raise ValueError(
            f"criterion: expected 0 (cell overlaps disk), 1 (cell centre ray) or 'area' (visible area), got "
            f"{criterion!r}"
        )
    return int(criterion)


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
        force: Resultant force in world coordinates [N], shape (3,), when a pressure was given.
        moment: Resultant moment about ``moment_origin`` [N m], shape (3,), when positions and pressure were given.
        moment_origin: Point the moment is taken about [m] (the mean lit particle centre by default).
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
#: Why frame averaging refuses a per-axis pressure.
FRAMES_ISOTROPIC = "frame averaging needs an isotropic pressure (the lamp axes turn from frame to frame)"
#: Diagnostics slots: the lamp's counters, then the area kernel's two.
_N_DIAG = lamp_kernels.N_DIAG + 2


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


def _check_int(name: str, value, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ValueError(f"{name}: expected an integer in [{lo}, {hi}], got {value!r}")
    return int(value)


class ShiningLamp:
    """Shining-lamp pressure boundary for Warp particle simulators: arrays in, forces added in place.

    ``update`` finds which particle each lamp cell lights and stores signed counts per particle. It starts from
    the last update's owners, re-evaluated at the new positions, so that a slowly moving body costs little more
    than reading its footprint; the result does not depend on that history (an atomic minimum). ``add_forces``
    adds the forces into a simulator's force array, in world coordinates; ``apply`` does both. None of them
    allocates (after the first update at a given particle count, or after :meth:`reserve`), synchronises or reads
    device data on the host, so they can be recorded in a CUDA graph with ``wp.ScopedCapture``. Invalid particles
    (non-finite, radius <= 0) are skipped and counted in :meth:`diagnostics`, never raised.

    With all six lamps on, the counts of each axis sum to exactly zero. The float32 forces ``add_forces`` writes
    are each the correctly rounded value of the exact float64 force, so they balance to float32 rounding (about
    3e-8 relative per force); the exact float64 forces, which sum to exactly zero, are
    ``lamp.counts_numpy() @ lamp.force_factors(pressure).T`` (what :func:`lamp_forces` returns). With a subset of
    lamps (``lamps``), the balance holds only on axes whose two lamps are both on.

    The frame: positions are world coordinates; the lamp works in the grid's frame (``grid.rotation``, the frame
    origin) and returns forces in world coordinates. The frame's pose lives in device arrays, :attr:`origin`
    (one ``vec3``, world coordinates) and :attr:`rotation` (one ``mat33``), which a simulator may overwrite between
    replays of a captured graph to move and turn the frame with its body; ``follow=True`` moves it by whole cells
    itself.

    ``add_forces`` before any ``update`` raises RuntimeError naming ``update``: there are no counts yet. A captured
    graph cannot record that state, because capture needs an eager update (or :meth:`reserve` and an update
    earlier in the same capture) first.
    """

    def __init__(
        self,
        grid: LampGrid,
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
        frames: int = 1,
        surfaces: str = "first",
        probe_radius: float | None = None,
        max_rounds: int = DEFAULT_MAX_ROUNDS,
        max_bytes: int = DEFAULT_MAX_BYTES,
    ):
        """Allocate the per-cell arrays of ``grid`` on ``device``.

        Args:
            grid: The lamp grids.
            criterion: 1, a cell is lit where its centre ray meets the sphere (depth where the ray enters for
                the low lamp, leaves for the high lamp); 0, where the cell rectangle meets the projected disk
                (depth of the sphere centre on both sides): the memo's ``sl_ic``. ``"area"``: each cell's area is
                split among the spheres visible in it (the first ``depth_slots`` spheres on each of its corner
                rays, and the front sphere of the 8 corners around), exactly or on ``subpoints`` x ``subpoints``
                points: far more accurate per cell than criterion 1 (``README.md``, "Accuracy that beats
                refinement").
            lamps: "all", or names from :data:`LAMPS`.
            device: Warp device; the current default when None.
            depth_slots: Area criterion: spheres kept per corner ray and lamp, 1 to 4 (3: dense random packings;
                4: ordered packings).
            resolver: Area criterion: ``"subpoints"`` (each of S x S points of a cell goes to the first sphere that
                holds it; bitwise the same on CPU and GPU) or ``"exact"`` (circle arcs and cell edges; a last-bit
                difference of the trigonometry between CPU and GPU may move one unit of 4096 per cell).
            subpoints: Area criterion, sub-point resolver: points per cell edge, 1 to 16.
            follow: Move the grid with the body: each update finds the particles' box on the device and shifts
                the frame origin by whole cells so that the body sits centred in the grid, whose cell counts are a
                fixed capacity. Particles that outgrow it are counted as ``outside``; the forces still balance.
                Needs the box form of the grid (``LampGrid(lower, upper, cell)`` or ``enclosing``).
            split: How the depth pass shares out its work: 0, one thread per sphere for its three axes (the v4
                pass of ``bench/NOTES.md``); s >= 1, s threads per (sphere, axis), taking its rows in turn;
                ``"auto"`` chooses from the particle count when room is made for them (:meth:`reserve`), so that a
                small body still fills a GPU (0 on the CPU, where one thread runs the launch). The result does not
                depend on it.
            order: With a split, sort the work of each axis by the cell under each particle (a device radix
                sort), so that a warp's particles read the same rows: at the first update outside a capture, and
                again whenever :meth:`reorder` is called. ``"auto"``: for large bodies on a GPU. The result does
                not depend on it; a body that moves far from where it was sorted only loses speed.
            surfaces: ``"first"``: each lamp loads the first sphere its rays meet (the memo's lamp). ``"all"``:
                every wetted surface is loaded: the fluid is the region a probe ball of ``probe_radius`` can reach
                from outside without overlapping a sphere, and every crossing of its boundary along a lamp ray
                loads the nearest sphere (:mod:`warp_lamp.wetted`): slot walls, tunnels and overhangs get their
                pressure, sealed voids stay dry, and the probe bridges pores narrower than itself. Needs the box
                form of the grid, with a margin of ``probe_radius`` plus a cell beyond the particles, and criterion 1.
            probe_radius: ``surfaces="all"``: the probe radius rho [m]. For a membrane on the surface particles,
                a quarter to one mean radius (a dense packing keeps the probe out of its pores from about a third
                of a diameter); for mud, which fills a trough several diameters wide but not the pores, one to two
                mean radii (concave corners round off to rho; as rho grows the loaded surface becomes the convex
                hull); rho -> 0 lets the fluid into every connected pore.
            max_rounds: ``surfaces="all"``: bound on the connectivity solve's rounds; a solve that needs more is
                cut short and counted in the diagnostics (the balance still holds).
            frames: Frame averaging: run the lamp in this many fixed orientations (``frames.lamp_frame_rotations``:
                the grid's own first, then a low-discrepancy set turned by it) and average the forces. Each frame's
                grid is the smallest box in that frame around ``grid``'s box, with its cells (cubic cells needed).
                ``update`` runs every frame's pass (all recorded in a capture); :attr:`frames` lists the per-frame
                lamps for their diagnostics.
            max_bytes: Budget for the lamp's per-cell arrays [bytes] (the area criterion keeps ``depth_slots``
                keys per corner and lamp; frame averaging keeps one set per frame); over it, ValueError before
                anything is allocated.
        """
        if not isinstance(grid, LampGrid):
            raise TypeError(f"grid: expected a LampGrid, got {type(grid).__name__}")
        self._weight = 1.0
        self.frames = []
        frames = _check_int("frames", frames, 1, 1 << 10)
        if frames > 1:
            if follow:
                raise ValueError("frames: frame averaging with follow=True is not supported; follow one frame")
            grids = [grid.rotated(r) for r in lamp_frame_rotations(frames)]
            need = (
                sum(g.n_samples if criterion == "area" else g.n_cells for g in grids)
                * 16
                * (depth_slots if criterion == "area" else 1)
            )
            check_budget(need, max_bytes, f"frames: {frames} frames need {need:,} bytes", "raise max_bytes")
            options = dict(
                criterion=criterion,
                lamps=lamps,
                device=device,
                depth_slots=depth_slots,
                resolver=resolver,
                subpoints=subpoints,
                split=split,
                order=order,
                surfaces=surfaces,
                probe_radius=probe_radius,
                max_rounds=max_rounds,
                max_bytes=max_bytes,
            )
            self.frames = [ShiningLamp(g, **options) for g in grids]
            for child in self.frames:
                child._weight = 1.0 / frames
            self.grid = grid
            self.criterion = self.frames[0].criterion
            self.lamp_mask = self.frames[0].lamp_mask
            self.device = self.frames[0].device
            self.unit = self.frames[0].unit
            self.follow = False
            self.n = 0
            self._inputs = None
            return
        if order not in ("auto", True, False):
            raise ValueError(f"order: expected 'auto', True or False, got {order!r}")
        if split != "auto" and (isinstance(split, bool) or not isinstance(split, (int, np.integer)) or split < 0):
            raise ValueError(f"split: expected 'auto' or an integer >= 0, got {split!r}")
        if resolver not in AREA_RESOLVERS:
            raise ValueError(f"resolver: expected one of {AREA_RESOLVERS}, got {resolver!r}")
        if follow not in (True, False):
            raise ValueError(f"follow: expected True or False, got {follow!r}")
        self.grid = grid
        self.criterion = _check_criterion(criterion)
        self.lamp_mask = lamp_mask(lamps)
        self.device = d = wp.get_device(device)
        area = self.criterion == "area"
        self.depth_slots = _check_int("depth_slots", depth_slots, 1, lamp_kernels.MAX_SLOTS) if area else 1
        self.subpoints = _check_int("subpoints", subpoints, 1, 16)
        self.resolver = resolver
        #: Counts per whole cell: 1 for cell counts, the area criterion's fixed-point units.
        self.unit = 1
        if area:
            self.unit = AREA_EXACT_UNIT if resolver == "exact" else self.subpoints**2
        # Where the depth pass's rays sit: cell centres or rectangles, or the area criterion's cell corners.
        self._ray = int(RAY_CORNER) if area else self.criterion
        if follow and not grid.is_box:
            raise ValueError("follow: needs the box form of the grid (LampGrid(lower, upper, cell) or enclosing)")
        if surfaces not in ("first", "all"):
            raise ValueError(f"surfaces: expected 'first' or 'all', got {surfaces!r}")
        self.surfaces = surfaces
        self._wet = None
        if surfaces == "all":
            if probe_radius is None:
                raise ValueError("probe_radius: surfaces='all' needs the probe radius rho [m] (see the docstring)")
            if self.criterion != 1:
                raise ValueError("criterion: surfaces='all' loads crossings along the cell-centre rays (criterion 1)")
            self._wet = WettedSurface(
                grid, probe_radius=probe_radius, lamps=lamps, max_rounds=max_rounds, device=d, max_bytes=max_bytes
            )
            self.nbytes = self._wet.nbytes
            samples = 0
        elif probe_radius is not None:
            raise ValueError("probe_radius: only with surfaces='all'")
        else:
            samples = grid.n_samples if area else grid.n_cells
            self.nbytes = 2 * self.depth_slots * samples * 8
            check_budget(
                self.nbytes,
                max_bytes,
                f"depth_slots: {self.depth_slots} keys per lamp on {samples:,} rays need {self.nbytes:,} bytes",
                "raise max_bytes, lower depth_slots or use larger cells",
            )
        self.follow = bool(follow)
        self._split = split
        self.split = 0
        self._order = order
        self.order = wp.empty(0, dtype=wp.int32, device=d)
        self._no_order = self.order
        self._order_keys = wp.empty(0, dtype=wp.int32, device=d)
        self._order_ids = wp.empty(0, dtype=wp.int32, device=d)
        self._ordered_n = -1
        #: The frame's pose on the device: origin (world coordinates, one vec3) and rotation (one mat33).
        self.origin, self.rotation = grid.pose_arrays(d)
        frame_pose = grid.pose_arrays(d, in_frame=True)
        # Kernel views of the grid: its cells (scatter, area kernel) and its rays (seed, depth pass), for world
        # positions and for positions already in frame coordinates.
        self._cells = {False: grid.params(self.origin, self.rotation), True: grid.params(*frame_pose)}
        self._rays = {
            False: grid.params(self.origin, self.rotation, corners=area),
            True: grid.params(*frame_pose, corners=area),
        }
        self.keys = wp.full(2 * self.depth_slots * samples, value=_EMPTY, dtype=wp.uint64, device=d)
        self._frame_positions = wp.zeros(0, dtype=wp.vec3, device=d)
        self.diag = wp.zeros(_N_DIAG, dtype=wp.int32, device=d)
        self.counts = wp.zeros(0, dtype=wp.int64, device=d)
        if self.follow:
            self.follow_shift = wp.zeros(1, dtype=wp.vec3i, device=d)
            self._bounds = wp.array([3.0e38] * 3 + [-3.0e38] * 3, dtype=wp.float32, device=d)
            # The grid never changes, so its base origin, cells and box are kernel constants, made once.
            base = grid.world_origin
            self._follow_base = (
                wp.vec3(*base.astype(np.float32)),
                wp.vec3d(*base),
                wp.vec3d(*grid.box_cell),
                wp.vec3i(*grid.box_counts),
            )
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
        for child in self.frames:
            child.reserve(n)
        if self.frames:
            return
        if 3 * n > self.counts.shape[0]:
            if self.device.is_capturing:
                raise RuntimeError(
                    f"positions: {n} particles exceed the {self.counts.shape[0] // 3} reserved; call "
                    "ShiningLamp.reserve(n) or one eager update before wp.ScopedCapture"
                )
            if self._wet is None:
                self.counts = wp.zeros(3 * n, dtype=wp.int64, device=self.device)
            else:
                self._wet.reserve(n)
                self.counts = self._wet.counts
                self._frame_positions = wp.zeros(n, dtype=wp.vec3, device=self.device)
            self.split = _auto_split(n, self.device) if self._split == "auto" else int(self._split)
            if self.depth_slots > 1:
                self.split = max(self.split, 1)  # the D-slot depth pass is compiled for shared work only
            sort = _auto_order(n, self.device) if self._order == "auto" else self._order
            if sort and self.split > 0:
                self.order = wp.empty(3 * n, dtype=wp.int32, device=self.device)
                self._order_keys = wp.empty(2 * n, dtype=wp.int32, device=self.device)
                self._order_ids = wp.empty(2 * n, dtype=wp.int32, device=self.device)
                self._ordered_n = -1

    def forget(self) -> None:
        """Drop the last update's owners, so that the next update runs cold (for benchmarks; results are equal)."""
        for child in self.frames:
            child.forget()
        if self.frames:
            return
        wp.launch(lamp_kernels.lamp_forget, dim=self.keys.shape[0], outputs=[self.keys], device=self.device)

    def _check_array(self, name, arr, dtype, n=None):
        check_warp_array(name, arr, dtype, self.device, "the lamp", n)

    def update(self, positions: wp.array, radii: wp.array, active: wp.array | None = None, *, in_frame=False) -> None:
        """Recompute which particle each cell lights, and each particle's signed counts.

        Runs :meth:`launch_seed`, :meth:`launch_depth` and :meth:`launch_scatter` on these inputs (after the
        grid's move, with ``follow``).

        Args:
            positions: Particle centres [m], warp array of vec3 (float32), shape (N,), on the lamp's device: world
                coordinates, which the lamp moves into its frame (:attr:`origin`, :attr:`rotation`).
            radii: Particle radii [m], warp array of float32, shape (N,).
            active: Optional warp array of int32, shape (N,): 0 makes a particle invisible (no shadow, no force).
            in_frame: ``positions`` are already in frame coordinates (``grid.to_frame``, computed by the caller,
                e.g. in float64 before the cast to float32), so the lamp moves nothing (and does not follow).
        """
        if self.frames:
            if in_frame:
                raise ValueError("in_frame: frame averaging needs world positions (each frame moves them itself)")
            for child in self.frames:
                child.update(positions, radii, active)
            self.n = self.frames[0].n
            self._inputs = self.frames[0]._inputs
            return
        n = check_particle_arrays(positions, radii, active, self.device, "the lamp")
        if active is None:
            active = self._no_active
        self.reserve(n)
        self.n = n
        particles = lamp_kernels.LampParticles()
        particles.positions = positions
        particles.radii = radii
        particles.active = active
        particles.n = n
        self._inputs = (bool(in_frame), particles)
        if self.follow and not in_frame:
            self.launch_follow()
        if self._wet is not None:
            self._update_wetted(particles, in_frame)
            return
        if self.order.shape[0] and self._ordered_n != n and not self.device.is_capturing:
            self.reorder()
        self.launch_seed()
        self.launch_depth()
        self.launch_scatter()

    def _update_wetted(self, particles, in_frame) -> None:
        positions = particles.positions
        if not in_frame:
            wp.launch(
                lamp_kernels.lamp_to_frame,
                dim=self.n,
                inputs=[self._cells[False], particles],
                outputs=[self._frame_positions],
                device=self.device,
            )
            positions = self._frame_positions[: self.n]
        self._wet.update(positions, particles.radii, None if particles.active is self._no_active else particles.active)

    def reorder(self) -> None:
        """Sort the depth pass's work on each axis by the cell under each particle, at the last update's positions
        (a device radix sort; not inside a capture). Only a lamp with a split and ``order`` on keeps an order."""
        if self.frames:
            for child in self.frames:
                child.reorder()
            return
        if not self.order.shape[0] or self._inputs is None:
            return
        in_frame, particles = self._inputs
        n = self.n
        for a in range(3):
            wp.launch(
                lamp_kernels.lamp_order_keys,
                dim=n,
                inputs=[self._rays[in_frame], particles, a],
                outputs=[self._order_keys, self._order_ids],
                device=self.device,
            )
            wp.utils.radix_sort_pairs(self._order_keys, self._order_ids, n)
            wp.copy(self.order, self._order_ids, dest_offset=a * n, src_offset=0, count=n)
        self._ordered_n = n

    # The steps of an update, on the inputs of the last update: named so that benchmarks can time them.

    def launch_follow(self) -> None:
        """Update step 0, with ``follow``: find the body's box and move the frame origin by whole cells."""
        _, particles = self._inputs
        origin32, origin, cell, box = self._follow_base
        wp.launch(
            lamp_kernels.lamp_follow_bounds,
            dim=self.n,
            inputs=[particles, origin32, self.rotation],
            outputs=[self._bounds],
            device=self.device,
        )
        wp.launch(
            lamp_kernels.lamp_follow_shift,
            dim=1,
            inputs=[origin, cell, box, self.rotation],
            outputs=[self._bounds, self.follow_shift, self.origin],
            device=self.device,
        )

    def launch_seed(self) -> None:
        """Update step 1: clear the counts, and re-evaluate each ray's last owners at the current positions."""
        if self.frames:
            for child in self.frames:
                child.launch_seed()
            return
        in_frame, particles = self._inputs
        rays = self._rays[in_frame]
        kernel, inputs = lamp_kernels.lamp_seed, [rays, particles, self._ray]
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
        """Update step 2: every sphere offers its depth to every ray it meets."""
        if self.frames:
            for child in self.frames:
                child.launch_depth()
            return
        in_frame, particles = self._inputs
        if self.n == 0:
            return
        if self.depth_slots > 1:
            kernel = lamp_kernels.lamp_depth_slots
        else:
            kernel = lamp_kernels.lamp_depth if self.split else lamp_kernels.lamp_depth_sphere
        wp.launch(
            kernel,
            dim=self.n * (3 * self.split if self.split else 1),
            inputs=[
                self._rays[in_frame],
                particles,
                self._ray,
                self.lamp_mask,
                self.split,
                self.depth_slots,
                self._launch_order(),
            ],
            outputs=[self.keys, self.diag],
            device=self.device,
            block_dim=lamp_kernels.DEPTH_BLOCK_DIM,
        )

    def launch_scatter(self) -> None:
        """Update step 3: each lit cell adds its +1 / -1 to its owners' counts (the area criterion: each cell
        shares its units among the spheres visible in it)."""
        if self.frames:
            for child in self.frames:
                child.launch_scatter()
            return
        if self.n == 0:
            return
        in_frame, particles = self._inputs
        cells = self._cells[in_frame]
        if self.criterion == "area":
            wp.launch(
                area_kernels.area_cells,
                dim=self.grid.n_cells,
                inputs=[
                    cells,
                    particles,
                    self.keys,
                    self.depth_slots,
                    self._rays[in_frame].offset,  # where each lamp's corner samples start among the keys
                    self.lamp_mask,
                    area_kernels.RESOLVER_EXACT if self.resolver == "exact" else area_kernels.RESOLVER_SUBPOINTS,
                    self.subpoints,
                    self.unit,
                ],
                outputs=[self.counts, self.diag[2:]],
                device=self.device,
            )
            return
        wp.launch(
            lamp_kernels.lamp_scatter,
            dim=self.grid.n_cells,
            inputs=[cells, self.keys],
            outputs=[self.counts],
            device=self.device,
        )

    def _launch_order(self) -> wp.array:
        # An order sorted for another particle count would skip particles: run unordered until the next reorder.
        return self.order if self._ordered_n == self.n else self._no_order

    def _force_area(self) -> np.ndarray:
        # Cell area per count, with the frame's share of an average: the one expression host and device use.
        return self.grid.cell_area / (self.unit / self._weight)

    def force_factors(self, pressure) -> np.ndarray:
        """F[j, a]: world force component j [N] per count on lamp axis a (``frames.lamp_force_factors``), for
        the grid's rotation: the exact float64 forces are ``counts_numpy() @ F.T``, summed over a in order.

        Args:
            pressure: A number, three numbers (per lamp axis) or a stress tensor diagonal in the lamp frame [Pa].
        """
        if self.frames:
            raise ValueError("force_factors: one per frame; use lamp.frames[k].force_factors")
        p, _ = lamp_pressure(pressure, self.grid.rotation)
        check_force_range(p, self.grid.cell_area, self.grid.counts[:, 0] * self.grid.counts[:, 1])
        return lamp_force_factors(p, self._force_area(), self.grid.rotation)

    def add_forces(self, forces: wp.array, pressure) -> None:
        """Add each particle's forces of the last update to ``forces``, in world coordinates.

        Args:
            forces: Simulator force array [N], warp array of vec3 (float32), shape (>= N,); added to, not cleared.
            pressure: Fluid pressure [Pa]: a number, three numbers (per lamp axis), a stress tensor (3 x 3,
                compression positive) diagonal in the lamp frame, or a warp float32 array of 1 or 3 values on the
                device (read when the kernel runs, so a captured graph sees its current value; a device value is
                not range-checked, since reading it would synchronise).

        Raises:
            RuntimeError: before any ``update`` (eager, or earlier in the same capture): there are no counts yet.
            ValueError: a constant pressure whose P A count leaves float32's range, or the exact range.
        """
        if self._inputs is None:
            raise RuntimeError("add_forces: no counts yet; call ShiningLamp.update (or apply) first")
        if self.frames:
            self._check_frames_pressure(pressure)
            for child in self.frames:
                child.add_forces(forces, pressure)
            return
        self._check_array("forces", forces, wp.vec3, self.n)
        const = wp.vec3d(0.0, 0.0, 0.0)
        arr = self._no_pressure
        if isinstance(pressure, wp.array):
            self._check_array("pressure", pressure, wp.float32)
            if pressure.shape[0] not in (1, 3):
                raise ValueError(f"pressure: a device array must hold 1 or 3 values, got {pressure.shape[0]}")
            arr = pressure
        else:
            p, _ = lamp_pressure(pressure, self.grid.rotation)
            cells = self.grid.counts[:, 0] * self.grid.counts[:, 1]
            check_force_range(p, self.grid.cell_area, cells)  # the exact range
            check_force_range(p, self.grid.cell_area, cells, float32=True)
            const = wp.vec3d(*p)
        if self.n > 0:
            in_frame = self._inputs[0]
            wp.launch(
                lamp_kernels.lamp_add_forces,
                dim=self.n,
                inputs=[
                    self.counts,
                    wp.vec3d(*self._force_area()),
                    self._cells[True].rotation if in_frame else self.rotation,
                    const,
                    arr,
                ],
                outputs=[forces],
                device=self.device,
            )

    def _check_frames_pressure(self, pressure) -> None:
        # The lamp axes turn from frame to frame, so a per-axis pressure would load each frame differently: only
        # an isotropic one averages. A device array is checked by its length (reading its values would sync).
        if isinstance(pressure, wp.array):
            if pressure.shape[0] != 1:
                raise ValueError(f"pressure: {FRAMES_ISOTROPIC}: a device array of 1 value, got {pressure.shape[0]}")
        elif np.ptp(lamp_pressure(pressure, self.frames[0].grid.rotation)[0]) > 0:
            raise ValueError(f"frames: {FRAMES_ISOTROPIC}")

    def apply(self, positions: wp.array, radii: wp.array, forces: wp.array, pressure, *, active=None) -> None:
        """``update`` then ``add_forces``; arguments as there."""
        self.update(positions, radii, active)
        self.add_forces(forces, pressure)

    def counts_numpy(self) -> np.ndarray:
        """Signed counts of the last update, shape (N, 3), int64 (copies to the host); with frame averaging,
        one set per frame, shape (frames, N, 3)."""
        if self.frames:
            return np.stack([child.counts_numpy() for child in self.frames])
        return self.counts.numpy()[: 3 * self.n].reshape(self.n, 3)

    def forces_numpy(self, pressure) -> np.ndarray:
        """The exact float64 forces of the last update in world coordinates [N], shape (N, 3), summed over frames
        (a host copy: what :func:`lamp_forces` returns)."""
        if self.frames:
            self._check_frames_pressure(pressure)
            return sum(child.forces_numpy(pressure) for child in self.frames)
        c = self.counts_numpy()
        f = self.force_factors(pressure)
        return (c[:, :1] * f[:, 0] + c[:, 1:2] * f[:, 1]) + c[:, 2:3] * f[:, 2]

    def frame_origin(self) -> np.ndarray:
        """The frame origin of the last update in frame coordinates [m], float64: ``grid.origin``, moved by whole
        cells with ``follow`` (reads the device: a synchronisation). A grid ``LampGrid(frame_origin, ...,
        rotation=grid.rotation)`` with the same cells and counts reproduces the last update bitwise."""
        if not self.follow:
            return self.grid.origin.copy()
        k = self.follow_shift.numpy()[0].astype(np.float64)
        return self.grid.origin + k * self.grid.box_cell

    def diagnostics(self, positions=None, pressure=None, *, moment_origin=None) -> LampDiagnostics | WettedDiagnostics:
        """Surface flags, owner and depth maps, lit cells, skip counters, and resultants (host copies); with
        ``surfaces="all"``, the wetted surface's :class:`~warp_lamp.wetted.WettedDiagnostics` (voxel maps, per-ray
        crossings, the connectivity solve), with the resultant force in world coordinates.

        Args:
            positions: Particle centres [m], shape (N, 3) with N of the last update (numpy, or warp on any device),
                world coordinates, for the resultant moment.
            pressure: Pressure [Pa] (as :meth:`add_forces` takes it on the host), for the resultant force and moment.
            moment_origin: Point for the moment [m]; the mean centre of the lit particles by default.
        """
        if self.frames:
            raise ValueError("diagnostics: one per frame; use lamp.frames[k].diagnostics()")
        if positions is not None:
            positions = check_positions("positions", positions, self.n)
        if moment_origin is not None:
            moment_origin = check_vec3("moment_origin", moment_origin)
        if self._wet is not None:
            out = self._wet.diagnostics()
            if pressure is not None:
                out.force = self.forces_numpy(pressure).sum(axis=0)
            return out
        diag = self.diag.numpy()
        counts = self.counts_numpy()
        keys = self.keys.numpy()
        corners = self.criterion == "area"
        if corners:
            keys = keys.reshape(-1, self.depth_slots)[:, 0]
        owners, depths = lamp_owner_maps(keys, self.grid, corners=corners)
        surface = np.zeros(self.n, dtype=bool)
        lit = {}
        for name, own in owners.items():
            hit = own >= 0
            lit[name] = int(hit.sum())
            surface[own[hit]] = True
        out = LampDiagnostics(
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
        )
        if pressure is not None:
            f = self.forces_numpy(pressure)
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
    criterion: int | str = 1,
    lamps="all",
    active=None,
    device=None,
    **lamp_options,
) -> ShiningLamp:
    """One lamp update on host data; returns the lamp, for its counts and :meth:`ShiningLamp.diagnostics`.

    The positions go into the grid's frame (``grid.to_frame``: the origin subtracted, then the rotation) in float64
    before the cast to float32, so a body far from the origin gets the same result as near it; pass ``centers`` to
    ``diagnostics`` for the moment.

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
        criterion: 1, cell-centre ray (default); 0, cell rectangle meets the projected disk; ``"area"``, each
            cell's area split among the spheres visible in it (:class:`ShiningLamp`).
        lamps: "all", or names from :data:`LAMPS` ("-x" is the lamp at minus infinity, pushing toward +x).
        active: Optional mask, shape (N,), booleans or numbers (nonzero: active): inactive particles are
            invisible (no shadow, no force).
        device: Warp device; by default where warp-array inputs live, else the current default.
        **lamp_options: Further keywords of :class:`ShiningLamp` (``depth_slots``, ``resolver``, ``subpoints``,
            ``surfaces``, ``probe_radius``, ``max_rounds``, ``split``, ``order``, ``max_bytes``); with
            ``surfaces="all"`` the default grid's margin grows by ``probe_radius``.
    """
    device = check_device_match(device, centers=centers, radii=radii, active=active)
    c, r = check_particles(centers, radii)
    criterion = _check_criterion(criterion)
    lamps = lamp_names(lamps)
    cells_per_diameter = check_positive("cells_per_diameter", cells_per_diameter)
    n = c.shape[0]
    mask = None if active is None else check_mask("active", active, n)
    if grid is None:
        probe = lamp_options.get("probe_radius") if lamp_options.get("surfaces") == "all" else None
        if n == 0:
            grid = LampGrid([0.0] * 3, [1.0] * 3, 1.0)
        else:
            grid = LampGrid.enclosing(c, r, cells_per_diameter=cells_per_diameter, probe_radius=probe or 0.0)
    elif not isinstance(grid, LampGrid):
        raise TypeError(f"grid: expected a LampGrid, got {type(grid).__name__}")
    lamp = ShiningLamp(grid, criterion=criterion, lamps=lamps, device=device, **lamp_options)
    pos = wp.array(grid.to_frame(c).astype(np.float32).reshape(n, 3), dtype=wp.vec3, device=device)
    rad = wp.array(r.astype(np.float32), dtype=wp.float32, device=device)
    act = None if mask is None else wp.array(mask, dtype=wp.int32, device=device)
    lamp.update(pos, rad, act, in_frame=True)
    return lamp


def lamp_forces(centers, radii, pressure, *, frames: int = 1, **options) -> np.ndarray:
    """Shining-lamp forces on a body of spheres under fluid pressure, in world coordinates [N], float64.

    Each cell of the three lamp grids shines from both ends of its axis; the first sphere its ray meets takes
    P_a A_cell along the ray, at its centre (or, with ``criterion="area"``, each visible sphere its share of the
    cell). Opposite lamps light the same cells, so with all six lamps on the forces sum to exactly zero on every
    axis, in any order of summation (also in a rotated frame, and averaged over frames: each world component is a
    sum of integer multiples of powers of two); with a subset of lamps only axes whose two lamps are on balance.

    The float64 forces returned are exact multiples of the rounded P_a A_a (see :func:`pressure_area`), so they
    sum to exactly zero on every balanced axis, in any order of summation (``math.fsum`` and a plain ``sum``
    agree). :class:`ShiningLamp`'s float32 forces are these, rounded once each.

    Args:
        centers: Particle centres [m], shape (N, 3), float64 welcome: the grid origin is subtracted in float64
            before the cast to float32, so a body far from the origin gets the same forces as near it. A warp
            array on any device is read to the host once and the work runs on its device (see
            :func:`lamp_update`).
        radii: Particle radii [m], shape (N,), or one number for all.
        pressure: Fluid pressure [Pa]: one number, (P1, P2, P3) per lamp axis (polyaxial loading), or a
            symmetric 3 x 3 stress tensor (compression positive), which the lamp applies in its principal frame
            (without ``grid``: the enclosing grid is built in that frame; with ``grid``: the tensor must be
            diagonal in the grid's frame).
        frames: Average over this many fixed lamp frames (``frames.lamp_frame_rotations``), each with its own
            enclosing grid (or ``grid`` turned, :meth:`LampGrid.rotated`); needs an isotropic pressure.
        **options: The keyword arguments of :func:`lamp_update` and :class:`ShiningLamp`: ``grid``,
            ``cells_per_diameter``, ``criterion``, ``lamps``, ``active``, ``device``, ``depth_slots``, ``resolver``,
            ``subpoints``, ``surfaces``, ``probe_radius``, ``max_rounds``, ``split``, ``order``, ``max_bytes``.

    Returns:
        Forces [N] (units of pressure times length squared), shape (N, 3), float64.

    Raises:
        ValueError: bad data or options, naming the argument (and the first bad index), or a pressure whose
            P A leaves the exact range.
    """
    grid = options.pop("grid", None)
    if grid is not None and not isinstance(grid, LampGrid):
        raise TypeError(f"grid: expected a LampGrid, got {type(grid).__name__}")
    p, frame = lamp_pressure(pressure, None if grid is None else grid.rotation)
    frames = _check_int("frames", frames, 1, 1 << 10)
    if frames > 1 and np.ptp(p) > 0:
        raise ValueError(f"frames: {FRAMES_ISOTROPIC}")
    options["device"] = check_device_match(
        options.get("device"), centers=centers, radii=radii, active=options.get("active")
    )
    c, r = check_particles(centers, radii)
    cells_per_diameter = options.pop("cells_per_diameter", 4)
    base = np.eye(3) if frame is None else frame
    total = np.zeros((len(r), 3))
    for rotation in lamp_frame_rotations(frames):
        g = grid
        if g is not None:
            g = g.rotated(rotation)
        elif len(r):
            probe = options.get("probe_radius") if options.get("surfaces") == "all" else None
            g = LampGrid.enclosing(
                c, r, cells_per_diameter=cells_per_diameter, rotation=base @ rotation, probe_radius=probe or 0.0
            )
        lamp = lamp_update(c, r, grid=g, cells_per_diameter=cells_per_diameter, **options)
        lamp._weight = 1.0 / frames
        total = total + lamp.forces_numpy(p)
    return total
