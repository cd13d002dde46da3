"""The lamp's pipeline, stage by stage: frame -> rays -> estimator -> counts -> forces.

Every lamp, whatever its mode, is the same five stages, each a small object with thin launchers (one comment
each, as Newton's solvers share one Model/State):

1. **Frame** (:class:`LampFrame`): where the lamp stands. Its pose lives in two device arrays (origin, rotation)
   that a simulator may overwrite between graph replays; with ``follow`` it moves by whole cells after the body.
2. **Rays** (:meth:`LampFrame.rays`): the grid as the kernels read it: cell-centre rays, or the cell corners the
   area criterion samples.
3. **Estimator** (:class:`Estimator`, implementations in :mod:`warp_lamp.estimators`): which particle each ray's
   pressure goes to. It reads the particles once they are checked (:class:`LampInput`) and writes
4. **counts**: signed integer counts per particle and lamp axis, in units of :attr:`Estimator.unit` per cell;
5. **forces** (:func:`launch_add_forces`, :func:`exact_forces`): counts times P A per unit, in world
   coordinates, exactly balanced.

Input arrays are checked once, where they enter (:func:`lamp_input`), and travel down as a :class:`LampInput`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_lamp.frames import lamp_force_factors
from warp_lamp.grid import LampGrid
from warp_lamp.kernels import lamp as lamp_kernels
from warp_lamp.kernels.grid import LampGridParams
from warp_lamp.kernels.walls import LampWalls
from warp_lamp.validate import WALL_REST, check_particle_arrays

__all__ = ["Estimator", "LampFrame", "LampInput", "exact_forces", "lamp_input", "launch_add_forces"]


@dataclass
class LampInput:
    """The particles of one update, checked once at the public entry.

    Attributes:
        particles: The kernels' view (positions, radii, mask, count).
        n: Particle count N.
        in_frame: Positions are already frame coordinates (the lamp moves nothing and does not follow).
        active: The mask as the caller gave it (None: all active).
    """

    particles: lamp_kernels.LampParticles
    n: int
    in_frame: bool
    active: wp.array | None


def lamp_input(
    positions, radii, active, device, no_active: wp.array, *, in_frame: bool = False, owner: str = "the lamp"
) -> LampInput:
    """Check an update's device arrays (dtype, shape, device; no data is read, so a capture can record it) and
    pack them for the kernels.

    Args:
        positions: Particle centres [m], warp array of vec3 (float32), shape (N,).
        radii: Particle radii [m], warp array of float32, shape (N,).
        active: Optional warp array of int32, shape (N,); None: all active.
        device: The lamp's device.
        no_active: An empty int32 array on ``device`` that stands for "all active" (made once by the caller, so
            that an update allocates nothing).
        in_frame: The positions are frame coordinates already.
        owner: Who checks, for the messages.
    """
    n = check_particle_arrays(positions, radii, active, device, owner)
    p = lamp_kernels.LampParticles()
    p.positions = positions
    p.radii = radii
    p.active = active if active is not None else no_active
    p.n = n
    return LampInput(p, n, bool(in_frame), active)


class LampFrame:
    """Where the lamp stands: the grid's pose on the device, and the following grid.

    :attr:`origin` (one ``vec3``, the frame origin in world coordinates) and :attr:`rotation` (one ``mat33``) are
    read by every kernel at run time, so a simulator may overwrite them between replays of a captured graph;
    with ``follow`` the frame moves itself by whole cells so that the body stays centred in the grid.
    """

    def __init__(self, grid: LampGrid, device, *, follow: bool = False, walls: np.ndarray | None = None):
        self.grid = grid
        self.device = device
        self.follow = bool(follow)
        #: The frame's pose on the device: origin (world coordinates, one vec3) and rotation (one mat33).
        self.origin, self.rotation = grid.pose_arrays(device)
        self._identity = grid.pose_arrays(device, in_frame=True)
        self._params = {}
        walls = np.zeros((0, 4)) if walls is None else np.asarray(walls, dtype=np.float64)
        #: Walls that bound the fluid.
        self.n_walls = len(walls)
        #: Their planes in world coordinates, (W, 4) float64, as ``check_walls`` gave them.
        self.wall_planes = walls
        #: The walls' planes in world coordinates, (n, d) per wall with the fluid where n . x > d: one ``vec4`` each
        #: on the device (a simulator may overwrite them between replays, e.g. to move a platen).
        self.walls = wp.array(walls.astype(np.float32).reshape(-1, 4), dtype=wp.vec4, device=device)
        # In the frame: derived on the device at each update from :attr:`walls` (so that a simulator may move them),
        # with the frame's pose for world positions, with the grid's own float64 pose for positions in the frame
        # (from the float64 planes while :attr:`walls` still holds them as given).
        self._walls_frame = wp.zeros(self.n_walls, dtype=wp.vec4, device=device)
        #: Per wall, the smallest gap (n . c - d - r) / r over the particles at the last update (float32).
        self.wall_gap = wp.zeros(self.n_walls, dtype=wp.float32, device=device)
        self._grid_pose = (wp.vec3d(*grid.world_origin), wp.mat33d(*grid.rotation.ravel()))
        self._walls_given = wp.array(walls.reshape(-1, 4), dtype=wp.vec4d, device=device)
        self._walls = LampWalls()
        self._walls.frame = self._walls_frame
        self._walls.n = self.n_walls
        self._walls.gap = self.wall_gap
        self._walls.rest = WALL_REST
        if self.follow:
            self.follow_shift = wp.zeros(1, dtype=wp.vec3i, device=device)
            self._bounds = wp.array([3.0e38] * 3 + [-3.0e38] * 3, dtype=wp.float32, device=device)
            # The grid never changes, so its base origin, cells and box are kernel constants, made once.
            base = grid.world_origin
            self._follow_base = (
                wp.vec3(*base.astype(np.float32)),
                wp.vec3d(*base),
                wp.vec3d(*grid.box_cell),
                wp.vec3i(*grid.box_counts),
            )

    def rays(self, in_frame: bool, *, corners: bool = False) -> LampGridParams:
        """The grid's rays for the kernels: one per cell (centre or rectangle), or one per cell corner (the area
        criterion's samples); for world positions (the frame's pose) or for positions already in the frame."""
        key = (bool(in_frame), bool(corners))
        if key not in self._params:
            origin, rotation = self._identity if in_frame else (self.origin, self.rotation)
            self._params[key] = self.grid.params(origin, rotation, corners=corners)
        return self._params[key]

    def walls_view(self, in_frame: bool) -> LampWalls:
        """The walls in the frame, as the kernels read them (as :meth:`launch_walls` last placed them)."""
        return self._walls

    def launch_walls(self, in_frame: bool) -> None:
        """Place the walls in the frame of this update: the current pose for world positions, the grid's own for
        positions already in the frame; reset their gaps (``walls_contact``)."""
        if not self.n_walls:
            return
        if in_frame:
            kernel, inputs = lamp_kernels.walls_to_grid_frame, [*self._grid_pose, self.walls, self._walls_given]
        else:
            kernel, inputs = lamp_kernels.walls_to_frame, [self.origin, self.rotation, self.walls]
        wp.launch(
            kernel, dim=self.n_walls, inputs=inputs, outputs=[self._walls_frame, self.wall_gap], device=self.device
        )

    def force_rotation(self, in_frame: bool) -> wp.array:
        """The rotation that takes the last update's forces to the caller's coordinates."""
        return self._identity[1] if in_frame else self.rotation

    def launch_follow(self, inp: LampInput) -> None:
        """Find the body's box and move the frame origin by whole cells (capacity fixed at construction)."""
        origin32, origin, cell, box = self._follow_base
        wp.launch(
            lamp_kernels.lamp_follow_bounds,
            dim=inp.n,
            inputs=[inp.particles, origin32, self.rotation],
            outputs=[self._bounds],
            device=self.device,
        )
        self.launch_agree_bounds()
        wp.launch(
            lamp_kernels.lamp_follow_shift,
            dim=1,
            inputs=[origin, cell, box, self.rotation],
            outputs=[self._bounds, self.follow_shift, self.origin],
            device=self.device,
        )

    def launch_agree_bounds(self) -> None:
        """Between the box and the move: the box of the particles this process holds is the body's (a hook: where
        the particles are split across processes, ``distributed.py`` reduces the box over them here)."""

    def frame_origin(self) -> np.ndarray:
        """The frame origin of the last update in frame coordinates [m], float64 (a device read with ``follow``)."""
        if not self.follow:
            return self.grid.origin.copy()
        k = self.follow_shift.numpy()[0].astype(np.float64)
        return self.grid.origin + k * self.grid.box_cell


class Estimator:
    """Which particle each ray's pressure goes to: the one interface every lamp mode implements.

    An estimator owns its device buffers (sized by :meth:`reserve`, so that a captured update allocates nothing)
    and writes :attr:`counts`: three int64 per particle, the signed units of cell area each lamp axis gave it (+
    for the low lamp, - for the high one), :attr:`unit` units per whole cell. Subclasses set :attr:`name`,
    :attr:`unit`, :attr:`nbytes` and :attr:`steps`, and implement :meth:`reserve`, :meth:`update`,
    :meth:`diagnostics`; :meth:`forget` and :meth:`reorder` are optional.

    Attributes:
        name: The mode, for messages and the lamp's ``repr``.
        unit: Counts per whole cell.
        counts: int64 counts, 3 per particle (at least 3 N after :meth:`reserve`).
        n: Particle count of the last update.
        nbytes: Device bytes of the per-cell buffers.
        steps: Names of the update's steps, in order, each a method ``launch_<step>`` (benchmarks time them).
    """

    name = "estimator"
    unit = 1
    steps: tuple[str, ...] = ()

    def __init__(self, frame: LampFrame, lamp_mask: int):
        self.frame = frame
        self.grid = frame.grid
        self.device = frame.device
        self.lamp_mask = lamp_mask
        self.counts = wp.zeros(0, dtype=wp.int64, device=self.device)
        self.n = 0
        self.nbytes = 0
        self._input: LampInput | None = None

    def reserve(self, n: int) -> None:
        """Make room for ``n`` particles (not inside a capture: it may allocate)."""
        raise NotImplementedError

    def update(self, inp: LampInput) -> None:
        """Run the steps on checked particles: counts for every particle, units of :attr:`unit` per cell."""
        raise NotImplementedError

    def forget(self) -> None:
        """Drop what the last update left to start from (a benchmark's cold start; results never depend on it)."""

    def reorder(self) -> None:
        """Re-sort the work by cell at the last update's positions, where the estimator keeps an order."""

    def diagnostics(self):
        """What the last update found, as host copies (a dataclass of the mode's own)."""
        raise NotImplementedError

    def _check_room(self, n: int, have: int) -> bool:
        """Whether ``n`` particles need new buffers; inside a capture that is an error naming the way out."""
        if n <= have:
            return False
        if self.device.is_capturing:
            raise RuntimeError(
                f"positions: {n} particles exceed the {have} reserved; call ShiningLamp.reserve(n) or one eager "
                "update before wp.ScopedCapture"
            )
        return True


def launch_add_forces(
    counts: wp.array, area_per_unit: np.ndarray, rotation: wp.array, pressure, n: int, forces: wp.array, device
) -> None:
    """forces[i] += F counts[i]: P A per unit, rounded so that every sum is exact (``frames.lamp_force_factors``),
    turned into world coordinates by ``rotation``; a constant pressure (3 values) or a device array of 1 or 3
    values read when the kernel runs."""
    if n == 0:
        return
    const, arr = pressure
    wp.launch(
        lamp_kernels.lamp_add_forces,
        dim=n,
        inputs=[counts, wp.vec3d(*area_per_unit), rotation, const, arr],
        outputs=[forces],
        device=device,
    )


def exact_forces(counts: np.ndarray, pressure: np.ndarray, area_per_unit: np.ndarray, rotation) -> np.ndarray:
    """The exact float64 forces of host counts (N, 3) [N], in world coordinates: counts times the rounded factors,
    summed over the lamp axes in order (as the device does)."""
    f = lamp_force_factors(pressure, area_per_unit, rotation)
    return (counts[:, :1] * f[:, 0] + counts[:, 1:2] * f[:, 1]) + counts[:, 2:3] * f[:, 2]
