"""Why the area criterion misses spheres on the lattice balls, and which gather finds them (reference only, CPU).

For each scene (the table's lattice balls, the specimen) at 4 cells per diameter: the per-particle force error
(``visible_area_error`` against the exact visible areas) of the reference estimator
(``area_estimate_reference``) with its gather as shipped and with the study hooks: D slots, seeds from both lamps'
keys (``_cell_seeds="both"``), the depth pass without the spheres one other sphere hides (``_hidden_rounds``,
``hidden_spheres``). And ``--misses``: for the low x lamp, the visible area (16 x 16 points per cell, first surface
by brute force) that goes to a sphere the cell did not gather, by the shallowest slot that sphere holds at the
cell's corners: a gather that reads deeper at the corners finds it, one that reads more rays does not.

    PYTHONPATH=. python bench/experiments/area_gather_study.py --scenes small --json out.json
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

import warp_lamp as wl
from warp_lamp.measures import visible_area_error
from warp_lamp.reference import area_depth_slots, area_estimate_reference, visible_area_reference
from warp_lamp.reference.area import _EMPTY, _LOW32, CORNERS, _frame
from warp_lamp.scenes import scene_lattice_ball, scene_sphere_specimen
from warp_lamp.validate import LAMPS

SCENES = {
    "small": lambda: scene_lattice_ball(diameter=0.05),
    "big": scene_lattice_ball,
    "specimen": scene_sphere_specimen,
}
#: (D, resolver, hooks).
VARIANTS = (
    (3, "subpoints", {}),
    (3, "subpoints", {"_hidden_rounds": 2}),
    (3, "subpoints", {"_cell_seeds": "both", "_hidden_rounds": 2}),
    (4, "subpoints", {"_cell_seeds": "both", "_hidden_rounds": 2}),
    (4, "exact", {}),
    (4, "exact", {"_hidden_rounds": 2}),
    (4, "exact", {"_cell_seeds": "both"}),
    (4, "exact", {"_cell_seeds": "both", "_hidden_rounds": 2}),
)


def error(scene, grid, exact, d, resolver, hooks) -> dict:
    est = area_estimate_reference(scene.centers, scene.radii, grid, depth_slots=d, resolver=resolver, **hooks)
    cell_area = np.array([grid.cell[a, 0] * grid.cell[a, 1] for a in range(3)])
    rms = visible_area_error(est.units * cell_area / est.unit, exact, 1.0, float(scene.radii.mean()))["rms"]
    return {"rms": rms, "overflow": est.stats["overflow"], "seeds": est.stats["seeds"]}


def misses(scene, grid, d, points=16) -> dict:
    """Low x lamp: fraction of the visible area won by a sphere its cell did not gather, by that sphere's
    shallowest slot at the cell's corners (of 64 kept)."""
    est = area_estimate_reference(scene.centers, scene.radii, grid, depth_slots=d, details=True, lamps=[LAMPS[0]])
    deep, off = area_depth_slots(scene.centers, scene.radii, grid, depth_slots=64, lamps=[LAMPS[0]])
    q, r, axes = _frame(scene.centers, scene.radii, grid, np.ones(len(scene.radii), bool))
    cu, cv, hu, hv, nu, nv = axes[0]
    pu, pv = (q[:, 1] - cu).astype(np.float64), (q[:, 2] - cv).astype(np.float64)
    pz, r = q[:, 0].astype(np.float64), r.astype(np.float64)
    cells = est.cells[LAMPS[0]]
    gathered = {int(c): set(s[s >= 0].tolist()) for c, s in zip(cells["cell"], cells["seeds"], strict=True)}
    total, by_slot = 0, {}
    for cell in range(nu * nv):
        i, j = cell % nu, cell // nu
        x0, y0 = i * hu, j * hv
        gx = np.maximum(np.maximum(x0 - pu, pu - (x0 + hu)), 0)
        gy = np.maximum(np.maximum(y0 - pv, pv - (y0 + hv)), 0)
        cand = np.flatnonzero(gx * gx + gy * gy < r * r)
        if len(cand) == 0:
            continue
        tx, ty = np.meshgrid(x0 + (np.arange(points) + 0.5) * hu / points, y0 + (np.arange(points) + 0.5) * hv / points)
        d2 = (tx[None] - pu[cand, None, None]) ** 2 + (ty[None] - pv[cand, None, None]) ** 2
        rr = r[cand, None, None] ** 2
        z = np.where(d2 <= rr, pz[cand, None, None] - np.sqrt(np.maximum(rr - d2, 0)), np.inf)
        hit = np.isfinite(z.min(axis=0))
        won, n = np.unique(cand[np.argmin(z, axis=0)[hit]], return_counts=True)
        total += int(n.sum())
        for p, k in zip(won, n, strict=True):
            if p in gathered.get(cell, ()):
                continue
            slots = []
            for di, dj in CORNERS:
                s = off[0] + (j + dj) * (nu + 1) + (i + di)
                ks = deep[2 * s * 64 : 2 * s * 64 + 64]
                w = np.flatnonzero((ks != _EMPTY) & ((ks & _LOW32).astype(np.int64) == p))
                if len(w):
                    slots.append(int(w[0]))
            key = str(min(slots)) if slots else "none"
            by_slot[key] = by_slot.get(key, 0) + int(k)
    return {"missed": sum(by_slot.values()) / max(total, 1), "by_slot": {k: v / total for k, v in by_slot.items()}}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", default="small,big")
    ap.add_argument("--misses", action="store_true")
    ap.add_argument("--json")
    args = ap.parse_args()
    out = []
    for name in args.scenes.split(","):
        scene = SCENES[name]()
        grid = wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=4)
        t0 = time.perf_counter()
        exact = visible_area_reference(scene.centers, scene.radii)
        print(f"{name}: {scene.n} spheres, exact areas {time.perf_counter() - t0:.0f} s", flush=True)
        for d, resolver, hooks in VARIANTS:
            row = {"scene": name, "depth_slots": d, "resolver": resolver, "hooks": hooks}
            row.update(error(scene, grid, exact, d, resolver, hooks))
            out.append(row)
            print(f"  D{d} {resolver:<9} {hooks!s:<48} {100 * row['rms']:.3f}%  overflow {row['overflow']}", flush=True)
        if args.misses:
            for d in (3, 4):
                m = misses(scene, grid, d)
                out.append({"scene": name, "depth_slots": d, "misses": m})
                print(f"  misses D{d}: {m}", flush=True)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump({"device": "cpu (reference, NumPy)", "rows": out}, f, indent=1)


if __name__ == "__main__":
    main()
