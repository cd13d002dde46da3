"""Walls that bound the fluid (issue 19, part 2): the platen and "pressure on the top only" figures on the issue's
random 50 mm box at 2 MPa, in the wetted mode (rho = the mean radius) and in the memo's mode, beside the old recipe
(no wall, the -z lamp off). Prints Markdown and writes JSON.

    PYTHONPATH=$PWD python bench/experiments/wetted_walls.py --device cpu \
        --out bench/results/cpu-dev-2026-11-25-walls.json

The footprint is the area of the union of the particles' disks projected along z, from a raster (pixel centres
inside a disk) of 2,000 and 4,000 pixels along the longer side: the two agree to a few 1e-5, the raster's error.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import time

import numpy as np
import warp as wp

from warp_lamp.lamp import lamp_update
from warp_lamp.scenes import scene_box_specimen

P = 2.0e6
SIDES = ["-x", "+x", "-y", "+y", "+z"]


def footprint_area(centers, radii, pixels):
    """Area of the union of the particles' disks projected along z [m^2], from a raster of ``pixels`` cells along
    the longer side of their box (a pixel counts when its centre lies inside a disk)."""
    lo = (centers[:, :2] - radii[:, None]).min(axis=0)
    hi = (centers[:, :2] + radii[:, None]).max(axis=0)
    step = float((hi - lo).max()) / pixels
    xs = lo[0] + (np.arange(int(np.ceil((hi[0] - lo[0]) / step))) + 0.5) * step
    ys = lo[1] + (np.arange(int(np.ceil((hi[1] - lo[1]) / step))) + 0.5) * step
    cover = np.zeros((len(xs), len(ys)), dtype=bool)
    for (cx, cy), r in zip(centers[:, :2], radii, strict=True):
        i0, i1 = np.searchsorted(xs, [cx - r, cx + r])
        j0, j1 = np.searchsorted(ys, [cy - r, cy + r])
        dx, dy = xs[i0:i1, None] - cx, ys[None, j0:j1] - cy
        cover[i0:i1, j0:j1] |= dx * dx + dy * dy < r * r
    return float(cover.sum()) * step * step


def run(c, r, *, mode, walls, lamps, rho, device):
    """One update on host positions; the body's force, the walls', timings and the loaded particles."""
    kw = dict(surfaces="all", probe_radius=rho) if mode == "wetted" else dict(criterion=1)
    t0 = time.perf_counter()
    lamp = lamp_update(c, r, lamps=lamps, walls=walls, device=device, **kw)
    wp.synchronize_device(device)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    lamp = lamp_update(c, r, grid=lamp.grid, lamps=lamps, walls=walls, device=device, **kw)
    wp.synchronize_device(device)
    second = time.perf_counter() - t0
    f = lamp.forces_numpy(P)
    out = dict(
        force=f.sum(axis=0).tolist(),
        loaded=int(np.abs(f).sum(axis=1).astype(bool).sum()),
        seconds_first=first,
        seconds=second,
        cells=lamp.grid.counts.tolist(),
        cell=lamp.grid.cell.tolist(),
    )
    if walls:
        out["wall_forces"] = lamp.wall_forces_numpy(P).tolist()
        d = lamp.diagnostics()
        counts = d.counts.sum(axis=0) + np.asarray(d.wall_counts).sum(axis=0)
        out["body_plus_walls_counts"] = counts.tolist()
        out["window_z"] = int(lamp.grid.counts[2].prod())
        out["cell_area"] = lamp.grid.cell_area.tolist()
    return out, f


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    device = wp.get_device(args.device)
    scene = scene_box_specimen((0.05, 0.05, 0.05), 0.005)
    c, r = scene.centers, scene.radii
    rho = float(r.mean())
    a2000 = footprint_area(c, r, 2000)
    a4000 = footprint_area(c, r, 4000)
    area = a4000
    z_low = float((c[:, 2] - r).min())
    z_top = float((c[:, 2] + r).max())
    z_mid = 0.5 * (z_low + z_top)
    z_near_top = float(c[:, 2].max()) - rho  # a radius below the highest centre: about the top layer's centres
    up = (0.0, 0.0, 1.0)
    cases = [
        ("before: no wall, -z lamp off", None, SIDES, None),
        ("platen under the lowest sphere", [((0.0, 0.0, z_low), up)], "all", None),
        ("top only: fluid above mid-height", [((0.0, 0.0, z_mid), up)], "all", z_mid),
        ("top only: fluid above the top layer's centres", [((0.0, 0.0, z_near_top), up)], "all", z_near_top),
    ]
    rows = []
    runs = [(case, mode, 1.0) for case in cases for mode in ("wetted", "memo")]
    runs += [(case, "wetted", k) for k in (0.5, 2.0) for case in cases[:2]]
    for (label, walls, lamps, cut), mode, k in runs:
        res, f = run(c, r, mode=mode, walls=walls, lamps=lamps, rho=k * rho, device=device)
        res.update(case=label, mode=mode, rho_over_mean_radius=k if mode == "wetted" else None)
        res["fz_over_minus_P_footprint"] = res["force"][2] / (-P * area)
        res["fz_over_minus_P_top"] = res["force"][2] / (-P * 0.05 * 0.05)
        if cut is not None:
            below = c[:, 2] + r < cut
            above = c[:, 2] - r > cut
            res["wall_height"] = cut
            res["wholly_below"] = int(below.sum())
            res["wholly_below_loaded"] = int(np.abs(f[below]).sum(axis=1).astype(bool).sum())
            res["wholly_above"] = int(above.sum())
            res["wholly_above_loaded"] = int(np.abs(f[above]).sum(axis=1).astype(bool).sum())
            res["fz_particles_above_wall"] = float(f[c[:, 2] > cut, 2].sum())
        rows.append(res)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    result = dict(
        device=str(device),
        name=device.name,
        machine=platform.processor() or platform.machine(),
        commit=commit,
        scene=dict(name=scene.name, particles=int(len(r)), mean_radius=rho, z_low=z_low, z_top=z_top),
        pressure=P,
        rho=rho,
        footprint_m2=dict(pixels_2000=a2000, pixels_4000=a4000),
        rows=rows,
    )
    print(
        f"{scene.name}: {len(r):,} spheres, mean radius {rho * 1e3:.3f} mm, P = {P / 1e6:g} MPa, 4 cells per "
        f"diameter, device {device} ({device.name}), commit {commit}\n"
    )
    print(
        f"footprint (union of the projected disks): {a4000 * 1e6:.1f} mm^2 (4,000 px; 2,000 px: "
        f"{a2000 * 1e6:.1f}); P A = {P * area:.1f} N; top face 50 x 50 mm: P A = {P * 0.0025:.1f} N\n"
    )
    print(
        "| case | mode | rho / r | Fx [N] | Fy [N] | Fz [N] | Fz / (-P footprint) | wall Fz [N] | loaded | update [s] |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for res in rows:
        wall = res.get("wall_forces")
        wall_z = f"{sum(w[2] for w in wall):.1f}" if wall else ""
        fx, fy, fz = res["force"]
        ratio = res["fz_over_minus_P_footprint"]
        print(
            f"| {res['case']} | {res['mode']} | {res['rho_over_mean_radius'] or ''} | {fx:.3g} | {fy:.3g} | {fz:.1f} "
            f"| {ratio:.4f} "
            f"| {wall_z} | {res['loaded']} | {res['seconds']:.3f} |"
        )
    print()
    for res in rows:
        if "wall_height" in res:
            print(
                f"- {res['case']} ({res['mode']}), wall at z = {res['wall_height'] * 1e3:.2f} mm: "
                f"{res['wholly_below_loaded']} of {res['wholly_below']} particles wholly below it loaded, "
                f"{res['wholly_above_loaded']} of {res['wholly_above']} wholly above it; Fz of the particles whose "
                f"centre is above it {res['fz_particles_above_wall']:.1f} N"
            )
        if "body_plus_walls_counts" in res:
            counts = res["body_plus_walls_counts"]
            print(
                f"- {res['case']} ({res['mode']}): body + walls counts per axis {counts} "
                f"(z window {res['window_z']:,} cells)"
            )
    if args.out:
        with open(args.out, "w") as fh:
            json.dump(result, fh, indent=1)


if __name__ == "__main__":
    main()
