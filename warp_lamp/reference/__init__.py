"""Plain float64 NumPy references for the kernels, written for clarity rather than speed.

The kernels decide in float32 (the lamp) or float64 (porosity). Where a float32 decision sits within rounding of a
boundary, the lamp reference flags the cell as ambiguous, with a bound derived from float32's unit roundoff, and
tests compare every other cell exactly.
"""

from warp_lamp.reference.area import (
    EXACT_UNIT,
    AreaEstimate,
    area_depth_slots,
    area_estimate_reference,
    hidden_spheres,
    visible_area_reference,
    visible_disk_areas,
    visible_sphere_areas,
)
from warp_lamp.reference.distributed import (
    fixed_units_reference,
    global_keys_reference,
    merge_lists_reference,
    scatter_reference,
    scatter_walls_reference,
)
from warp_lamp.reference.lamp import EPS32, LampReference, lamp_reference
from warp_lamp.reference.porosity import (
    PAPER_TABLE_1,
    midpoint_sphere_offsets,
    midpoint_spheres,
    octant_volume,
    porosity_reference,
    sphere_box_volume,
)

__all__ = [
    "EPS32",
    "EXACT_UNIT",
    "PAPER_TABLE_1",
    "AreaEstimate",
    "LampReference",
    "area_depth_slots",
    "area_estimate_reference",
    "fixed_units_reference",
    "global_keys_reference",
    "hidden_spheres",
    "lamp_reference",
    "merge_lists_reference",
    "midpoint_sphere_offsets",
    "midpoint_spheres",
    "octant_volume",
    "porosity_reference",
    "scatter_reference",
    "scatter_walls_reference",
    "sphere_box_volume",
    "visible_area_reference",
    "visible_disk_areas",
    "visible_sphere_areas",
]
