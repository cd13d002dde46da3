"""The shining lamp inside DEM engines that are not Warp simulators: YADE and LAMMPS.

:class:`EngineLamp` is the engine-neutral part (float64 NumPy positions in, forces out, the lamp kept between
calls); :class:`YadeLamp` and :class:`LammpsLamp` move an engine's arrays through it as fast as the engine allows.
Neither engine is imported until an adapter is used.
"""

from warp_lamp.engines.core import CallTimings, EngineLamp
from warp_lamp.engines.lammps import LammpsContacts, LammpsLamp, load_lammps, open_lammps, preload_mpich
from warp_lamp.engines.yade import YadeLamp, yade_contacts, yade_omega

__all__ = [
    "CallTimings",
    "EngineLamp",
    "LammpsContacts",
    "LammpsLamp",
    "YadeLamp",
    "load_lammps",
    "open_lammps",
    "preload_mpich",
    "yade_contacts",
    "yade_omega",
]
