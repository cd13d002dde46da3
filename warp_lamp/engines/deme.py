"""The shining lamp inside DEM-Engine (DEME 3, https://github.com/projectchrono/DEM-Engine), a GPU DEM engine.

Install: ``pip install "warp-lamp[deme]"`` (``deme[cuda12]``: DEME 3.0.19 and the CUDA 12.8 runtime, NVRTC, NVCC
headers, CCCL and cuRAND wheels its just-in-time kernels need). DEME runs on NVIDIA GPUs only; its first
``Initialize()`` on a machine compiles its kernels for about three minutes.

Use::

    from warp_lamp.engines import DemeLamp
    batch = solver.AddClumps(sphere_types, centres)   # one-sphere clumps, in the order of `radii`
    tracker = solver.Track(batch)
    solver.Initialize()
    lamp = DemeLamp(solver, tracker, 10e6, radii=radii, every=10)
    lamp.step(20000)                                  # each step: the lamp when due, its load queued, one DEME step

What DEME 3's Python API gives, and what the adapter copies (checked against the 3.0.19 wheel's bindings and its
``AuxClasses.h``):

- Positions: ``tracker.PositionsToDevice(ptr, capacity, device)`` writes the tracked owners' centres of mass as
  float32 ``float3`` into memory the caller owns; the adapter hands it a Warp array's pointer on the lamp's GPU, so
  the positions go from DEME's arrays to the lamp's without the host (one device copy of 12 bytes per owner).
  Clumps of several spheres also need the owners' orientations (``OrientationQuaternionsToDevice``, (x, y, z, w)),
  and a kernel puts each sphere at its owner's centre plus its rotated offset. A lamp on the CPU reads the host
  lists instead (``tracker.Positions()``, ``OrientationQuaternions()``): a copy through Python lists.
- Radii: DEME's Python API has no read of a clump template's spheres, so the adapter takes them from the caller
  (``radii`` for one-sphere clumps, :class:`DemeClumps` for clumps of several spheres), once.
- Forces: DEME takes no external force per owner, only an extra acceleration for the next step:
  ``tracker.AddAccFromDevice(ptr, device)`` (world frame, one ``float3`` per tracked owner, consumed after one
  step) and ``tracker.AddAngAccFromDevice`` (angular, in each owner's principal frame). The adapter sums its
  spheres' forces per owner on the device, divides by the owner's mass (``tracker.Masses()``, read once), and for
  clumps of several spheres turns the torque about the centre of mass into an angular acceleration with the
  principal moments (``tracker.MOIs()``). Because the acceleration lasts one step, :meth:`DemeLamp.apply` queues it
  again before every step (one call; the memo's ``ct_pressrate`` runs the lamp itself every ``every`` steps). On the
  CPU path, ``tracker.AddAcc(list)`` and ``AddAngAcc(list)``.

A one-sphere clump takes its sphere's force at its centre: no torque. A clump of several spheres takes each sphere's
own force; their sum moves it, and their moment about its centre of mass turns it (``torques=False`` drops the
turning). DEME's positions are float32 in world coordinates, so the lamp's input carries their rounding (about
6e-8 of the distance from DEME's origin).
"""

from __future__ import annotations

import importlib.util
import time

import numpy as np
import warp as wp

from warp_lamp.engines.core import CallTimings, EngineLamp
from warp_lamp.validate import check_integer, check_particles

__all__ = ["DemeClumps", "DemeLamp", "add_deme_spheres", "deme_unavailable", "load_deme"]

_EXTRA = 'pip install "warp-lamp[deme]"'


def deme_unavailable() -> str | None:
    """Why DEME cannot run here (``deme`` not installed, or no CUDA device), or None where it can."""
    if importlib.util.find_spec("deme") is None:
        return f"deme: not installed ({_EXTRA})"
    if not wp.is_cuda_available():
        return "deme: DEM-Engine runs on NVIDIA GPUs only, and Warp finds no CUDA device here"
    return None


def load_deme():
    """The ``deme`` module; ImportError naming the extra where it is missing, RuntimeError where there is no CUDA
    device (DEME's import needs the NVIDIA driver's ``libcuda.so.1``)."""
    if importlib.util.find_spec("deme") is None:
        raise ImportError(f"deme: not installed; {_EXTRA} (DEM-Engine 3 and its CUDA 12 wheels)")
    if not wp.is_cuda_available():
        raise RuntimeError("deme: DEM-Engine runs on NVIDIA GPUs only, and Warp finds no CUDA device here")
    try:
        import deme
    except ImportError as e:
        raise ImportError(f"deme: installed but does not load ({e}); {_EXTRA} brings its CUDA 12 wheels") from e
    return deme


def add_deme_spheres(solver, centers, radii, material, *, density: float = 2620.0, template_radii=None):
    """Add spheres to a DEME solver (before ``Initialize()``) as one batch of one-sphere clumps, in the given order.

    DEME gives every clump a template: this loads one sphere template per distinct radius (mass from ``density``,
    DEME's own moment of inertia for a solid sphere), so a polydisperse body has as many templates as radii; with
    many, call ``solver.DisableJitifyClumpTemplates()`` and ``DisableJitifyMassProperties()`` before
    ``Initialize()``, so that DEME keeps them in device arrays instead of compiling them into its kernels.

    Args:
        solver: A ``deme.DEMSolver``, not yet initialised.
        centers: Sphere centres [m], shape (N, 3).
        radii: Sphere radii [m], shape (N,).
        material: A material from ``solver.LoadMaterial``.
        density: Particle density [kg/m^3], > 0.
        template_radii: Radii to load templates for besides those of ``radii`` [m]. DEME compiles its templates'
            volumes into its kernels, so two solvers share their compiled kernels (and skip DEME's minutes of
            compiling) only with the same templates, domain box and material: load a common set in each.

    Returns:
        ``(batch, tracker)``: the ``DEMClumpBatch`` and ``solver.Track(batch)``, whose owners follow ``centers``.
    """
    c, r = check_particles(centers, radii)
    if len(r) == 0:
        raise ValueError("centers: need at least one sphere")
    if not (np.isfinite(density) and density > 0):
        raise ValueError(f"density: must be finite and > 0, got {density!r}")
    bad = np.flatnonzero(r <= 0)
    if len(bad):
        raise ValueError(f"radii: must be > 0; radii[{bad[0]}] = {r[bad[0]]}")
    pool = r if template_radii is None else np.concatenate([r, np.asarray(template_radii, dtype=np.float64).ravel()])
    if not np.all(np.isfinite(pool) & (pool > 0)):
        raise ValueError("template_radii: must be finite and > 0")
    unique = np.unique(pool)
    which = np.searchsorted(unique, r)
    templates = [solver.LoadSphereType(float(density * 4.0 / 3.0 * np.pi * u**3), float(u), material) for u in unique]
    batch = solver.AddClumps([templates[i] for i in which], c.tolist())
    return batch, solver.Track(batch)


class DemeClumps:
    """Which spheres make each tracked owner: radii, the owner of each sphere, and its offset in the owner's frame.

    Spheres are listed owner by owner, in the tracker's owner order. One-sphere clumps (``DemeClumps(radii)``) have
    one sphere each at offset zero.

    Attributes:
        radii: Sphere radii [m], shape (S,), float64.
        owner: Tracker index of each sphere's owner, shape (S,), int32, non-decreasing, every owner present.
        offsets: Each sphere's centre in its owner's principal frame, relative to its centre of mass [m], (S, 3).
        start: First sphere of each owner, shape (K + 1,), int32 (``start[K] = S``).
        owners: K, the number of owners.
        single: Every owner is one sphere at its centre of mass (no orientation needed).
    """

    def __init__(self, radii, *, owner=None, offsets=None):
        """Args:
        radii: Sphere radii [m], shape (S,), each > 0.
        owner: Tracker index of each sphere's owner, shape (S,): 0, ..., K-1, non-decreasing, none left out;
            one sphere per owner (``arange(S)``) by default.
        offsets: Sphere centres in the owner's principal frame [m], shape (S, 3); zeros by default.
        """
        r = np.asarray(radii, dtype=np.float64)
        if r.ndim != 1 or len(r) == 0:
            raise ValueError(f"radii: expected shape (S,) with S >= 1, got {r.shape}")
        bad = np.flatnonzero(~(np.isfinite(r) & (r > 0)))
        if len(bad):
            raise ValueError(f"radii: must be finite and > 0; radii[{bad[0]}] = {r[bad[0]]}")
        s = len(r)
        if owner is None:
            o = np.arange(s, dtype=np.int64)
        else:
            o = np.asarray(owner)
            if o.dtype.kind not in "iu" or o.shape != (s,):
                raise ValueError(f"owner: expected {s} integers (one per sphere), got {o.dtype} {o.shape}")
            o = o.astype(np.int64)
            if o[0] != 0:
                raise ValueError(f"owner: the first sphere must belong to owner 0, got owner[0] = {o[0]}")
            step = np.diff(o)
            bad = np.flatnonzero((step < 0) | (step > 1))
            if len(bad):
                k = int(bad[0]) + 1
                raise ValueError(
                    f"owner: spheres must be listed owner by owner (0, 1, 2, ... with none left out); "
                    f"owner[{k}] = {o[k]} follows {o[k - 1]}"
                )
        if offsets is None:
            d = np.zeros((s, 3))
        else:
            d = np.asarray(offsets, dtype=np.float64)
            if d.shape != (s, 3):
                raise ValueError(f"offsets: expected shape ({s}, 3), got {d.shape}")
            bad = np.flatnonzero(~np.all(np.isfinite(d), axis=1))
            if len(bad):
                raise ValueError(f"offsets: must be finite; offsets[{bad[0]}] = {d[bad[0]].tolist()}")
        self.radii = r
        self.owner = o.astype(np.int32)
        self.offsets = d
        self.owners = int(o[-1]) + 1
        self.start = np.searchsorted(o, np.arange(self.owners + 1)).astype(np.int32)
        self.single = bool(self.owners == s and not np.any(d))

    @classmethod
    def from_templates(cls, templates, types) -> DemeClumps:
        """The spheres of owners built from templates.

        Args:
            templates: Per template, ``(radii, offsets)``: its spheres' radii [m], shape (c,), and centres in its
                principal frame relative to its centre of mass [m], shape (c, 3), as given to
                ``solver.LoadClumpType``.
            types: Template index of each tracked owner, in tracker order, shape (K,).
        """
        tpl = []
        for k, item in enumerate(templates):
            try:
                r, d = item
            except (TypeError, ValueError):
                raise ValueError(f"templates[{k}]: expected (radii, offsets)") from None
            r = np.atleast_1d(np.asarray(r, dtype=np.float64))
            d = np.asarray(d, dtype=np.float64).reshape(-1, 3) if np.size(d) else np.zeros((0, 3))
            if r.ndim != 1 or len(r) == 0 or d.shape != (len(r), 3):
                raise ValueError(f"templates[{k}]: expected c >= 1 radii and (c, 3) offsets, got {r.shape}, {d.shape}")
            tpl.append((r, d))
        t = np.asarray(types)
        if t.dtype.kind not in "iu" or t.ndim != 1 or len(t) == 0:
            raise ValueError(f"types: expected K >= 1 integers, got {t.dtype} {t.shape}")
        bad = np.flatnonzero((t < 0) | (t >= len(tpl)))
        if len(bad):
            raise ValueError(f"types: template indices 0..{len(tpl) - 1}; types[{bad[0]}] = {t[bad[0]]}")
        counts = np.array([len(tpl[i][0]) for i in t])
        radii = np.concatenate([tpl[i][0] for i in t])
        offsets = np.concatenate([tpl[i][1] for i in t])
        return cls(radii, owner=np.repeat(np.arange(len(t)), counts), offsets=offsets)

    def centers(self, positions, quats=None) -> np.ndarray:
        """World sphere centres [m], shape (S, 3), float64, from owner centres (K, 3) and quaternions (K, 4) in
        (x, y, z, w) order (needed unless :attr:`single`)."""
        p = np.asarray(positions, dtype=np.float64)
        if self.single:
            return p.copy()
        return p[self.owner] + _rotate(np.asarray(quats, dtype=np.float64)[self.owner], self.offsets)

    def loads(self, forces, quats, mass, moi, *, torques: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Per owner, the linear acceleration sum F / m (world frame) and, with ``torques`` (and owners of several
        spheres), the angular acceleration in its principal frame; float64, shape (K, 3) each."""
        f = np.asarray(forces, dtype=np.float64)
        total = np.add.reduceat(f, self.start[:-1], axis=0)
        acc = total / np.asarray(mass, dtype=np.float64)[:, None]
        if self.single or not torques:
            return acc, None
        q = np.asarray(quats, dtype=np.float64)
        arm = _rotate(q[self.owner], self.offsets)
        torque = np.add.reduceat(np.cross(arm, f), self.start[:-1], axis=0)
        inv = q * np.array([-1.0, -1.0, -1.0, 1.0])
        return acc, _rotate(inv, torque) / np.asarray(moi, dtype=np.float64)


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate each v by the unit quaternion q (x, y, z, w): v + 2 w (u x v) + 2 u x (u x v)."""
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    u, w = q[:, :3], q[:, 3:]
    uv = np.cross(u, v)
    return v + 2.0 * w * uv + 2.0 * np.cross(u, uv)


def _is_real_deme(obj) -> bool:
    return type(obj).__module__.split(".")[0] in ("deme", "DEME")


class DemeLamp:
    """Shining-lamp pressure on the owners a DEME tracker follows, as next-step accelerations.

    Each :meth:`update` reads the owners' positions (on the GPU: :mod:`module docs <warp_lamp.engines.deme>`), runs
    the lamp (an :class:`~warp_lamp.engines.EngineLamp`: every mode, walls included, through ``lamp_options``), and
    turns the spheres' forces into each owner's acceleration (and angular acceleration for clumps of several
    spheres). :meth:`apply` queues them for DEME's next step; DEME consumes them after one step, so call it before
    every step, or let :meth:`step` do both.

    Attributes:
        solver: The ``deme.DEMSolver``.
        tracker: The tracker of the owners under pressure (``solver.Track(batch)``).
        clumps: The spheres of each owner (:class:`DemeClumps`).
        core: The :class:`~warp_lamp.engines.EngineLamp` (its ``lamp``, ``grid``, ``pressure``).
        transfer: ``"device"`` (DEME's ``*ToDevice`` / ``*FromDevice`` calls with Warp arrays on the lamp's GPU) or
            ``"host"`` (DEME's list calls).
        every: The lamp runs every this many :meth:`step` steps.
        timings: Seconds of each update's parts (:class:`~warp_lamp.engines.CallTimings`, wall clock and CPU):
            ``read`` (DEME's positions into the lamp's input), ``lamp`` (update and forces), ``write`` (the owners'
            accelerations); on a GPU each part ends with a device synchronisation, so the parts are its own.
        apply_seconds: Wall seconds of each :meth:`apply` (the per-step queueing).
        step_seconds: Wall seconds of each DEME step that :meth:`step` ran (``DoStepDynamics``).
    """

    def __init__(
        self,
        solver,
        tracker,
        pressure,
        *,
        radii=None,
        clumps: DemeClumps | None = None,
        torques: bool = True,
        every: int = 1,
        transfer: str = "auto",
        validate: bool = True,
        **lamp_options,
    ):
        """Args:
        solver: A ``deme.DEMSolver``, initialised (``Initialize()``).
        tracker: ``solver.Track(batch)`` of the clumps under pressure; every tracked owner is made of spheres.
        pressure: Fluid pressure [Pa] (a number, three per-axis numbers or a stress tensor; see
            :class:`~warp_lamp.engines.EngineLamp`); ``lamp.pressure = p`` changes it between updates.
        radii: One-sphere clumps: each owner's radius [m], shape (K,), in tracker order.
        clumps: Clumps of several spheres (:class:`DemeClumps`); give ``radii`` or ``clumps``, not both.
        torques: Turn clumps of several spheres by the moment of their spheres' forces (DEME's angular
            acceleration); False applies the sum only.
        every: :meth:`step` runs the lamp every this many steps; its last load is queued on every step.
        transfer: ``"device"``, ``"host"``, or ``"auto"`` (device where the lamp runs on a GPU).
        validate: Passed to DEME's device calls (range and pointer checks; False saves their cost).
        **lamp_options: Keywords of :class:`~warp_lamp.engines.EngineLamp` (``device``, default ``"cuda:0"``
            where there is a GPU; ``cells_per_diameter``, ``grid``, ``follow``, ``criterion``, ``surfaces``,
            ``probe_radius``, ``walls``, ``frames``, ...).
        """
        if (radii is None) == (clumps is None):
            raise ValueError("radii, clumps: give one (radii for one-sphere clumps, clumps for several spheres)")
        if clumps is None:
            clumps = DemeClumps(radii)
        elif not isinstance(clumps, DemeClumps):
            raise TypeError(f"clumps: expected DemeClumps, got {type(clumps).__name__}")
        self.every = check_integer("every", every, minimum=1)
        if transfer not in ("auto", "device", "host"):
            raise ValueError(f"transfer: 'auto', 'device' or 'host', got {transfer!r}")
        self.solver, self.tracker, self.clumps = solver, tracker, clumps
        self.torques = bool(torques) and not clumps.single
        self.validate = bool(validate)
        ids = list(tracker.GetOwnerIDs())
        if len(ids) != clumps.owners:
            what = "radii" if radii is not None else "clumps"
            raise ValueError(
                f"{what}: describes {clumps.owners} owners, the tracker follows {len(ids)} (one entry per tracked "
                "clump, in tracker order)"
            )
        self.owner_ids = np.asarray(ids, dtype=np.int64)
        self.mass = np.asarray(tracker.Masses(), dtype=np.float64).reshape(-1)
        bad = np.flatnonzero(~(np.isfinite(self.mass) & (self.mass > 0)))
        if self.mass.shape != (clumps.owners,) or len(bad):
            raise ValueError(f"tracker: owner masses must be > 0 (tracked owner {bad[0] if len(bad) else '?'})")
        self.moi = np.asarray(tracker.MOIs(), dtype=np.float64).reshape(-1, 3) if self.torques else None
        if self.moi is not None and not np.all(self.moi > 0):
            raise ValueError("tracker: owner moments of inertia must be > 0 to turn clumps (or torques=False)")
        lamp_options.setdefault("device", "cuda:0" if wp.is_cuda_available() else "cpu")
        pos, quats = self._read_host()
        self.core = EngineLamp(clumps.centers(pos, quats), clumps.radii, pressure, **lamp_options)
        self.device = self.core.device
        if transfer == "auto":
            transfer = "device" if self.device.is_cuda else "host"
        if transfer == "device" and not self.device.is_cuda and _is_real_deme(tracker):
            raise ValueError("transfer: DEME's device calls need the lamp on a CUDA device (device='cuda:0')")
        self.transfer = transfer
        self.timings = CallTimings()
        self.apply_seconds: list[float] = []
        self.step_seconds: list[float] = []
        self.steps = 0
        self.acc = np.zeros((clumps.owners, 3))
        self.ang_acc = np.zeros((clumps.owners, 3)) if self.torques else None
        self._updated = False
        if transfer == "device":
            self._device_buffers()

    def _device_buffers(self) -> None:
        c, d, k = self.clumps, self.device, self.clumps.owners
        self._ordinal = int(d.ordinal) if d.is_cuda else 0
        self._pos = wp.zeros(k, dtype=wp.vec3, device=d)
        self._rot = wp.zeros(k if not c.single else 1, dtype=wp.quat, device=d)
        self._centers = wp.zeros(len(c.radii), dtype=wp.vec3, device=d)
        self._radii = wp.array(c.radii.astype(np.float32), dtype=wp.float32, device=d)
        self._forces = wp.zeros(len(c.radii), dtype=wp.vec3, device=d)
        self._owner = wp.array(c.owner, dtype=wp.int32, device=d)
        self._offsets = wp.array(c.offsets.astype(np.float32), dtype=wp.vec3, device=d)
        self._start = wp.array(c.start, dtype=wp.int32, device=d)
        self._mass = wp.array(self.mass.astype(np.float32), dtype=wp.float32, device=d)
        moi = self.moi if self.moi is not None else np.ones((1, 3))
        self._moi = wp.array(moi.astype(np.float32), dtype=wp.vec3, device=d)
        self._acc = wp.zeros(k, dtype=wp.vec3, device=d)
        self._ang = wp.zeros(k if self.torques else 1, dtype=wp.vec3, device=d)
        self._reference = wp.vec3(*self.core.reference.astype(np.float32))

    @property
    def pressure(self):
        """The pressure the next update applies [Pa]."""
        return self.core.pressure

    @pressure.setter
    def pressure(self, value) -> None:
        self.core.pressure = value

    def _read_host(self) -> tuple[np.ndarray, np.ndarray | None]:
        k = self.clumps.owners
        pos = np.asarray(self.tracker.Positions(), dtype=np.float64).reshape(-1, 3)
        if pos.shape != (k, 3):
            raise RuntimeError(f"tracker: Positions() gave {pos.shape[0]} owners, expected {k}")
        if self.clumps.single:  # one sphere at each centre of mass: no orientation needed
            return pos, None
        quats = np.asarray(self.tracker.OrientationQuaternions(), dtype=np.float64).reshape(-1, 4)
        return pos, quats

    def _check_updated(self, name: str) -> None:
        if not self._updated:
            raise RuntimeError(f"{name}: no load yet; call DemeLamp.update first")

    def _sync(self) -> None:
        # Warp's stream only: a device-wide synchronisation would also wait for DEME's contact detection, which
        # runs on its own streams beside the step.
        if self.device.is_cuda:
            wp.synchronize_stream(wp.get_stream(self.device))

    def update(self) -> None:
        """Read the owners' positions, run the lamp, and compute each owner's accelerations for :meth:`apply`."""
        marks = [self.timings.mark()]
        if self.transfer == "device":
            self._update_device(marks)
        else:
            pos, quats = self._read_host()
            centers = self.clumps.centers(pos, quats)
            marks.append(self.timings.mark())
            f = self.core.forces(centers)
            self._host_forces = f
            marks.append(self.timings.mark())
            self.acc, self.ang_acc = self.clumps.loads(f, quats, self.mass, self.moi, torques=self.torques)
            marks.append(self.timings.mark())
        self.timings.record(marks)
        self._updated = True

    def _update_device(self, marks) -> None:
        c, d, t, k = self.clumps, self.device, self.tracker, self.clumps.owners
        t.PositionsToDevice(int(self._pos.ptr), k, self._ordinal, self.validate)
        if not c.single:
            t.OrientationQuaternionsToDevice(int(self._rot.ptr), k, self._ordinal, self.validate)
        wp.launch(
            _kernels().sphere_centers_from_owners,
            dim=len(c.radii),
            inputs=[self._pos, self._rot, self._owner, self._offsets, self._reference, int(not c.single)],
            outputs=[self._centers],
            device=d,
        )
        self._sync()
        marks.append(self.timings.mark())
        lamp = self.core.lamp
        lamp.update(self._centers, self._radii, in_frame=False)
        self._forces.zero_()
        lamp.add_forces(self._forces, self.core.pressure)
        self._sync()
        marks.append(self.timings.mark())
        wp.launch(
            _kernels().owner_accelerations,
            dim=k,
            inputs=[self._forces, self._offsets, self._start, self._rot, self._mass, self._moi, int(self.torques)],
            outputs=[self._acc, self._ang],
            device=d,
        )
        self._sync()  # DEME reads the accelerations on its own stream
        marks.append(self.timings.mark())

    def apply(self) -> None:
        """Queue the last update's accelerations for DEME's next step (DEME drops them after that step)."""
        self._check_updated("apply")
        t0 = time.perf_counter()
        t = self.tracker
        if self.transfer == "device":
            t.AddAccFromDevice(int(self._acc.ptr), self._ordinal, self.validate)
            if self.torques:
                t.AddAngAccFromDevice(int(self._ang.ptr), self._ordinal, self.validate)
        else:
            t.AddAcc(self.acc.tolist())
            if self.torques:
                t.AddAngAcc(self.ang_acc.tolist())
        self.apply_seconds.append(time.perf_counter() - t0)

    def step(self, steps: int = 1) -> None:
        """Run ``steps`` DEME steps: the lamp every :attr:`every` steps (counted over all calls), its load queued
        before each step (:meth:`apply`), then ``solver.DoStepDynamics()``."""
        for _ in range(check_integer("steps", steps)):
            if self.steps % self.every == 0:
                self.update()
            self.apply()
            t0 = time.perf_counter()
            self.solver.DoStepDynamics()
            self.step_seconds.append(time.perf_counter() - t0)
            self.steps += 1

    def forces(self) -> np.ndarray:
        """The spheres' forces of the last update [N], shape (S, 3), world frame (a host copy)."""
        self._check_updated("forces")
        if self.transfer == "device":
            return self._forces.numpy().astype(np.float64)
        return self._host_forces.copy()

    def accelerations(self) -> tuple[np.ndarray, np.ndarray | None]:
        """The last update's owner accelerations (linear, world frame; angular, principal frame, or None) (host
        copies), shape (K, 3) each."""
        self._check_updated("accelerations")
        if self.transfer == "device":
            ang = self._ang.numpy().astype(np.float64) if self.torques else None
            return self._acc.numpy().astype(np.float64), ang
        return self.acc.copy(), None if self.ang_acc is None else self.ang_acc.copy()

    @property
    def calls(self) -> int:
        """Lamp updates so far."""
        return self.timings.calls

    def cost(self, *, skip: int = 1) -> dict:
        """Median seconds per update of ``read``, ``lamp`` and ``write`` and their ``total``, wall clock and CPU
        (:meth:`CallTimings.cost`), the first ``skip`` updates left out; with ``apply`` and ``step``, the median
        wall seconds of the per-step queueing and of DEME's step."""
        out = self.timings.cost(skip=skip)
        for name, values in (("apply", self.apply_seconds), ("step", self.step_seconds)):
            v = values[skip:] or values
            out[name] = float(np.median(v)) if v else float("nan")
        return out


def _kernels():
    from warp_lamp.kernels import owners

    return owners
