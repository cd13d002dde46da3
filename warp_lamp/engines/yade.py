"""The shining lamp inside YADE (https://yade-dem.org): a ``PyRunner``-ready adapter.

YADE runs its own interpreter (``/usr/bin/yade`` starts ``/usr/bin/python3``), so warp-lang and warp_lamp must be
importable there. With Debian's ``yade`` package (2023.02a, Python 3.11), a virtual environment over the system
interpreter that sees its packages keeps YADE's NumPy and adds ours::

    /usr/bin/python3 -m venv --system-site-packages ~/yade-env   # Debian's python, YADE's interpreter
    ~/yade-env/bin/pip install warp-lamp                  # or: pip install -e . in a checkout
    ~/yade-env/bin/python /usr/bin/yade -j1 -n -x script.py

and in the script::

    from warp_lamp.engines import YadeLamp
    lamp = YadeLamp(10e6)                                 # every sphere in O.bodies, 10 MPa
    O.engines = O.engines[:-1] + [PyRunner(command="lamp()", iterPeriod=10), O.engines[-1]]

Access, measured on the SphereTest specimen (4,628 spheres; ``docs/engines.md``,
``bench/experiments/yade_access.py``):

- Positions: YADE offers no array view. The fastest read is ``yade._utils.coordsAndDisplacements(axis)``, a C++
  loop over the bodies that returns one list of floats per axis (three calls, 0.57 ms), against 15-54 ms for a
  Python loop over ``O.bodies`` (``b.state.pos``). It lists every body in ``O.bodies`` order (walls and facets too),
  so the adapter maps its sphere ids into that order once, and again when the body count changes. Radii are read
  once (``b.shape.radius``); call :meth:`YadeLamp.refresh_radii` after growing particles.
- Forces: ``O.forces.setPermF(id, f)`` keeps a force on a body until it is set again, so a ``PyRunner`` every N
  iterations applies the lamp between its calls (``addF`` lasts one step). Called with plain lists (``f.tolist()``)
  it costs 0.74 ms for all 4,628 (a ``Vector3(*row)`` per body 2.3-6.5 ms, NumPy rows 9-13 ms); the adapter writes
  only the rows that changed since its last call (a few per call in a settling body). The first ``setPermF`` loop
  in a scene costs ~20-26 ms (the force container grows).

Traps a YADE user meets (each checked on 2023.02a):

- ``O.forces.permF(i)`` reads zero in a scene where no step has run yet, although the force is set (``O.forces.f(i)``
  shows it); run one step before reading it back.
- A script runs in the ``yade`` launcher's globals: a variable named ``opts`` replaces the launcher's own and
  crashes YADE's exit (``AttributeError: 'dict' object has no attribute 'mpi_mode'``); ``__file__`` is
  ``/usr/bin/yade`` there, so a script finds itself through ``sys.argv[0]``.
- ``PyRunner`` takes a command string that runs in those globals: keep the adapter in a global (``lamp``) and pass
  ``command="lamp()"``.
- ``TesselationWrapper.applyAlphaForces`` (YADE's own pressure boundary) with its default alpha = 0 crashes in CGAL
  (see :mod:`warp_lamp.bench.engines`).
"""

from __future__ import annotations

import numpy as np

from warp_lamp.engines.core import CallTimings, EngineLamp

__all__ = ["YadeLamp", "yade_contacts", "yade_omega"]


def yade_omega():
    """YADE's ``O`` (the running simulation), or ImportError saying how to run inside YADE."""
    try:
        import yade
    except ImportError as e:
        raise ImportError(
            "yade: not importable here; the YADE adapter runs inside YADE's interpreter (apt-get install yade; "
            "then e.g. ~/yade-env/bin/python /usr/bin/yade -n -x script.py, see warp_lamp.engines.yade)"
        ) from e
    return yade.Omega()


def _sphere_ids(omega) -> list[int]:
    from yade.wrapper import Sphere

    return [b.id for b in omega.bodies if isinstance(b.shape, Sphere)]


class YadeLamp:
    """Shining-lamp pressure on YADE's spheres, set as permanent forces; call it from a ``PyRunner``.

    Each call reads the sphere centres (:meth:`positions`), runs an :class:`~warp_lamp.engines.EngineLamp` kept
    between calls, and sets each changed force with ``O.forces.setPermF``. The force stays until the next call,
    so ``PyRunner(command="lamp()", iterPeriod=N)`` refreshes the lamp every N iterations (the memo's
    ``ct_pressrate``). The adapter owns the permanent forces of its spheres, and remembers what it wrote: a row is
    written again only when the lamp's force on it changes, so after setting permanent forces on these spheres
    elsewhere, call :meth:`rewrite_all`.

    Attributes:
        ids: Body ids of the spheres the lamp sees, shape (N,).
        core: The :class:`~warp_lamp.engines.EngineLamp` (its ``lamp``, ``grid``, ``pressure``).
        timings: Seconds of each call's parts (:class:`~warp_lamp.engines.CallTimings`, wall clock and CPU):
            ``read`` (positions), ``lamp`` (the lamp's own cost), ``write`` (setting the forces).
        written: Rows written by the last call.
    """

    def __init__(self, pressure, *, ids=None, omega=None, **lamp_options):
        """Set up the adapter.

        Args:
            pressure: Fluid pressure [Pa] (a number, three per-axis numbers or a stress tensor; see
                :class:`~warp_lamp.engines.EngineLamp`); ``lamp.pressure = p`` changes it between calls.
            ids: Body ids of the spheres under pressure; every body with a ``Sphere`` shape by default.
            omega: YADE's ``O``; the running one by default.
            **lamp_options: Keywords of :class:`~warp_lamp.engines.EngineLamp` (``cells_per_diameter``, ``grid``,
                ``follow``, ``device``, ``criterion``, ``surfaces``, ``probe_radius``, ...).
        """
        self.O = yade_omega() if omega is None else omega
        ids = _sphere_ids(self.O) if ids is None else [int(i) for i in ids]
        if not ids:
            raise ValueError("ids: no sphere bodies to put under pressure")
        if len(set(ids)) != len(ids) or min(ids) < 0:
            raise ValueError("ids: body ids >= 0, each once")
        self.ids = np.asarray(ids, dtype=np.int64)
        self._ids_list = self.ids.tolist()
        self._layout = None
        x = self.positions()
        self.radii = self._read_radii()
        self.core = EngineLamp(x, self.radii, pressure, **lamp_options)
        self._written = np.full((len(ids), 3), np.nan)  # nothing written yet: the first call writes every row
        self.timings = CallTimings()
        self.written = 0

    @property
    def pressure(self):
        """The pressure the next call applies [Pa]."""
        return self.core.pressure

    @pressure.setter
    def pressure(self, value) -> None:
        self.core.pressure = value

    def _read_radii(self) -> np.ndarray:
        bodies = self.O.bodies
        try:
            return np.array([bodies[i].shape.radius for i in self._ids_list], dtype=np.float64)
        except AttributeError:
            raise ValueError("ids: every body must be a sphere (have shape.radius)") from None

    def refresh_radii(self) -> None:
        """Read the radii again (after ``growParticles`` or a change of ``shape.radius``)."""
        self.radii = self._read_radii()

    def _map_layout(self, count: int) -> None:
        order = [b.id for b in self.O.bodies]
        if len(order) != count:
            raise RuntimeError(f"O.bodies: listed {len(order)} bodies, coordsAndDisplacements {count}")
        where = np.full(max(max(order), int(self.ids.max())) + 1, -1, dtype=np.int64)
        where[np.asarray(order)] = np.arange(len(order))
        missing = np.flatnonzero(where[self.ids] < 0)
        if len(missing):
            k = int(missing[0])
            raise ValueError(f"ids: body {int(self.ids[k])} (index {k}) is not in O.bodies")
        self._layout = (count, where[self.ids])

    def positions(self) -> np.ndarray:
        """The spheres' centres [m], shape (N, 3), float64: three C++ loops over the bodies
        (``yade._utils.coordsAndDisplacements``), no Python loop per body."""
        from yade._utils import coordsAndDisplacements

        cols = [coordsAndDisplacements(a)[0] for a in range(3)]
        if self._layout is None or self._layout[0] != len(cols[0]):
            self._map_layout(len(cols[0]))
        return np.array(cols, dtype=np.float64).T[self._layout[1]]

    def write(self, forces: np.ndarray) -> int:
        """Set ``forces`` [N], shape (N, 3), as the spheres' permanent forces, the changed rows only; returns how
        many rows were written."""
        f = np.asarray(forces, dtype=np.float64)
        rows = np.flatnonzero(np.any(f != self._written, axis=1))
        set_force = self.O.forces.setPermF
        for i, v in zip(self.ids[rows].tolist(), f[rows].tolist(), strict=True):
            set_force(i, v)
        self._written[rows] = f[rows]
        return len(rows)

    def rewrite_all(self) -> None:
        """Make the next call write every row (after permanent forces were set on these spheres elsewhere)."""
        self._written[:] = np.nan

    def __call__(self) -> None:
        """Read, run the lamp, write: one refresh of the pressure forces."""
        marks = [self.timings.mark()]
        x = self.positions()
        marks.append(self.timings.mark())
        f = self.core.forces(x, self.radii)
        marks.append(self.timings.mark())
        self.written = self.write(f)
        marks.append(self.timings.mark())
        self.timings.record(marks)

    def clear(self) -> None:
        """Take the lamp's forces off (set the spheres' permanent forces to zero)."""
        self.write(np.zeros((len(self.ids), 3)))

    @property
    def calls(self) -> int:
        """Calls so far."""
        return self.timings.calls

    def cost(self, *, skip: int = 1) -> dict:
        """Median seconds per call of ``read``, ``lamp`` and ``write`` and their ``total``, wall clock and CPU
        (:meth:`CallTimings.cost`), the first ``skip`` calls left out."""
        return self.timings.cost(skip=skip)


def yade_contacts(ids, *, omega=None) -> tuple[np.ndarray, np.ndarray]:
    """The real sphere-sphere contacts among ``ids``: pairs as indices into ``ids``, shape (C, 2), and the force
    each contact puts on its first particle [N], shape (C, 3) (for :func:`warp_lamp.measures.sphere_stress`).

    YADE's laws apply ``phys.normalForce + phys.shearForce`` to ``id2`` and its negative to ``id1``.
    """
    omega = yade_omega() if omega is None else omega
    ids = np.asarray(ids, dtype=np.int64)
    where = np.full(int(ids.max()) + 1, -1, dtype=np.int64)
    where[ids] = np.arange(len(ids))
    pairs, forces = [], []
    for c in omega.interactions:
        if not c.isReal or c.id1 > ids.max() or c.id2 > ids.max():
            continue
        i, j = where[c.id1], where[c.id2]
        if i < 0 or j < 0:
            continue
        f = c.phys.normalForce + c.phys.shearForce
        pairs.append((i, j))
        forces.append((-f[0], -f[1], -f[2]))
    return np.array(pairs, dtype=np.int64).reshape(-1, 2), np.array(forces, dtype=np.float64).reshape(-1, 3)
