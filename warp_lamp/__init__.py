"""warp_lamp: the shining-lamp pressure boundary and sphere-packing porosity, as NVIDIA Warp kernels."""

from warp_lamp.grid import LampGrid
from warp_lamp.lamp import LAMPS, LampDiagnostics, ShiningLamp, lamp_forces, lamp_solve

__all__ = ["LAMPS", "LampDiagnostics", "LampGrid", "ShiningLamp", "lamp_forces", "lamp_solve"]
__version__ = "0.1.0"
