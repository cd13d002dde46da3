"""The wetted surface's accuracy on a lone sphere: its load against the exact P pi r^2, beside criterion 1.

A sphere of radius r at the origin, grids of ``cells_per_diameter`` cells per diameter whose lower corner is
offset by a random fraction of a cell per axis (seeded; the same offsets for every mode, so that the columns
compare like with like), only the ``-x`` lamp on. The load is the x-force over ``P pi r^2``: its mean and RMS error
over the offsets, for ``surfaces="all"`` at each probe radius rho (in cells) and for criterion 1 (the first-surface
lamp) on the same grids. Run it as a module for the table and a JSON file::

    PYTHONPATH=$PWD python -m warp_lamp.bench.wetted --out bench/results/cpu-dev-2026-11-25-wetted-convergence.json
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np
import warp as wp

__all__ = ["CELLS", "RHO_CELLS", "format_convergence", "lone_sphere_convergence"]

#: Cells per diameter of the table.
CELLS = (4, 8, 16)
#: Probe radii of the table, in cells.
RHO_CELLS = (0.0, 0.25, 0.5, 1.0, 2.0, 4.0)


def _grid(radius: float, h: float, rho: float, offset):
    from warp_lamp.grid import LampGrid

    m = int(np.ceil((radius + rho) / h)) + 3  # the probe's margin plus three cells
    lower = -m * h - np.asarray(offset) * h
    return LampGrid(lower, lower + (2 * m + 2) * h, h)


def lone_sphere_convergence(
    *, cells=CELLS, rho_cells=RHO_CELLS, offsets: int = 32, seed: int = 0, radius: float = 0.5, device=None
) -> dict:
    """The lone sphere's ``-x`` load over ``P pi r^2``, per cells per diameter and probe radius.

    Args:
        cells: Cells per diameter.
        rho_cells: Probe radii rho in cells (h = 2 r / cells).
        offsets: Random grid offsets per resolution (the same for every rho and for criterion 1).
        seed: Seed of the offsets.
        radius: Sphere radius r [m].
        device: Warp device.

    Returns:
        ``{"rows": [...], ...}``: a row per (cells, rho) with ``mean``, ``rms`` (of load / (P pi r^2) - 1) and the
        per-offset ``loads``; criterion 1's rows have ``rho_cells`` None.
    """
    from warp_lamp import lamp_forces

    device = wp.get_device(device)
    rng = np.random.default_rng(seed)
    exact = np.pi * radius * radius
    rows = []
    t0 = time.perf_counter()
    for cpd in cells:
        h = 2.0 * radius / cpd
        offs = rng.random((offsets, 3))
        modes = [(None, {"criterion": 1})]
        modes += [(k, {"surfaces": "all", "probe_radius": k * h}) for k in rho_cells]
        for k, options in modes:
            loads = []
            for off in offs:
                grid = _grid(radius, h, (k or 0.0) * h, off)
                f = lamp_forces([[0.0, 0.0, 0.0]], [radius], 1.0, grid=grid, lamps=["-x"], device=device, **options)
                loads.append(float(f[0, 0]) / exact)
            err = np.asarray(loads) - 1.0
            rows.append(
                {
                    "cells_per_diameter": cpd,
                    "rho_cells": k,
                    "mean": float(np.mean(loads)),
                    "rms": float(np.sqrt(np.mean(err * err))),
                    "loads": loads,
                }
            )
    return {
        "device": str(device),
        "host": platform.node(),
        "radius": radius,
        "offsets": offsets,
        "seed": seed,
        "seconds": time.perf_counter() - t0,
        "rows": rows,
    }


def format_convergence(result: dict) -> str:
    """Markdown: a row per cells per diameter, mean / RMS error per rho, criterion 1 last."""
    rows = result["rows"]
    rhos = [r["rho_cells"] for r in rows if r["rho_cells"] is not None]
    rhos = list(dict.fromkeys(rhos))
    head = "| cells/d | " + " | ".join(f"rho = {k:g} h" for k in rhos) + " | criterion 1 |"
    lines = [head, "| --- " * (len(rhos) + 2) + "|"]
    for cpd in dict.fromkeys(r["cells_per_diameter"] for r in rows):
        cells = {r["rho_cells"]: r for r in rows if r["cells_per_diameter"] == cpd}
        text = [f"{cells[k]['mean']:.4f} / {cells[k]['rms']:.4f}" for k in [*rhos, None]]
        lines.append(f"| {cpd:g} | " + " | ".join(text) + " |")
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default=None)
    ap.add_argument("--offsets", type=int, default=32)
    ap.add_argument("--out", default=None, help="JSON file for the result")
    args = ap.parse_args(argv)
    wp.config.quiet = True
    result = lone_sphere_convergence(offsets=args.offsets, device=args.device)
    print(
        f"Lone sphere, load / (P pi r^2): mean / RMS error over {result['offsets']} grid offsets ({result['device']})"
    )
    print()
    print(format_convergence(result))
    if args.out:
        with open(args.out, "w") as f:
            json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
