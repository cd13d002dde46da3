"""The benchmarks behind ``warp-lamp bench``: speed against error for the lamp, its modes, porosity and peers.

Modules: :mod:`~warp_lamp.bench.speed` (the lamp's speed and error, device ceilings, the figure),
:mod:`~warp_lamp.bench.modes` (small bodies, area, wetted, frames), :mod:`~warp_lamp.bench.wetted` (the wetted
surface's lone-sphere convergence), :mod:`~warp_lamp.bench.porosity`, :mod:`~warp_lamp.bench.tolerance` (the
speed-error table behind ``tolerance=``), :mod:`~warp_lamp.bench.engines` (YADE's alpha-shape caps as a peer),
:mod:`~warp_lamp.bench.peers` (what a Warp user would write without this library) and
:mod:`~warp_lamp.bench.common` (what they share). None of them is imported by the library itself.
"""

from warp_lamp.bench.common import lattice_grid, markdown_table
from warp_lamp.bench.speed import bench_lamp, format_tables, place_labels, plot, specimen_stress, time_bvh, time_lamp

__all__ = [
    "bench_lamp",
    "format_tables",
    "lattice_grid",
    "markdown_table",
    "place_labels",
    "plot",
    "specimen_stress",
    "time_bvh",
    "time_lamp",
]
