"""CPU (or any device) update time of the area criterion on the SphereTest specimen (issue 19's before/after).

    PYTHONPATH=. python bench/experiments/area_timing.py --cpd 4 --repeats 7
    PYTHONPATH=/tmp/a7331c6 python bench/experiments/area_timing.py   # the original code, same machine

Median of ``repeats`` eager updates (``warp_lamp.bench.modes.time_update``, no moving body), per resolver and D;
also the overlapping polydisperse ball when ``--overlap`` names its npz (area_overlap.py --save-scene).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from warp_lamp import LampGrid, ShiningLamp
from warp_lamp.bench.modes import time_update
from warp_lamp.scenes import Scene, scene_sphere_specimen


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cpd", type=float, nargs="+", default=[4.0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--overlap", help="npz of the overlapping ball (centers, radii)")
    ap.add_argument("--json")
    args = ap.parse_args()
    scenes = [scene_sphere_specimen()]
    if args.overlap:
        d = np.load(args.overlap)
        scenes.append(Scene("overlapping polydisperse ball", d["centers"], d["radii"], np.zeros(3)))
    rows = []
    print("| scene | cells/d | resolver | D | update ms |")
    print("| --- | --- | --- | --- | --- |")
    for scene in scenes:
        for cpd in args.cpd:
            grid = LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=cpd)
            for resolver, slots in (("subpoints", 3), ("exact", 3), ("exact", 4)):
                lamp = ShiningLamp(grid, criterion="area", resolver=resolver, depth_slots=slots, device=args.device)
                t = time_update(lamp, scene, args.device, repeats=args.repeats, moving=False)
                row = dict(scene=scene.name, cells_per_diameter=cpd, resolver=resolver, depth_slots=slots, **t)
                rows.append(row)
                print(f"| {scene.name} | {cpd:g} | {resolver} | {slots} | {1e3 * t['update_s']:.1f} |", flush=True)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
