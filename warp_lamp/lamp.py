"""Shining-lamp pressure boundary (Potyondy, PFC3D memo): the lamp a user holds, and the one-call host functions.

:class:`ShiningLamp` is a thin façade over the pipeline of :mod:`warp_lamp.pipeline` (frame -> rays -> estimator
-> counts -> forces): it checks its options once, picks the estimator (:mod:`warp_lamp.estimators`) from them, and
runs the stages in order. :class:`FrameAveragedLamp` is a composite of K lamps in fixed frames.
:func:`lamp_forces` and :func:`lamp_update` check host data once and run one update.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_lamp.estimators import (
    AREA_EXACT_UNIT,
    AREA_GATHERS,
    AREA_RESOLVERS,
    AreaSplit,
    FirstHit,
    LampDiagnostics,
    WettedCrossings,
    lamp_owner_maps,
)
from warp_lamp.frames import lamp_frame_rotations, lamp_pressure, pressure_area
from warp_lamp.grid import LampGrid, LampGridSpec
from warp_lamp.kernels import lamp as lamp_kernels
from warp_lamp.pipeline import Estimator, LampFrame, LampInput, exact_forces, lamp_input, launch_add_forces
from warp_lamp.tolerance import LampChoice, choose_settings
from warp_lamp.validate import (
    DEFAULT_MAX_BYTES,
    LAMPS,
    check_budget,
    check_device_match,
    check_force_range,
    check_integer,
    check_mask,
    check_particles,
    check_positions,
    check_positive,
    check_vec3,
    check_walls,
    check_warp_array,
    format_value,
    lamp_mask,
    lamp_names,
    resolve_device,
    user_stacklevel,
    walls_behind_message,
)
from warp_lamp.wetted import DEFAULT_MAX_ROUNDS, WettedDiagnostics, check_probe_radius

__all__ = [
    "AREA_EXACT_UNIT",
    "AREA_GATHERS",
    "AREA_RESOLVERS",
    "LAMPS",
    "FrameAveragedLamp",
    "LampDiagnostics",
    "LampOptions",
    "ShiningLamp",
    "lamp_forces",
    "lamp_mask",
    "lamp_names",
    "lamp_owner_maps",
    "lamp_update",
    "pressure_area",
]

#: Why frame averaging refuses a per-axis pressure.
FRAMES_ISOTROPIC = "frame averaging needs an isotropic pressure (the lamp axes turn from frame to frame)"
#: Why walls and frame averaging do not go together (every turned frame's lamp axes cut a wall).
FRAMES_WALLS = "not with frame averaging (frames > 1); use one frame with the walls"


def _check_criterion(criterion) -> int | str:
    if isinstance(criterion, str) and criterion == "area":
        return "area"
    if criterion not in (0, 1) or isinstance(criterion, bool):
        raise ValueError(
            f"criterion: expected 0 (cell overlaps disk), 1 (cell centre ray) or 'area' (visible area), got "
            f"{format_value(criterion)}"
        )
    return int(criterion)


def _check_int(name: str, value, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ValueError(f"{name}: expected an integer in [{lo}, {hi}], got {format_value(value)}")
    return int(value)


#: What ``tolerance=`` chooses, with the defaults the caller must leave alone.
_CHOSEN = {
    "criterion": 1,
    "resolver": "subpoints",
    "depth_slots": 3,
    "subpoints": 8,
    "gather": "front",
    "surfaces": "first",
    "cells_per_diameter": 4,
}


def _tolerance_choice(tolerance, device, **given) -> LampChoice:
    """``choose_settings``, after refusing, naming ``tolerance``, what it would override."""
    names = ", ".join(sorted(k for k, v in given.items() if v != _CHOSEN[k]))
    if names:
        raise ValueError(
            f"tolerance: chooses the criterion, the area settings and the cells per diameter itself; leave out "
            f"{names} (or leave out tolerance)"
        )
    return choose_settings(tolerance, device)


@dataclass(frozen=True)
class LampOptions:
    """A lamp's options, checked once (:meth:`checked`); what :class:`ShiningLamp` documents, argument by argument."""

    criterion: int | str = 1
    lamps: tuple = LAMPS
    depth_slots: int = 3
    resolver: str = "subpoints"
    subpoints: int = 8
    gather: str = "front"
    follow: bool = False
    split: int | str = "auto"
    order: bool | str = "auto"
    surfaces: str = "first"
    probe_radius: float | None = None
    max_rounds: int = DEFAULT_MAX_ROUNDS
    max_bytes: float = DEFAULT_MAX_BYTES
    walls: np.ndarray | None = None
    skin: bool | str = "auto"

    @classmethod
    def checked(
        cls,
        *,
        criterion=1,
        lamps="all",
        depth_slots=3,
        resolver="subpoints",
        subpoints=8,
        gather="front",
        follow=False,
        split="auto",
        order="auto",
        surfaces="first",
        probe_radius=None,
        max_rounds=DEFAULT_MAX_ROUNDS,
        max_bytes=DEFAULT_MAX_BYTES,
        walls=None,
        skin="auto",
    ) -> LampOptions:
        """The options, or an error naming the first bad one."""
        if order not in ("auto", True, False):
            raise ValueError(f"order: expected 'auto', True or False, got {format_value(order)}")
        if split != "auto" and (isinstance(split, bool) or not isinstance(split, (int, np.integer)) or split < 0):
            raise ValueError(f"split: expected 'auto' or an integer >= 0, got {format_value(split)}")
        if resolver not in AREA_RESOLVERS:
            raise ValueError(f"resolver: expected one of {AREA_RESOLVERS}, got {format_value(resolver)}")
        if follow not in (True, False):
            raise ValueError(f"follow: expected True or False, got {format_value(follow)}")
        criterion = _check_criterion(criterion)
        lamps = lamp_names(lamps)
        area = criterion == "area"
        depth_slots = _check_int("depth_slots", depth_slots, 1, lamp_kernels.MAX_SLOTS) if area else 1
        subpoints = _check_int("subpoints", subpoints, 1, 16)
        if gather not in AREA_GATHERS:
            raise ValueError(f"gather: expected one of {AREA_GATHERS}, got {format_value(gather)}")
        if gather != "front" and not area:
            raise ValueError(f"gather: {gather!r} is the area criterion's (criterion='area')")
        if surfaces not in ("first", "all"):
            raise ValueError(f"surfaces: expected 'first' or 'all', got {format_value(surfaces)}")
        if surfaces == "all":
            if probe_radius is None:
                raise ValueError("probe_radius: surfaces='all' needs the probe radius rho [m] (see the docstring)")
            probe_radius = check_positive("probe_radius", probe_radius, allow_zero=True)
            if criterion != 1:
                raise ValueError("criterion: surfaces='all' loads crossings along the cell-centre rays (criterion 1)")
        elif probe_radius is not None:
            raise ValueError("probe_radius: only with surfaces='all'")
        if not (skin is True or skin is False or skin == "auto"):
            raise ValueError(f"skin: expected 'auto', True or False, got {format_value(skin)}")
        walls = check_walls(walls)
        if len(walls) and area:
            raise ValueError(
                "walls: only with criteria 0 and 1 (surfaces='first' or 'all'), not with criterion='area': its "
                "per-cell payout balances the two lamps of a cell against each other, and a wall that stops the rays "
                "of one lamp but not the other's would leave that payout unbalanced"
            )
        return cls(
            criterion=criterion,
            lamps=lamps,
            depth_slots=depth_slots,
            resolver=resolver,
            subpoints=subpoints,
            gather=gather,
            follow=bool(follow),
            split=split,
            order=order,
            surfaces=surfaces,
            probe_radius=probe_radius,
            max_rounds=max_rounds,
            max_bytes=max_bytes,
            walls=walls,
            skin=skin,
        )

    def estimator(self, frame: LampFrame) -> Estimator:
        """The estimator these options ask for, on ``frame``."""
        mask = lamp_mask(self.lamps)
        if self.surfaces == "all":
            return WettedCrossings(
                frame,
                mask,
                lamps=self.lamps,
                probe_radius=check_probe_radius(self.probe_radius),
                max_rounds=self.max_rounds,
                max_bytes=self.max_bytes,
                skin="auto" if self.skin is not False else None,
            )
        shared = dict(split=self.split, order=self.order, max_bytes=self.max_bytes)
        if self.criterion == "area":
            est = AreaSplit(
                frame, mask, depth_slots=self.depth_slots, resolver=self.resolver, subpoints=self.subpoints, **shared
            )
            if self.gather == "deep":
                est.gather_both = True
                est.hidden_rounds = 2
            return est
        return FirstHit(frame, mask, criterion=self.criterion, **shared)


class ShiningLamp:
    """Shining-lamp pressure boundary for Warp particle simulators: arrays in, forces added in place.

    ``update`` finds which particle each lamp cell lights and stores signed counts per particle. It starts from
    the last update's owners, re-evaluated at the new positions, so that a slowly moving body costs little more
    than reading its footprint; the result does not depend on that history (an atomic minimum). ``add_forces``
    adds the forces into a simulator's force array, in world coordinates; ``apply`` does both. None of them
    allocates (after the first update at a given particle count, or after :meth:`reserve`), synchronises or reads
    device data on the host, so they can be recorded in a CUDA graph with ``wp.ScopedCapture``. Invalid particles
    (non-finite, radius <= 0) are skipped and counted in :meth:`diagnostics`, never raised: a device path cannot
    stop mid-capture. (:func:`lamp_forces`, which reads host data anyway, refuses them instead, naming the first
    bad index.)

    With all six lamps on, the counts of each axis sum to exactly zero. The float32 forces ``add_forces`` writes
    are each the correctly rounded value of the exact float64 force, so they balance to float32 rounding (about
    3e-8 relative per force); the exact float64 forces, which sum to exactly zero, are :meth:`forces_numpy` (what
    :func:`lamp_forces` returns). With a subset of lamps (``lamps``), the balance holds only on axes whose two lamps
    are both on.

    The lamp is a pipeline (:mod:`warp_lamp.pipeline`): its :attr:`frame` (pose, following grid) gives the rays of
    :attr:`grid`; its :attr:`estimator` (:mod:`warp_lamp.estimators`, chosen from the arguments) turns particles
    into counts; the forces are counts times P A. The estimator's buffers and steps (``keys``, ``split``,
    ``launch_seed``, ...) read through the lamp.

    The frame: positions are world coordinates; the lamp works in the grid's frame (``grid.rotation``, the frame
    origin) and returns forces in world coordinates. The frame's pose lives in device arrays, :attr:`origin`
    (one ``vec3``, world coordinates) and :attr:`rotation` (one ``mat33``), which a simulator may overwrite between
    replays of a captured graph to move and turn the frame with its body; ``follow=True`` moves it by whole cells
    itself.

    ``ShiningLamp(grid, frames=K)`` with K > 1 returns a :class:`FrameAveragedLamp`, the composite of K lamps.

    ``add_forces`` before any ``update`` raises RuntimeError naming ``update``: there are no counts yet. A captured
    graph cannot record that state, because capture needs an eager update (or :meth:`reserve` and an update
    earlier in the same capture) first.
    """

    def __new__(cls, grid=None, *, frames: int = 1, **options):
        frames = _check_int("frames", frames, 1, 1 << 10)
        if frames > 1:
            return FrameAveragedLamp(grid, frames=frames, **options)
        return super().__new__(cls)

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
        gather: str = "front",
        follow: bool = False,
        split: int | str = "auto",
        order: bool | str = "auto",
        frames: int = 1,
        surfaces: str = "first",
        probe_radius: float | None = None,
        max_rounds: int = DEFAULT_MAX_ROUNDS,
        max_bytes: int = DEFAULT_MAX_BYTES,
        walls=None,
        tolerance: float | None = None,
        skin: bool | str = "auto",
    ):
        """Allocate the per-cell arrays of ``grid`` on ``device``.

        Args:
            grid: The lamp grids, or a :class:`~warp_lamp.grid.LampGridSpec` (``LampGrid.spec(centers, radii)``)
                whose cells ``tolerance`` chooses (4 per mean diameter without ``tolerance``).
            criterion: 1, a cell is lit where its centre ray meets the sphere (depth where the ray enters for
                the low lamp, leaves for the high lamp); 0, where the cell rectangle meets the projected disk
                (depth of the sphere centre on both sides): the memo's ``sl_ic``. ``"area"``: each cell's area is
                split among the spheres visible in it (the first ``depth_slots`` spheres on each of its corner
                rays, and the front sphere of the 8 corners around), exactly or on ``subpoints`` x ``subpoints``
                points: far more accurate per cell than criterion 1 (``README.md``, "The area criterion").
            lamps: "all", or names from :data:`LAMPS`.
            device: Warp device; the current default when None.
            depth_slots: Area criterion: spheres kept per corner ray and lamp, 1 to 6 (3: dense random packings;
                4: ordered packings; 5 with the exact resolver and `gather="deep"`: lattice balls within 0.32%).
            resolver: Area criterion: ``"subpoints"`` (each of S x S points of a cell goes to the first sphere that
                holds it; bitwise the same on CPU and GPU) or ``"exact"`` (circle arcs and cell edges; a last-bit
                difference of the trigonometry between CPU and GPU may move one unit of 4096 per cell).
            subpoints: Area criterion, sub-point resolver: points per cell edge, 1 to 16.
            gather: Area criterion: where each cell finds the spheres it splits among. ``"front"``: the D slots of
                its corner rays (and the ring's front spheres). ``"deep"``: also the other lamp's slots, after two
                rounds that drop from the depth pass the spheres one other sphere hides, so that ordered packings
                with see-through columns lose no buried visible sphere (several times the gather's work; the
                distributed lamp has only ``"front"``).
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
            frames: Frame averaging: run the lamp in this many fixed orientations (``frames.lamp_frame_rotations``:
                the grid's own first, then a low-discrepancy set turned by it) and average the forces; K > 1
                returns a :class:`FrameAveragedLamp`.
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
            max_bytes: Budget for the lamp's per-cell arrays [bytes] (the area criterion keeps ``depth_slots``
                keys per corner and lamp); over it, ValueError before anything is allocated.
            walls: Walls that bound the fluid, ``[(point, normal), ...]`` in world coordinates [m], the normal
                pointing from the wall into the fluid (a platen under a sample: ``[((0, 0, z0), (0, 0, 1))]``). In
                the memo's mode a ray's fluid lies on the fluid side of every wall; the fluid between a wall and
                the body pushes both, except where the wall crosses the body's span on that ray or the body rests
                on the wall (its nearest particle within ``validate.WALL_REST`` of its radius), which seals that
                end (docs/guide/walls.md; the walls' forces: :meth:`diagnostics` ``wall_forces``). On an axis
                no wall cuts, the forces still sum to zero; on one a wall cuts, the body's and the walls' forces
                sum to P times the lamp window that faces the fluid. With ``surfaces="all"`` the probe keeps rho
                from every wall and the fluid beyond the box lies on the fluid side of every wall: nothing on a
                wall's side is loaded, and a crossing goes to a wall when the wall is nearer than every sphere
                (ties to the sphere). Not with ``criterion="area"``. The planes live on the device in
                :attr:`walls` (one ``vec4`` (n, d) each, fluid where n . x > d), which a simulator may overwrite
                between replays.
            tolerance: Ask for accuracy instead of settings: the largest acceptable RMS per-particle force error,
                as a fraction of P pi rbar^2 (0.01 is 1%). The lamp then takes the cheapest estimator and cells per
                diameter that meet it in the speed-error table the package ships (:mod:`warp_lamp.tolerance` says
                the rule, the scenes and what it does not promise); needs a ``LampGridSpec`` as ``grid`` and
                leaves ``criterion`` and the area settings to the choice. :attr:`choice` (and
                :meth:`diagnostics`) say what was chosen.
            skin: ``surfaces="all"``: keep the exact test's decisions between updates (dry ones while the particles
                move less than a tenth of a cell, wet ones while the candidate that found them holds, crossing
                owners while they lead; ``WettedSurface(skin="auto")``); the results are bitwise the same without
                it. ``"auto"`` (default) or True: on; False: off, for runs where particles outrun the skin between
                most updates (a cut throwing chips: there it costs a little, `bench/NOTES.md`).
        """
        device = resolve_device(device)
        #: What ``tolerance=`` chose (None without it).
        self.choice = None
        if isinstance(grid, LampGridSpec):
            if tolerance is not None:
                self.choice = _tolerance_choice(
                    tolerance,
                    device,
                    criterion=criterion,
                    resolver=resolver,
                    depth_slots=depth_slots,
                    subpoints=subpoints,
                    gather=gather,
                    surfaces=surfaces,
                )
                chosen = self.choice.options()
                criterion = chosen["criterion"]
                resolver = chosen.get("resolver", resolver)
                depth_slots = chosen.get("depth_slots", depth_slots)
                subpoints = chosen.get("subpoints", subpoints)
                gather = chosen.get("gather", gather)
                grid = grid.build(self.choice.cells_per_diameter)
            else:
                grid = grid.build()
        elif tolerance is not None:
            raise ValueError(
                "tolerance: chooses the cells per diameter, so it needs a grid spec: "
                "ShiningLamp(LampGrid.spec(centers, radii), tolerance=...)"
            )
        if not isinstance(grid, LampGrid):
            raise TypeError(f"grid: expected a LampGrid, got {type(grid).__name__}")
        options = LampOptions.checked(
            criterion=criterion,
            lamps=lamps,
            depth_slots=depth_slots,
            resolver=resolver,
            subpoints=subpoints,
            gather=gather,
            follow=follow,
            split=split,
            order=order,
            surfaces=surfaces,
            probe_radius=probe_radius,
            max_rounds=max_rounds,
            max_bytes=max_bytes,
            walls=walls,
            skin=skin,
        )
        self._setup(grid, options, device)

    @classmethod
    def _build(cls, grid: LampGrid, options: LampOptions, device) -> ShiningLamp:
        """A lamp from options already checked (the host functions check them once for every frame)."""
        self = object.__new__(cls)
        self.choice = None
        self._setup(grid, options, device)
        return self

    def _setup(self, grid: LampGrid, options: LampOptions, device) -> None:
        if options.follow and not grid.is_box:
            raise ValueError("follow: needs the box form of the grid (LampGrid(lower, upper, cell) or enclosing)")
        self.grid = grid
        self.options = options
        self.device = device
        self.criterion = options.criterion
        self.surfaces = options.surfaces
        self.follow = options.follow
        self.lamp_mask = lamp_mask(options.lamps)
        #: Stage 1 (and 2): the frame's pose and the grid's rays; stage 3, the estimator: who takes each ray's
        #: pressure, as counts per particle.
        self.frame, self.estimator = self._stages(grid, options, device)
        # A frame's share of an average (FrameAveragedLamp sets it on its lamps).
        self._weight = 1.0
        self._no_active = wp.empty(0, dtype=wp.int32, device=device)
        self._no_pressure = wp.empty(0, dtype=wp.float32, device=device)
        self._input: LampInput | None = None
        self.n = 0

    def _stages(self, grid: LampGrid, options: LampOptions, device) -> tuple[LampFrame, Estimator]:
        # The frame and the estimator these options ask for (a hook: DistributedLamp swaps in the variants that
        # agree the following grid and reduce the keys across processes, distributed.py).
        frame = LampFrame(grid, device, follow=options.follow, walls=options.walls)
        return frame, options.estimator(frame)

    def __getattr__(self, name):
        # The estimator's buffers and steps (keys, diag, counts, unit, split, order, launch_seed, ...) read through
        # the lamp, as before the pipeline; only reached when the lamp has no such attribute itself.
        if name == "estimator" or name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.estimator, name)

    @property
    def origin(self) -> wp.array:
        """The frame origin in world coordinates [m], one ``vec3`` on the device (a simulator may overwrite it)."""
        return self.frame.origin

    @property
    def follow_shift(self) -> wp.array:
        """With ``follow``: the last update's shift of the frame origin in whole cells, one ``vec3i`` on the device."""
        return self.frame.follow_shift

    @property
    def walls(self) -> wp.array:
        """The walls' planes in world coordinates, one ``vec4`` (n, d) each, fluid where n . x > d."""
        return self.frame.walls

    @property
    def rotation(self) -> wp.array:
        """The frame's rotation, one ``mat33`` on the device (columns: the lamp axes in world coordinates)."""
        return self.frame.rotation

    def __repr__(self) -> str:
        return f"ShiningLamp({self.estimator.name}, {self.grid!r}, device={self.device})"

    def reserve(self, n: int) -> None:
        """Make room for ``n`` particles now, so that a later captured update need not allocate; this also fixes
        the depth pass's ``split`` for them.

        Args:
            n: Particle count, an integer >= 0.
        """
        self.estimator.reserve(check_integer("n", n))

    def forget(self) -> None:
        """Drop the last update's owners, so that the next update runs cold (for benchmarks; results are equal)."""
        self.estimator.forget()

    def reorder(self) -> None:
        """Sort the depth pass's work on each axis by the cell under each particle, at the last update's positions
        (a device radix sort; not inside a capture). Only a lamp with a split and ``order`` on keeps an order."""
        self.estimator.reorder()

    def update(self, positions: wp.array, radii: wp.array, active: wp.array | None = None, *, in_frame=False) -> None:
        """Recompute which particle each cell lights, and each particle's signed counts.

        Runs the pipeline on these inputs: the frame's move (with ``follow``), then the estimator's steps.

        Args:
            positions: Particle centres [m], warp array of vec3 (float32), shape (N,), on the lamp's device: world
                coordinates, which the lamp moves into its frame (:attr:`origin`, :attr:`rotation`).
            radii: Particle radii [m], warp array of float32, shape (N,).
            active: Optional warp array of int32, shape (N,): 0 makes a particle invisible (no shadow, no force).
            in_frame: ``positions`` are already in frame coordinates (``grid.to_frame``, computed by the caller,
                e.g. in float64 before the cast to float32), so the lamp moves nothing (and does not follow).
        """
        self._update(lamp_input(positions, radii, active, self.device, self._no_active, in_frame=in_frame))

    def _update(self, inp: LampInput) -> None:
        self.reserve(inp.n)
        self.n = inp.n
        self._input = inp
        # Stage 1: the frame follows the body (by whole cells), before any ray is cast.
        if self.follow and not inp.in_frame:
            self.launch_follow()
        self.frame.launch_walls(inp.in_frame)
        # Stages 2-4: the estimator casts the rays and writes the counts.
        self.estimator.update(inp)

    def launch_follow(self) -> None:
        """Update step 0, with ``follow``: find the body's box and move the frame origin by whole cells."""
        self.frame.launch_follow(self._input)

    def _area_per_unit(self) -> np.ndarray:
        # Cell area per count, with the frame's share of an average: the one expression host and device use.
        return self.grid.cell_area / (self.estimator.unit / self._weight)

    def force_factors(self, pressure) -> np.ndarray:
        """F[j, a]: world force component j [N] per count on lamp axis a (``frames.lamp_force_factors``), for
        the grid's rotation: the exact float64 forces are ``counts_numpy() @ F.T``, summed over a in order.

        Args:
            pressure: A number, three numbers (per lamp axis) or a stress tensor diagonal in the lamp frame [Pa].
        """
        from warp_lamp.frames import lamp_force_factors

        p = self._host_pressure(pressure)
        return lamp_force_factors(p, self._area_per_unit(), self.grid.rotation)

    def _host_pressure(self, pressure) -> np.ndarray:
        p, _ = lamp_pressure(pressure, self.grid.rotation)
        check_force_range(p, self.grid.cell_area, self.grid.counts[:, 0] * self.grid.counts[:, 1])
        return p

    def add_forces(self, forces: wp.array, pressure) -> None:
        """Add each particle's forces of the last update to ``forces``, in world coordinates (stage 5).

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
        if self._input is None:
            raise RuntimeError(f"add_forces: no counts yet; call {type(self).__name__}.update (or apply) first")
        check_warp_array("forces", forces, wp.vec3, self.device, "the lamp", self.n)
        launch_add_forces(
            self.estimator.counts,
            self._area_per_unit(),
            self.frame.force_rotation(self._input.in_frame),
            self._device_pressure(pressure),
            self.n,
            forces,
            self.device,
        )

    def _device_pressure(self, pressure) -> tuple:
        """(constant, array): a host pressure as three float64 values checked here, or a device array read by
        the kernel (1 or 3 float32 values)."""
        if isinstance(pressure, wp.array):
            check_warp_array("pressure", pressure, wp.float32, self.device, "the lamp")
            if pressure.shape[0] not in (1, 3):
                raise ValueError(f"pressure: a device array must hold 1 or 3 values, got {pressure.shape[0]}")
            return wp.vec3d(0.0, 0.0, 0.0), pressure
        p, _ = lamp_pressure(pressure, self.grid.rotation)
        cells = self.grid.counts[:, 0] * self.grid.counts[:, 1]
        check_force_range(p, self.grid.cell_area, cells)  # the exact range
        check_force_range(p, self.grid.cell_area, cells, float32=True)
        return wp.vec3d(*p), self._no_pressure

    def apply(self, positions: wp.array, radii: wp.array, forces: wp.array, pressure, *, active=None) -> None:
        """``update`` then ``add_forces``; arguments as there."""
        self.update(positions, radii, active)
        self.add_forces(forces, pressure)

    def counts_numpy(self) -> np.ndarray:
        """Signed counts of the last update, shape (N, 3), int64 (copies to the host)."""
        # .copy(): on the CPU .numpy() is a view of the device array, which the next update overwrites.
        return self.estimator.counts.numpy()[: 3 * self.n].reshape(self.n, 3).copy()

    def forces_numpy(self, pressure) -> np.ndarray:
        """The exact float64 forces of the last update in world coordinates [N], shape (N, 3) (a host copy: what
        :func:`lamp_forces` returns)."""
        return exact_forces(
            self.counts_numpy(), self._host_pressure(pressure), self._area_per_unit(), self.grid.rotation
        )

    def wall_forces_numpy(self, pressure) -> np.ndarray:
        """The exact float64 force on each wall in world coordinates [N], shape (W, 3): the reaction of the rays
        it stopped before any sphere."""
        counts = self.estimator.wall_counts.numpy().reshape(-1, 3)
        return exact_forces(counts, self._host_pressure(pressure), self._area_per_unit(), self.grid.rotation)

    def frame_origin(self) -> np.ndarray:
        """The frame origin of the last update in frame coordinates [m], float64: ``grid.origin``, moved by whole
        cells with ``follow`` (reads the device: a synchronisation). A grid ``LampGrid(frame_origin, ...,
        rotation=grid.rotation)`` with the same cells and counts reproduces the last update bitwise."""
        return self.frame.frame_origin()

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
        if positions is not None:
            positions = check_positions("positions", positions, self.n)
        if moment_origin is not None:
            moment_origin = check_vec3("moment_origin", moment_origin)
        out = self.estimator.diagnostics()
        if isinstance(out, LampDiagnostics):
            out.choice = self.choice
        if pressure is None:
            return out
        f = self.forces_numpy(pressure)
        out.force = f.sum(axis=0)
        if self.frame.n_walls:
            out.wall_forces = self.wall_forces_numpy(pressure)
        if positions is not None and isinstance(out, LampDiagnostics):
            x = positions
            if moment_origin is None:
                moment_origin = x[out.surface].mean(axis=0) if out.surface.any() else np.zeros(3)
            out.moment_origin = np.asarray(moment_origin, dtype=np.float64)
            out.moment = np.cross(x - out.moment_origin, f).sum(axis=0)
        return out


class FrameAveragedLamp:
    """Frame averaging: K :class:`ShiningLamp`\\ s in fixed orientations (``frames.lamp_frame_rotations``: the grid's
    own first, then a low-discrepancy set turned by it), each loading its particles with 1/K of the pressure.

    Each frame's grid is the smallest box in that frame around ``grid``'s box, with its cells (cubic cells needed).
    The methods are :class:`ShiningLamp`'s; ``update`` runs every frame's pass (all recorded in a capture), and
    :attr:`frames` lists the per-frame lamps for their diagnostics. The pressure must be isotropic (one value, or a
    device array of one value): the lamp axes turn from frame to frame.
    """

    def __init__(self, grid: LampGrid, *, frames: int, device=None, follow: bool = False, tolerance=None, **options):
        """Args: as :class:`ShiningLamp` (``frames`` >= 2; ``follow`` and ``tolerance`` are not supported)."""
        if tolerance is not None:
            raise ValueError("tolerance: not with frame averaging (its table is measured for one frame)")
        if not isinstance(grid, LampGrid):
            raise TypeError(f"grid: expected a LampGrid, got {type(grid).__name__}")
        frames = _check_int("frames", frames, 2, 1 << 10)
        if follow:
            raise ValueError("frames: frame averaging with follow=True is not supported; follow one frame")
        checked = LampOptions.checked(**options)
        if checked.walls is not None and len(checked.walls):
            # A turned frame's lamp axes all cut the wall, so no axis balances, and the walls' reactions would need
            # averaging over frames in world coordinates: not built.
            raise ValueError(f"walls: {FRAMES_WALLS}")
        area = checked.criterion == "area"
        grids = [grid.rotated(r) for r in lamp_frame_rotations(frames)]
        need = sum(g.n_samples if area else g.n_cells for g in grids) * 16 * (checked.depth_slots if area else 1)
        check_budget(need, checked.max_bytes, f"frames: {frames} frames need {need:,} bytes", "raise max_bytes")
        device = resolve_device(device)
        #: The per-frame lamps.
        self.frames = [ShiningLamp._build(g, checked, device) for g in grids]
        for child in self.frames:
            child._weight = 1.0 / frames
        self.grid = grid
        self.options = checked
        self.device = device
        self.criterion = checked.criterion
        self.lamp_mask = self.frames[0].lamp_mask
        self.unit = self.frames[0].estimator.unit
        self.follow = False
        self.n = 0
        self._updated = False

    def __repr__(self) -> str:
        return f"FrameAveragedLamp({len(self.frames)} frames of {self.frames[0]!r})"

    def reserve(self, n: int) -> None:
        """As :meth:`ShiningLamp.reserve`, for every frame."""
        n = check_integer("n", n)
        for child in self.frames:
            child.reserve(n)

    def forget(self) -> None:
        """As :meth:`ShiningLamp.forget`, for every frame."""
        for child in self.frames:
            child.forget()

    def reorder(self) -> None:
        """As :meth:`ShiningLamp.reorder`, for every frame."""
        for child in self.frames:
            child.reorder()

    def update(self, positions: wp.array, radii: wp.array, active: wp.array | None = None, *, in_frame=False) -> None:
        """Every frame's update, on world positions (each frame moves them itself)."""
        if in_frame:
            raise ValueError("in_frame: frame averaging needs world positions (each frame moves them itself)")
        inp = lamp_input(positions, radii, active, self.device, self.frames[0]._no_active)
        for child in self.frames:
            child._update(inp)
        self.n = inp.n
        self._updated = True

    def _steps(self, name: str) -> None:
        for child in self.frames:
            getattr(child, name)()

    def launch_seed(self) -> None:
        """Every frame's seed step."""
        self._steps("launch_seed")

    def launch_depth(self) -> None:
        """Every frame's depth step."""
        self._steps("launch_depth")

    def launch_scatter(self) -> None:
        """Every frame's scatter step."""
        self._steps("launch_scatter")

    def _check_pressure(self, pressure) -> None:
        # The lamp axes turn from frame to frame, so a per-axis pressure would load each frame differently: only
        # an isotropic one averages. A device array is checked by its length (reading its values would sync).
        if isinstance(pressure, wp.array):
            if pressure.shape[0] != 1:
                raise ValueError(f"pressure: {FRAMES_ISOTROPIC}: a device array of 1 value, got {pressure.shape[0]}")
        elif np.ptp(lamp_pressure(pressure, self.frames[0].grid.rotation)[0]) > 0:
            raise ValueError(f"frames: {FRAMES_ISOTROPIC}")

    def add_forces(self, forces: wp.array, pressure) -> None:
        """Every frame adds its share of the forces (as :meth:`ShiningLamp.add_forces`; isotropic pressure)."""
        if not self._updated:
            raise RuntimeError("add_forces: no counts yet; call ShiningLamp.update (or apply) first")
        self._check_pressure(pressure)
        for child in self.frames:
            child.add_forces(forces, pressure)

    def apply(self, positions: wp.array, radii: wp.array, forces: wp.array, pressure, *, active=None) -> None:
        """``update`` then ``add_forces``; arguments as there."""
        self.update(positions, radii, active)
        self.add_forces(forces, pressure)

    def counts_numpy(self) -> np.ndarray:
        """Each frame's counts, shape (frames, N, 3), int64."""
        return np.stack([child.counts_numpy() for child in self.frames])

    def forces_numpy(self, pressure) -> np.ndarray:
        """The exact float64 forces summed over the frames [N], shape (N, 3)."""
        self._check_pressure(pressure)
        return sum(child.forces_numpy(pressure) for child in self.frames)

    def frame_origin(self) -> np.ndarray:
        """The grid's frame origin [m] (frame averaging does not follow)."""
        return self.grid.origin.copy()

    def force_factors(self, pressure) -> np.ndarray:
        """One per frame: use ``lamp.frames[k].force_factors``."""
        raise ValueError("force_factors: one per frame; use lamp.frames[k].force_factors")

    def diagnostics(self, positions=None, pressure=None, *, moment_origin=None):
        """One per frame: use ``lamp.frames[k].diagnostics()``."""
        raise ValueError("diagnostics: one per frame; use lamp.frames[k].diagnostics()")


def _enclosing(c: np.ndarray, r: np.ndarray, cells_per_diameter, rotation, probe: float, max_bytes) -> LampGrid:
    """The default grid around host particles; a budget that only the probe's margin breaks names the probe."""
    if len(r) == 0:
        return LampGrid([0.0] * 3, [1.0] * 3, 1.0)
    try:
        return LampGrid.enclosing(
            c, r, cells_per_diameter=cells_per_diameter, rotation=rotation, probe_radius=probe, max_bytes=max_bytes
        )
    except ValueError:
        if probe > 0:
            LampGrid.enclosing(c, r, cells_per_diameter=cells_per_diameter, rotation=rotation, max_bytes=max_bytes)
            raise ValueError(
                f"probe_radius: {probe:.6g} m is {probe / (2.0 * float(r.mean())):.3g} mean particle diameters; the "
                "wetted surface needs a margin of probe_radius around the particles, and that grid exceeds "
                "max_bytes: take a smaller probe_radius (a quarter to two mean radii; README 'Every wetted "
                "surface'), larger cells, or a larger max_bytes"
            ) from None
        raise


def _warn_fines(radii: np.ndarray, grid: LampGrid, criterion) -> None:
    """Warn where the area criterion may give particles no load: it splits a cell's area among the spheres that
    the rays at the cell's corners meet, so a sphere narrower than a cell can fall between those rays and get
    nothing (criteria 0 and 1 sample it instead: right on average over positions)."""
    if criterion != "area" or len(radii) == 0:
        return
    h = float(np.min(grid.cell))
    fines = int(np.count_nonzero(2.0 * radii < h))
    if fines:
        warnings.warn(
            f"criterion 'area': {fines:,} particle{'s' if fines > 1 else ''} narrower than a cell ({h:.4g}; "
            f"smallest diameter {2.0 * float(radii.min()):.4g}) may fall between the cells' corner rays and get no "
            "load; use more cells per diameter (cells under the smallest diameter) or criterion 1 for such fines",
            stacklevel=3,
        )


def _host_update(c, r, mask, grid: LampGrid, options: LampOptions, device, *, weight: float = 1.0) -> ShiningLamp:
    """One update on checked host data: positions moved into the grid's frame in float64, then cast."""
    _warn_fines(r, grid, options.criterion)
    n = c.shape[0]
    if options.walls is not None:
        visible = c if mask is None else c[np.asarray(mask) != 0]
        rv = r if mask is None else r[np.asarray(mask) != 0]
        message = walls_behind_message(visible, rv, options.walls)
        if message:
            warnings.warn(message, stacklevel=user_stacklevel())
    # One update: a skin would only pay for certificates that no later update reads.
    lamp = ShiningLamp._build(grid, dataclasses.replace(options, skin=False), device)
    lamp._weight = weight
    pos = wp.array(grid.to_frame(c).astype(np.float32).reshape(n, 3), dtype=wp.vec3, device=device)
    rad = wp.array(r.astype(np.float32), dtype=wp.float32, device=device)
    act = None if mask is None else wp.array(mask, dtype=wp.int32, device=device)
    lamp._update(lamp_input(pos, rad, act, device, lamp._no_active, in_frame=True))
    return lamp


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
    depth_slots: int = 3,
    resolver: str = "subpoints",
    subpoints: int = 8,
    gather: str = "front",
    surfaces: str = "first",
    probe_radius: float | None = None,
    max_rounds: int = DEFAULT_MAX_ROUNDS,
    split: int | str = "auto",
    order: bool | str = "auto",
    max_bytes: int = DEFAULT_MAX_BYTES,
    walls=None,
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
            ``vec3d`` array on any device. Non-finite centres are refused, naming the first bad index.
        radii: Particle radii [m], shape (N,), or one number for all (NumPy, or a warp array); each finite and > 0.
        grid: Lamp grids; by default :meth:`LampGrid.enclosing` with ``cells_per_diameter`` (a placeholder
            one-cell grid when there are no particles); with ``surfaces="all"`` its margin grows by
            ``probe_radius``.
        cells_per_diameter: Cells per mean particle diameter for the default grid.
        criterion: 1, cell-centre ray (default); 0, cell rectangle meets the projected disk; ``"area"``, each
            cell's area split among the spheres visible in it (:class:`ShiningLamp`).
        lamps: "all", or names from :data:`LAMPS` ("-x" is the lamp at minus infinity, pushing toward +x).
        active: Optional mask, shape (N,), booleans or numbers (nonzero: active): inactive particles are
            invisible (no shadow, no force).
        device: Warp device; by default where warp-array inputs live, else the current default.
        depth_slots: Area criterion: spheres kept per corner ray (:class:`ShiningLamp`).
        resolver: Area criterion: ``"subpoints"`` or ``"exact"`` (:class:`ShiningLamp`).
        subpoints: Area criterion, sub-point resolver: points per cell edge (:class:`ShiningLamp`).
        gather: Area criterion: ``"front"`` or ``"deep"`` (:class:`ShiningLamp`).
        surfaces: ``"first"`` (the memo's lamp) or ``"all"`` (every wetted surface; :class:`ShiningLamp`).
        probe_radius: ``surfaces="all"``: the probe radius rho [m] (:class:`ShiningLamp`).
        max_rounds: ``surfaces="all"``: bound on the connectivity solve's rounds.
        split: The depth pass's threads per (sphere, axis) (:class:`ShiningLamp`; the result never depends on it).
        order: Sort the depth pass's work by cell (:class:`ShiningLamp`; the result never depends on it).
        max_bytes: Budget for the lamp's device arrays [bytes].
        walls: Walls that bound the fluid, ``[(point, normal), ...]`` in world coordinates (:class:`ShiningLamp`).
    """
    device = check_device_match(device, centers=centers, radii=radii, active=active)
    c, r = check_particles(centers, radii)
    options = LampOptions.checked(
        criterion=criterion,
        lamps=lamps,
        depth_slots=depth_slots,
        resolver=resolver,
        subpoints=subpoints,
        gather=gather,
        surfaces=surfaces,
        probe_radius=probe_radius,
        max_rounds=max_rounds,
        split=split,
        order=order,
        max_bytes=max_bytes,
        walls=walls,
    )
    cells_per_diameter = check_positive("cells_per_diameter", cells_per_diameter)
    mask = None if active is None else check_mask("active", active, c.shape[0])
    if grid is None:
        grid = _enclosing(c, r, cells_per_diameter, None, options.probe_radius or 0.0, max_bytes)
    elif not isinstance(grid, LampGrid):
        raise TypeError(f"grid: expected a LampGrid, got {type(grid).__name__}")
    return _host_update(c, r, mask, grid, options, device)


def lamp_forces(
    centers,
    radii,
    pressure,
    *,
    grid: LampGrid | None = None,
    cells_per_diameter: float = 4,
    criterion: int | str = 1,
    lamps="all",
    active=None,
    device=None,
    frames: int = 1,
    depth_slots: int = 3,
    resolver: str = "subpoints",
    subpoints: int = 8,
    gather: str = "front",
    surfaces: str = "first",
    probe_radius: float | None = None,
    max_rounds: int = DEFAULT_MAX_ROUNDS,
    split: int | str = "auto",
    order: bool | str = "auto",
    max_bytes: int = DEFAULT_MAX_BYTES,
    walls=None,
    tolerance: float | None = None,
) -> np.ndarray:
    """Shining-lamp forces on a body of spheres under fluid pressure, in world coordinates [N], float64.

    Each cell of the three lamp grids shines from both ends of its axis; the first sphere its ray meets takes
    P_a A_cell along the ray, at its centre (or, with ``criterion="area"``, each visible sphere its share of the
    cell). Opposite lamps light the same cells, so with all six lamps on the forces sum to exactly zero on every
    axis, in any order of summation (also in a rotated frame, and averaged over frames: each world component is a
    sum of integer multiples of powers of two); with a subset of lamps only axes whose two lamps are on balance.

    The float64 forces returned are exact multiples of the rounded P_a A_a (see :func:`pressure_area`), so they
    sum to exactly zero on every balanced axis, in any order of summation (``math.fsum`` and a plain ``sum``
    agree). :class:`ShiningLamp`'s float32 forces are these, rounded once each.

    Host data is checked once, here: a non-finite centre or a radius <= 0 raises ValueError naming the first bad
    index (a :class:`ShiningLamp` on device arrays skips such particles and counts them instead, as a device path
    must).

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
        grid: Lamp grids; by default :meth:`LampGrid.enclosing` with ``cells_per_diameter`` (margin grown by
            ``probe_radius`` with ``surfaces="all"``).
        cells_per_diameter: Cells per mean particle diameter for the default grid.
        criterion: 1 (cell-centre ray), 0 (cell rectangle meets the disk) or ``"area"`` (:class:`ShiningLamp`).
        lamps: "all", or names from :data:`LAMPS`.
        active: Optional mask, shape (N,): inactive particles cast no shadow and take no force.
        device: Warp device; by default where warp-array inputs live, else the current default.
        frames: Average over this many fixed lamp frames (``frames.lamp_frame_rotations``), each with its own
            enclosing grid (or ``grid`` turned, :meth:`LampGrid.rotated`); needs an isotropic pressure.
        depth_slots: Area criterion: spheres kept per corner ray, 1 to 6.
        resolver: Area criterion: ``"subpoints"`` or ``"exact"``.
        subpoints: Area criterion, sub-point resolver: points per cell edge, 1 to 16.
        surfaces: ``"first"`` (the memo's lamp) or ``"all"`` (every wetted surface).
        probe_radius: ``surfaces="all"``: the probe radius rho [m].
        max_rounds: ``surfaces="all"``: bound on the connectivity solve's rounds.
        split: The depth pass's threads per (sphere, axis); the result never depends on it.
        order: Sort the depth pass's work by cell; the result never depends on it.
        max_bytes: Budget for the lamp's device arrays [bytes].
        walls: Walls that bound the fluid, ``[(point, normal), ...]`` in world coordinates [m], normals pointing
            into the fluid (:class:`ShiningLamp`): a platen under a sample, or the level where the fluid stops.
            The walls' reactions are not in the returned forces: ``lamp_update(...).wall_forces_numpy(P)``.
        tolerance: Ask for accuracy instead of settings: the largest acceptable RMS per-particle force error, as a
            fraction of P pi rbar^2; the cheapest criterion, area settings and cells per diameter that meet it in
            the package's speed-error table are used (:mod:`warp_lamp.tolerance`; leave those arguments out).

    Returns:
        Forces [N] (units of pressure times length squared), shape (N, 3), float64.

    Raises:
        ValueError: bad data or options, naming the argument (and the first bad index), or a pressure whose
            P A leaves the exact range.
    """
    if grid is not None and not isinstance(grid, LampGrid):
        raise TypeError(f"grid: expected a LampGrid, got {type(grid).__name__}")
    p, frame = lamp_pressure(pressure, None if grid is None else grid.rotation)
    frames = _check_int("frames", frames, 1, 1 << 10)
    if frames > 1 and np.ptp(p) > 0:
        raise ValueError(f"frames: {FRAMES_ISOTROPIC}")
    device = check_device_match(device, centers=centers, radii=radii, active=active)
    c, r = check_particles(centers, radii)
    if tolerance is not None:
        if grid is not None:
            raise ValueError("tolerance: chooses the cells per diameter, so leave out grid (or leave out tolerance)")
        chosen = _tolerance_choice(
            tolerance,
            device,
            criterion=criterion,
            resolver=resolver,
            depth_slots=depth_slots,
            subpoints=subpoints,
            gather=gather,
            surfaces=surfaces,
            cells_per_diameter=cells_per_diameter,
        )
        cells_per_diameter = chosen.cells_per_diameter
        opts = chosen.options()
        criterion = opts["criterion"]
        resolver, depth_slots = opts.get("resolver", resolver), opts.get("depth_slots", depth_slots)
        subpoints = opts.get("subpoints", subpoints)
        gather = opts.get("gather", gather)
    options = LampOptions.checked(
        criterion=criterion,
        lamps=lamps,
        depth_slots=depth_slots,
        resolver=resolver,
        subpoints=subpoints,
        gather=gather,
        surfaces=surfaces,
        probe_radius=probe_radius,
        max_rounds=max_rounds,
        split=split,
        order=order,
        max_bytes=max_bytes,
        walls=walls,
    )
    if frames > 1 and options.walls is not None and len(options.walls):
        raise ValueError(f"walls: {FRAMES_WALLS}")
    cells_per_diameter = check_positive("cells_per_diameter", cells_per_diameter)
    mask = None if active is None else check_mask("active", active, c.shape[0])
    base = np.eye(3) if frame is None else frame
    total = np.zeros((len(r), 3))
    for rotation in lamp_frame_rotations(frames):
        if grid is not None:
            g = grid.rotated(rotation)
        else:
            g = _enclosing(c, r, cells_per_diameter, base @ rotation, options.probe_radius or 0.0, max_bytes)
        lamp = _host_update(c, r, mask, g, options, device, weight=1.0 / frames)
        total = total + lamp.forces_numpy(p)
    return total
