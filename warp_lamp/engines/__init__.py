"""The shining lamp inside DEM engines that are not Warp simulators: YADE, LAMMPS and DEM-Engine (DEME).

:class:`EngineLamp` is the engine-neutral part (float64 NumPy positions in, forces out, the lamp kept between
calls); :class:`YadeLamp`, :class:`LammpsLamp` and :class:`DemeLamp` move an engine's arrays through it as fast as
the engine allows (DEME's on the GPU). No engine is imported until an adapter is used.
"""

from warp_lamp.engines.core import CallTimings, EngineLamp
from warp_lamp.engines.deme import DemeClumps, DemeLamp, add_deme_spheres, deme_unavailable, load_deme
from warp_lamp.engines.lammps import LammpsContacts, LammpsLamp, load_lammps, open_lammps, preload_mpich
from warp_lamp.engines.yade import YadeLamp, yade_contacts, yade_omega

__all__ = [
    "CallTimings",
    "DemeClumps",
    "DemeLamp",
    "EngineLamp",
    "LammpsContacts",
    "LammpsLamp",
    "YadeLamp",
    "add_deme_spheres",
    "deme_unavailable",
    "load_deme",
    "load_lammps",
    "open_lammps",
    "preload_mpich",
    "yade_contacts",
    "yade_omega",
]
