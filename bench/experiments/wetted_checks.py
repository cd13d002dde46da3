"""Issue 10's checks beside the slot: the sealed cavity, the tunnel, and the convex SphereTest specimen, each with
the wetted-surface kernels (CPU) and, for the specimen, today's first-surface lamp. Prints Markdown.

    PYTHONPATH=$PWD python bench/experiments/wetted_checks.py
"""

import time

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.lamp import pressure_area
from warp_lamp.scenes import scene_cavity_block, scene_sphere_specimen, scene_tunnel_block
from warp_lamp.wetted import WettedSurface

P = 1.0


def wetted_solve(centers, radii, *, probe_radius, grid, device="cpu", **kw):
    """The wetted-surface engine on host positions (frame coordinates in float64, then float32)."""
    surface = WettedSurface(grid, probe_radius=probe_radius, device=device, **kw)
    pos = wp.array(grid.to_frame(centers).astype(np.float32), dtype=wp.vec3, device=device)
    surface.update(pos, wp.array(np.asarray(radii, dtype=np.float32), device=device))
    return surface


def forces(centers, radii, rho, grid):
    s = wetted_solve(centers, radii, probe_radius=rho, grid=grid, device="cpu")
    d = s.diagnostics()
    assert d.unattributed == 0 and not np.any(d.counts.sum(axis=0))
    return d.counts * pressure_area(P, grid), d


def cavity():
    scene = scene_cavity_block()
    full = scene.full()
    print(f"## Sealed cavity: {scene.name}, {scene.n:,} of {full.n:,} particles kept, 4 cells per diameter\n")
    print("| rho | particles whose force differs | removed particles loaded in the full block | max abs diff / (P A) |")
    print("| --- | --- | --- | --- |")
    grid = wl.LampGrid.enclosing(full.centers, full.radii, cells_per_diameter=4, margin=2.0)
    removed = np.setdiff1d(np.arange(full.n), scene.kept)
    area = pressure_area(P, grid)[0]
    for rho in (0.1, 0.225, 0.3, 0.45, 0.9):
        f_full, _ = forces(full.centers, full.radii, rho, grid)
        f_cut, _ = forces(scene.centers, scene.radii, rho, grid)
        diff = np.any(f_cut != f_full[scene.kept], axis=1)
        big = np.abs(f_cut - f_full[scene.kept]).max() / area
        print(f"| {rho:g} | {int(diff.sum())} | {int(np.any(f_full[removed] != 0, axis=1).sum())} | {big:g} |")
    print()


def tunnel():
    scene = scene_tunnel_block()
    full = scene.full()
    cut = scene.cut
    print(
        f"## Tunnel: {scene.name}, length {cut['length']:g}, nominal width {cut['width']:g} (removed columns), "
        "4 cells per diameter\n"
    )
    print("| rho | dFz above the axis / (P L) | minus nominal width | tunnel-wall particles loaded | rounds |")
    print("| --- | --- | --- | --- | --- |")
    rmean = float(full.radii.mean())
    for rho in (0.1, 0.225, 0.45, 0.9):
        grid = wl.LampGrid.enclosing(full.centers, full.radii, cells_per_diameter=4, margin=2 * rmean + rho)
        f_full, _ = forces(full.centers, full.radii, rho, grid)
        f_cut, d = forces(scene.centers, scene.radii, rho, grid)
        above = full.centers[:, 2] > cut["axis"][1]
        width = (f_cut[above[scene.kept], 2].sum() - f_full[above, 2].sum()) / (P * cut["length"])
        centre = (np.asarray(scene.block["n_per_axis"][1:]) - 1) / 2.0
        ring = np.hypot(*(scene.index[:, 1:] - centre).T) < cut["radius"] + 1.0
        print(
            f"| {rho:g} | {width:.3f} | {width - cut['width']:+.3f} | {int(d.surface[ring].sum())} of "
            f"{int(ring.sum())} | {d.rounds} |"
        )
    print()


def envelope_mean_pressure(scene, f):
    x = scene.centers - scene.center
    sigma = np.einsum("ni,nj->ij", x, f) / (4.0 / 3.0 * np.pi * scene.radius**3)
    return -np.trace(sigma) / 3.0 / P


def specimen():
    scene = scene_sphere_specimen()
    d_mean = 2.0 * float(scene.radii.mean())
    depth = scene.radius - np.linalg.norm(scene.centers - scene.center, axis=1) - scene.radii
    print(
        f"## Convex specimen: SphereTest, {scene.n:,} particles, mean diameter {d_mean * 1e3:.3f} mm, "
        "4 cells per diameter\n"
    )
    print(
        "| mode | loaded particles | of them deeper than one diameter | mean pressure / P (envelope) | "
        "loaded only here / only by first | CPU time |"
    )
    print("| --- | --- | --- | --- | --- | --- |")
    t0 = time.perf_counter()
    lamp = wl.lamp_update(scene.centers, scene.radii, cells_per_diameter=4, device="cpu")
    f1 = lamp.counts_numpy() * pressure_area(P, lamp.grid)
    t1 = time.perf_counter()
    first = lamp.diagnostics().surface
    print(
        f'| "first" | {int(first.sum()):,} | {int((first & (depth > d_mean)).sum())} | '
        f"{envelope_mean_pressure(scene, f1):.4f} | | {t1 - t0:.2f} s |"
    )
    for k in (0.5, 1, 2, 3, 5):
        rho = k * d_mean
        t0 = time.perf_counter()
        grid = wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=4, margin=d_mean + rho)
        f, d = forces(scene.centers, scene.radii, rho, grid)
        t1 = time.perf_counter()
        s = d.surface
        print(
            f"| all, rho = {k:g} d | {int(s.sum()):,} | {int((s & (depth > d_mean)).sum())} | "
            f"{envelope_mean_pressure(scene, f):.4f} | {int((s & ~first).sum())} / {int((first & ~s).sum())} | "
            f"{t1 - t0:.2f} s, {d.rounds} rounds |"
        )
    print()


if __name__ == "__main__":
    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    cavity()
    tunnel()
    specimen()
