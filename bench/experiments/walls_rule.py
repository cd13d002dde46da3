"""Walls in the memo's mode: a platen at rest and lifted, and the single-sphere cases, against geometry. Prints
Markdown, writes JSON and the figure of docs/guide/walls.md.

    PYTHONPATH=$PWD python bench/experiments/walls_rule.py --device cpu \
        --out bench/results/cpu-dev-2026-11-28-walls-rule.json --figure docs/walls_platen_lift.png

The platen: the random 50 mm box of ``bench/experiments/wetted_walls.py`` (1,022 spheres, 4 cells per mean
diameter, P = 2 MPa) on a wall at its lowest sphere's bottom, then lifted by a multiple of the mean radius (and
pushed in: a DEM overlap). The reference is P times the footprint (the union of the projected disks, raster).
The single sphere (R = 1, 32 cells per diameter): the expected force from the geometry of the wet part.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import warp as wp

from warp_lamp.grid import LampGrid
from warp_lamp.lamp import lamp_update
from warp_lamp.scenes import scene_box_specimen

sys.path.insert(0, str(Path(__file__).resolve().parent))
from wetted_walls import footprint_area

P = 2.0e6
LIFTS = [-0.05, 0.0, 0.05, 0.1, 0.15, 0.25, 0.5, 1.0, 2.0]


def platen(device):
    """Body Fz over -P footprint and the platen's Fz for each lift, memo's mode (criterion 1) and wetted (rho = r)."""
    scene = scene_box_specimen((0.05, 0.05, 0.05), 0.005)
    c, r = scene.centers, scene.radii
    rbar = float(r.mean())
    area = footprint_area(c, r, 4000)
    z_low = float((c[:, 2] - r).min())
    grid = LampGrid.enclosing(c, r, cells_per_diameter=4, margin=3.0 * rbar)
    wgrid = LampGrid.enclosing(c, r, cells_per_diameter=4, margin=3.0 * rbar, probe_radius=rbar)
    rows = []
    for lift in LIFTS:
        walls = [((0.0, 0.0, z_low - lift * rbar), (0.0, 0.0, 1.0))]
        row = dict(lift_over_mean_radius=lift)
        for mode, kw, g in (
            ("memo", dict(criterion=1), grid),
            ("wetted", dict(surfaces="all", probe_radius=rbar), wgrid),
        ):
            lamp = lamp_update(c, r, grid=g, walls=walls, device=device, **kw)
            f = lamp.forces_numpy(P)
            d = lamp.diagnostics()
            wall = lamp.wall_forces_numpy(P)
            window = float(g.cell_area[2] * g.counts[2].prod())
            row[mode] = dict(
                fz=float(f[:, 2].sum()),
                fx_fy=[float(f[:, 0].sum()), float(f[:, 1].sum())],
                ratio=float(f[:, 2].sum() / (-P * area)),
                wall_fz=float(wall[0, 2]),
                wall_over_minus_P_window=float(wall[0, 2] / (-P * window)),
                body_plus_walls_counts=(d.counts.sum(axis=0) + d.wall_counts.sum(axis=0)).tolist(),
                window_cells=int(g.counts[2].prod()),
            )
        rows.append(row)
    return dict(particles=int(len(r)), mean_radius=rbar, footprint_m2=area, z_low=z_low, rows=rows)


def sphere_cases(device):
    """The single-sphere cases: Fz (or F) over P pi R^2, against the geometry."""
    c, r = np.zeros((1, 3)), np.array([1.0])
    g = LampGrid.enclosing(c, r, cells_per_diameter=32)
    n = np.ones(3) / np.sqrt(3.0)
    diag = [-(0.5**0.5), 0.0, -(0.5**0.5)]
    cases = [
        ("sphere 1 R above a floor", [((0, 0, -2.0), (0, 0, 1))], [0.0, 0.0, 0.0]),
        ("fluid level at z = -0.5 R", [((0, 0, -0.5), (0, 0, 1))], [0.0, 0.0, -0.75]),
        ("fluid level at z = +0.5 R", [((0, 0, 0.5), (0, 0, 1))], [0.0, 0.0, -0.75]),
        ("wall through the centre, n = (1,1,1)/sqrt(3)", [((0, 0, 0), tuple(n))], (-n).tolist()),
        (
            "wall through the centre, n = (1e200, 0, 1e200)",
            [((0, 0, 0), (1e200, 0, 1e200))],
            diag,
        ),
        (
            "wall through the centre, n = (1e-200, 0, 1e-200)",
            [((0, 0, 0), (1e-200, 0, 1e-200))],
            diag,
        ),
    ]
    out = []
    for label, walls, want in cases:
        lamp = lamp_update(c, r, grid=g, walls=walls, device=device)
        f = lamp.forces_numpy(1.0)[0] / np.pi
        out.append(dict(case=label, got=f.tolist(), expected=want))
    return out


def figure(res, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = res["rows"]
    x = [row["lift_over_mean_radius"] for row in rows]
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for mode, style in (("memo", "o-"), ("wetted", "s--")):
        ax.plot(x, [-row[mode]["ratio"] for row in rows], style, label=f"body, {mode}")
    ax.axvspan(-0.1, 0.1, color="0.9", label="rests (|gap| <= 0.1 r)")
    ax.axhline(-1.0, color="0.5", lw=0.8)
    ax.set_xscale("symlog", linthresh=0.1)
    ax.set_xlabel("platen lifted below the lowest sphere [mean radii]")
    ax.set_ylabel("body Fz / (P x footprint)")
    ax.set_title(f"{res['particles']:,}-sphere box on a platen, P = 2 MPa, 4 cells per diameter", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", default=None)
    ap.add_argument("--figure", default=None)
    args = ap.parse_args()
    device = wp.get_device(args.device)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    res = platen(device)
    res["spheres"] = sphere_cases(device)
    machine = platform.processor() or platform.machine()
    res.update(device=str(device), name=device.name, machine=machine, commit=commit)
    print(f"device {device} ({device.name}), commit {commit}; footprint {res['footprint_m2'] * 1e6:.1f} mm^2\n")
    print(
        "| lift / r | memo Fz / (-P A) | memo platen / (-P window) | wetted Fz / (-P A) | wetted platen / (-P window) |"
    )
    print("| --- | --- | --- | --- | --- |")
    for row in res["rows"]:
        m, w = row["memo"], row["wetted"]
        print(
            f"| {row['lift_over_mean_radius']:g} | {m['ratio']:.4f} | {m['wall_over_minus_P_window']:.4f} "
            f"| {w['ratio']:.4f} | {w['wall_over_minus_P_window']:.4f} |"
        )
    print("\n| case | F / (P pi R^2) | expected |")
    print("| --- | --- | --- |")
    for s in res["spheres"]:
        got = ", ".join(f"{v:.4f}" for v in s["got"])
        want = ", ".join(f"{v:.4f}" for v in s["expected"])
        print(f"| {s['case']} | {got} | {want} |")
    if args.out:
        Path(args.out).write_text(json.dumps(res, indent=1))
    if args.figure:
        figure(res, args.figure)


if __name__ == "__main__":
    main()
