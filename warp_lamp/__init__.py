"""warp_lamp: the shining-lamp pressure boundary and sphere-packing porosity, as NVIDIA Warp kernels."""

from warp_lamp.grid import LampGrid
from warp_lamp.lamp import LAMPS, LampDiagnostics, ShiningLamp, lamp_forces, lamp_update
from warp_lamp.porosity import POROSITY_METHODS, kozeny_carman, porosity

__all__ = [
    "LAMPS",
    "POROSITY_METHODS",
    "LampDiagnostics",
    "LampGrid",
    "ShiningLamp",
    "kozeny_carman",
    "lamp_forces",
    "lamp_update",
    "porosity",
]
__version__ = "0.4.0"
