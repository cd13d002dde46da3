"""The lamp for engines that hold their particles on the host: float64 NumPy positions in, float64 forces out."""

from __future__ import annotations

import time

import numpy as np
import warp as wp

from warp_lamp.frames import lamp_pressure
from warp_lamp.grid import LampGrid
from warp_lamp.lamp import ShiningLamp
from warp_lamp.validate import check_mask, check_particles, check_positions, check_walls

__all__ = ["CallTimings", "EngineLamp"]


class EngineLamp:
    """A :class:`~warp_lamp.ShiningLamp` kept between calls, for engines that hand out NumPy arrays.

    Each :meth:`forces` call takes the particles' float64 centres (and radii, when they change), moves them into
    the grid's frame in float64 before the cast to float32 (as :func:`warp_lamp.lamp_forces` does), updates the
    lamp from its last owners, and returns the exact float64 forces. Without ``follow`` or frame averaging the
    forces equal ``lamp_forces(centers, radii, pressure, grid=lamp.grid, ...)`` bitwise. The grid is fitted around
    the first positions (:meth:`LampGrid.enclosing`, with room for the body to move by a mean diameter); a body
    that moves farther needs ``follow=True``, which moves the grid by whole cells with the body.

    Attributes:
        grid: The lamp grids.
        lamp: The :class:`~warp_lamp.ShiningLamp`.
        pressure: The pressure the next call applies (a number, three per-axis numbers or a stress tensor
            diagonal in the grid's frame [Pa]); may be changed between calls (a servo).
        seconds: Seconds the last :meth:`forces` call took (the lamp's own cost: upload, update, forces).
    """

    def __init__(
        self,
        centers,
        radii,
        pressure,
        *,
        grid: LampGrid | None = None,
        cells_per_diameter: float = 4,
        follow: bool = False,
        device="cpu",
        **lamp_options,
    ):
        """Set up the adapter.

        Args:
            centers: Particle centres [m], shape (N, 3), N >= 1: where the grid is fitted.
            radii: Particle radii [m], shape (N,).
            pressure: Fluid pressure [Pa], as :meth:`ShiningLamp.add_forces` takes it on the host.
            grid: Lamp grids; by default :meth:`LampGrid.enclosing` around ``centers`` with ``cells_per_diameter``
                (its margin grown by ``probe_radius`` with ``surfaces="all"``).
            cells_per_diameter: Cells per mean particle diameter of the default grid.
            follow: Move the grid with the body by whole cells (:class:`ShiningLamp`'s ``follow``).
            device: Warp device the lamp runs on ("cpu" by default: the engine's arrays live on the host).
            **lamp_options: Further keywords of :class:`ShiningLamp` (``criterion``, ``lamps``, ``surfaces``,
                ``probe_radius``, ``frames``, ...).
        """
        c, r = check_particles(centers, radii)
        if len(r) == 0:
            raise ValueError("centers: need at least one particle to fit the lamp's grid")
        # Follow and frame averaging need world positions: they go in relative to a fixed float64 reference
        # (the first mean centre, unless a grid is given in world coordinates), which keeps the float32
        # positions small; the forces do not depend on it. Otherwise positions go into the grid's frame in float64.
        self._world = bool(follow) or lamp_options.get("frames", 1) != 1
        self.reference = c.mean(axis=0) if self._world and grid is None else np.zeros(3)
        if grid is None:
            probe = lamp_options.get("probe_radius") if lamp_options.get("surfaces") == "all" else None
            grid = LampGrid.enclosing(
                c - self.reference, r, cells_per_diameter=cells_per_diameter, probe_radius=probe or 0.0
            )
        elif not isinstance(grid, LampGrid):
            raise TypeError(f"grid: expected a LampGrid, got {type(grid).__name__}")
        self.grid = grid
        if self._world and lamp_options.get("walls") is not None:
            # The positions go in relative to the reference, so the walls must too (d shifts by n . reference).
            planes = check_walls(lamp_options["walls"])
            lamp_options["walls"] = [
                (n * d - self.reference, n) for n, d in zip(planes[:, :3], planes[:, 3], strict=True)
            ]
        self.lamp = ShiningLamp(grid, follow=follow, device=device, **lamp_options)
        self.device = self.lamp.device
        self.pressure = pressure
        self.n = 0
        self.seconds = 0.0
        self._reserve(len(r))
        self._radii.assign(r.astype(np.float32))
        self._r64 = r.copy()

    @property
    def pressure(self):
        """The pressure the next :meth:`forces` call applies [Pa]; checked when set."""
        return self._pressure

    @pressure.setter
    def pressure(self, value) -> None:
        lamp_pressure(value, self.grid.rotation)
        self._pressure = value

    def _reserve(self, n: int) -> None:
        d = self.device
        self.n = n
        self._pos = wp.zeros(n, dtype=wp.vec3, device=d)
        self._radii = wp.zeros(n, dtype=wp.float32, device=d)
        self._active = None
        self.lamp.reserve(n)

    def forces(self, centers, radii=None, *, active=None) -> np.ndarray:
        """The lamp's forces on the particles at ``centers`` [N], shape (N, 3), float64, world coordinates.

        Args:
            centers: Particle centres [m], shape (N, 3); N may differ from the last call (particles lost or
                added), and then ``radii`` is required.
            radii: Particle radii [m], shape (N,); the last ones when None.
            active: Optional mask, shape (N,): particles where it is 0 or False are invisible (no shadow, no
                force).
        """
        t0 = time.perf_counter()
        c = np.asarray(centers, dtype=np.float64)
        if c.ndim != 2 or c.shape[1] != 3:
            raise ValueError(f"centers: expected shape (N, 3), got {c.shape}")
        if c.shape[0] != self.n:
            if radii is None:
                raise ValueError(f"radii: the particle count changed ({self.n} -> {c.shape[0]}); pass the radii")
            self._reserve(c.shape[0])
        c = check_positions("centers", c, self.n)
        if radii is not None:
            _, r = check_particles(c, radii)
            if not np.array_equal(r, self._r64):
                self._radii.assign(r.astype(np.float32))
                self._r64 = r.copy()
        act = None
        if active is not None:
            m = check_mask("active", active, self.n)
            if self._active is None:
                self._active = wp.zeros(self.n, dtype=wp.int32, device=self.device)
            self._active.assign(m)
            act = self._active
        local = c - self.reference if self._world else self.grid.to_frame(c)
        self._pos.assign(local.astype(np.float32))
        self.lamp.update(self._pos, self._radii, act, in_frame=not self._world)
        f = self.lamp.forces_numpy(self.pressure)
        self.seconds = time.perf_counter() - t0
        return f


class CallTimings:
    """Seconds of each adapter call's parts, ``read`` (the engine's arrays), ``lamp`` (:meth:`EngineLamp.forces`)
    and ``write`` (the forces into the engine), on two clocks: the wall clock, and the calling thread's CPU time,
    which other jobs on a shared machine do not inflate (Warp's CPU kernels run on the calling thread).

    Attributes:
        wall: Per part, the wall-clock seconds of each call.
        cpu: Per part, the CPU seconds of each call.
    """

    PARTS = ("read", "lamp", "write")

    def __init__(self):
        self.wall = {p: [] for p in self.PARTS}
        self.cpu = {p: [] for p in self.PARTS}

    @staticmethod
    def mark() -> tuple[float, float]:
        """Both clocks now."""
        return time.perf_counter(), time.thread_time()

    def record(self, marks) -> None:
        """Add one call from its four marks (before read, after read, after the lamp, after write)."""
        for part, a, b in zip(self.PARTS, marks[:-1], marks[1:], strict=True):
            self.wall[part].append(b[0] - a[0])
            self.cpu[part].append(b[1] - a[1])

    @property
    def calls(self) -> int:
        return len(self.wall["read"])

    def cost(self, *, skip: int = 1) -> dict:
        """Median seconds per call of each part and of their ``total``, on each clock (``wall``, ``cpu``), leaving
        out the first ``skip`` calls (the first update finds every owner; an engine's first write may grow its
        containers); ``calls`` counts them all."""
        out = {"calls": self.calls}
        for clock, table in (("wall", self.wall), ("cpu", self.cpu)):
            row = {}
            for part, values in table.items():
                v = values[skip:] or values
                row[part] = float(np.median(v)) if v else float("nan")
            totals = [sum(t) for t in zip(*table.values(), strict=True)]
            totals = totals[skip:] or totals
            row["total"] = float(np.median(totals)) if totals else float("nan")
            out[clock] = row
        return out
