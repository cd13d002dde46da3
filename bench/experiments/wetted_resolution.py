"""Issue 19: do the wetted-surface figures depend on the cells? The SphereTest specimen's mean pressure, the slot
block's wall and floor ratios and the tunnel's width, at 4, 6 and 8 cells per diameter, for several probe radii.
Kernels on the CPU, whichever ``warp_lamp`` is imported (run it on an older checkout for the "before" figures).
Prints Markdown.

    PYTHONPATH=$PWD python bench/experiments/wetted_resolution.py
"""

import time

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.lamp import pressure_area
from warp_lamp.measures import slot_load_ratios
from warp_lamp.scenes import scene_slot_block, scene_sphere_specimen, scene_tunnel_block
from warp_lamp.wetted import WettedSurface

P = 1.0
CELLS = (4, 6, 8)


def forces(centers, radii, rho, grid):
    """Forces of one eager update (frame coordinates in float64, then float32), and its CPU time."""
    surface = WettedSurface(grid, probe_radius=rho, device="cpu")
    pos = wp.array(grid.to_frame(centers).astype(np.float32), dtype=wp.vec3, device="cpu")
    rad = wp.array(np.asarray(radii, dtype=np.float32), device="cpu")
    surface.update(pos, rad)  # first call: allocation and, once, compilation
    t0 = time.perf_counter()
    surface.update(pos, rad)
    wp.synchronize_device("cpu")
    return surface.counts_numpy() * pressure_area(P, grid), time.perf_counter() - t0


def specimen():
    scene = scene_sphere_specimen()
    d = 2.0 * float(scene.radii.mean())
    print("## SphereTest specimen: mean pressure / P (forces at particle centres, envelope volume)\n")
    print("| rho / d | " + " | ".join(f"{c} cells/d" for c in CELLS) + " |")
    print("| --- " * (len(CELLS) + 1) + "|")
    for k in (0.25, 0.5, 1.0):
        cells = []
        for cpd in CELLS:
            grid = wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=cpd, margin=d + k * d)
            f, t = forces(scene.centers, scene.radii, k * d, grid)
            x = scene.centers - scene.center
            sigma = np.einsum("ni,nj->ij", x, f) / (4.0 / 3.0 * np.pi * scene.radius**3)
            cells.append(f"{-np.trace(sigma) / 3.0 / P:.4f} ({t:.2f} s)")
        print(f"| {k:g} | " + " | ".join(cells) + " |", flush=True)
    print()


def slot():
    scene = scene_slot_block()
    rm = float(scene.radii.mean())
    print("## Slot block: walls (-y / +y) and floor load / (P A)\n")
    print("| rho / r_mean | " + " | ".join(f"{c} cells/d" for c in CELLS) + " |")
    print("| --- " * (len(CELLS) + 1) + "|")
    for k in (0.5, 1.0, 2.0):
        cells = []
        for cpd in CELLS:
            grid = wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=cpd, margin=2 * rm + k * rm)
            f, t = forces(scene.centers, scene.radii, k * rm, grid)
            r = slot_load_ratios(scene, f, P)
            cells.append(f"{r['wall_lo']:.3f} / {r['wall_hi']:.3f}, {r['floor']:.3f} ({t:.2f} s)")
        print(f"| {k:g} | " + " | ".join(cells) + " |", flush=True)
    print()


def tunnel():
    scene = scene_tunnel_block()
    full = scene.full()
    cut = scene.cut
    rm = float(full.radii.mean())
    print(f"## Tunnel: dFz above the axis / (P L), nominal width {cut['width']:g}\n")
    print("| rho | " + " | ".join(f"{c} cells/d" for c in CELLS) + " |")
    print("| --- " * (len(CELLS) + 1) + "|")
    above = full.centers[:, 2] > cut["axis"][1]
    for rho in (0.225, 0.45, 0.9):
        cells = []
        for cpd in CELLS:
            grid = wl.LampGrid.enclosing(full.centers, full.radii, cells_per_diameter=cpd, margin=2 * rm + rho)
            f_full, _ = forces(full.centers, full.radii, rho, grid)
            f_cut, _ = forces(scene.centers, scene.radii, rho, grid)
            cells.append(f"{(f_cut[above[scene.kept], 2].sum() - f_full[above, 2].sum()) / (P * cut['length']):.3f}")
        print(f"| {rho:g} | " + " | ".join(cells) + " |", flush=True)
    print()


if __name__ == "__main__":
    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    specimen()
    slot()
    tunnel()
