"""A fixed workload for Nsight Compute: the SphereTest specimen at 4 cells per diameter, updated a few times in the
mode named on the command line (``area``: sub-points D = 4 with the deep gather; ``wetted``: the wetted surface
from scratch, rho = r-bar), so that ``ncu -k regex:...`` can profile its heaviest kernels (``bench/gpu/parts/ncu.sh``).

    python bench/experiments/ncu_probe.py area|wetted [--updates 6] [--scene specimen|lattice]

``--scene lattice``: the wetted benchmark's 1M lattice box (``scene_lattice_box(100)``, cell 0.25), where every SM is
full.
"""

from __future__ import annotations

import argparse

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.scenes import scene_lattice_box, scene_sphere_specimen
from warp_lamp.wetted import WettedSurface


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("area", "wetted"))
    ap.add_argument("--updates", type=int, default=6)
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--lineinfo", action="store_true", help="modules built with line info (ncu's source view)")
    ap.add_argument("--cells", type=int, default=4, help="cells per diameter")
    ap.add_argument("--scene", choices=("specimen", "lattice"), default="specimen")
    args = ap.parse_args()
    wp.config.lineinfo = args.lineinfo
    wp.init()
    device = wp.get_device(args.device)
    sc = scene_sphere_specimen()
    if args.mode == "area":
        grid = wl.LampGrid.enclosing(sc.centers, sc.radii, cells_per_diameter=args.cells)
        lamp = wl.ShiningLamp(
            grid, device=device, criterion="area", resolver="subpoints", depth_slots=4, subpoints=8, gather="deep"
        )
        pos = wp.array(grid.to_frame(sc.centers).astype(np.float32), dtype=wp.vec3, device=device)
        rad = wp.array(sc.radii.astype(np.float32), dtype=wp.float32, device=device)

        def update():
            lamp.update(pos, rad, in_frame=True)
    else:
        if args.scene == "lattice":
            sc = scene_lattice_box(100)
        rho = float(sc.radii.mean())
        grid = wl.LampGrid.enclosing(sc.centers, sc.radii, cells_per_diameter=args.cells, margin=3.0 * rho)
        if args.scene == "lattice":
            # As the wetted benchmark's grid (bench/experiments/wetted_bench.py, grid_for): cell 0.25.
            lo = sc.centers.min(axis=0) - sc.radii.max() - 0.25 - rho
            hi = sc.centers.max(axis=0) + sc.radii.max() + 0.25 + rho
            grid = wl.LampGrid(lo, hi, 0.25)
        surf = WettedSurface(grid, probe_radius=rho, device=device)
        pos = wp.array((sc.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
        rad = wp.array(sc.radii.astype(np.float32), dtype=wp.float32, device=device)

        def update():
            surf.update(pos, rad)

    for _ in range(args.updates):
        update()
    wp.synchronize_device(device)
    print(f"ncu_probe {args.mode}: {args.updates} updates on {device}")


if __name__ == "__main__":
    main()
