"""Issue 15: where the area criterion's update time goes, stage by stage (seed, depth pass, per-cell pass), against
criterion 1 on the same grid; one run, one CUDA device.

Each stage is timed as the difference of captured graphs (seed; seed + depth; seed + depth + cells), CUDA-event
medians of replays. Variants: the defaults (8 x 8 sub-points, D = 3), 4 x 4 sub-points, D = 2, the exact resolver.

    python bench/experiments/area_stages.py --json out.json
"""

import argparse
import json

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.bench import lattice_grid
from warp_lamp.scenes import scene_lattice_box, scene_sphere_specimen
from warp_lamp.timing import run_header, time_median_events

wp.config.log_level = wp.LOG_WARNING


def scenes(quick):
    spec = scene_sphere_specimen()
    for k in (2, 3, 4):
        yield f"specimen d/{k}", spec, wl.LampGrid.enclosing(spec.centers, spec.radii, cells_per_diameter=k)
    if quick:
        return
    box = scene_lattice_box(100)
    yield "lattice 1M cell 0.25", box, lattice_grid(box, 0.25)


VARIANTS = (
    ("criterion 1", {"criterion": 1}),
    ("area S8 D3", {"criterion": "area"}),
    ("area S4 D3", {"criterion": "area", "subpoints": 4}),
    ("area S8 D2", {"criterion": "area", "depth_slots": 2}),
    ("area S8 D1", {"criterion": "area", "depth_slots": 1}),
    ("area exact D3", {"criterion": "area", "resolver": "exact"}),
)


def stages(scene, grid, options, device, repeats):
    lamp = wl.ShiningLamp(grid, device=device, **options)
    pos = wp.array(grid.to_frame(scene.centers).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    lamp.update(pos, rad, in_frame=True)
    steps = (lamp.launch_seed, lamp.launch_depth, lamp.launch_scatter)
    out = {}
    for k, name in enumerate(("seed", "depth", "cells")):
        with wp.ScopedCapture(device=device) as cap:
            for step in steps[: k + 1]:
                step()
        out[name] = time_median_events(lambda c=cap: wp.capture_launch(c.graph), device, repeats=repeats)
    with wp.ScopedCapture(device=device) as cap:
        lamp.update(pos, rad, in_frame=True)
    out["update"] = time_median_events(lambda: wp.capture_launch(cap.graph), device, repeats=repeats)
    return {
        "seed_s": out["seed"],
        "depth_s": out["depth"] - out["seed"],
        "cells_s": out["cells"] - out["depth"],
        "update_s": out["update"],
        "split": lamp.split,
    }


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--json")
    parser.add_argument("--repeats", type=int, default=50)
    args = parser.parse_args()
    device = wp.get_device("cuda:0" if wp.get_cuda_device_count() else "cpu")
    rows = []
    for label, scene, grid in scenes(args.quick):
        for name, options in VARIANTS:
            t = stages(scene, grid, options, device, args.repeats)
            rows.append({"scene": label, "variant": name, **t})
            print(
                f"{label:<22} {name:<14} split {t['split']:>2}  seed {t['seed_s'] * 1e3:7.3f}  depth "
                f"{t['depth_s'] * 1e3:7.3f}  cells {t['cells_s'] * 1e3:7.3f}  update {t['update_s'] * 1e3:7.3f} ms",
                flush=True,
            )
    if args.json:
        with open(args.json, "w") as f:
            json.dump({**run_header([device]), "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
