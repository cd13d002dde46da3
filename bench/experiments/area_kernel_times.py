"""Per-kernel GPU times of one area-criterion update (Warp's CUDA activity timing, eager updates, median over
repeats), beside the update's graph replay: where the area criterion's time goes, stage by stage (seed, depth pass,
hidden rounds, cell pass, rows, payout).

Rows: the SphereTest specimen at 4 cells per diameter (criterion 1 at 4 and 32 for the ratios, sub-points D3 front,
sub-points D4 deep, exact D4 deep) and the 1M lattice box (criterion 1, sub-points D4 deep).

    python bench/experiments/area_kernel_times.py --device cuda:0 --out $OUT/area_kernel_times.json
    python bench/experiments/area_kernel_times.py --device cpu --quick          # a CPU check of the script
"""

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.bench import lattice_grid
from warp_lamp.scenes import scene_lattice_box, scene_sphere_specimen
from warp_lamp.timing import time_median_events

sys.path.insert(0, str(Path(__file__).parent))
from kernel_times import activity_times, print_top

C1 = {"criterion": 1}
S3 = {"criterion": "area", "resolver": "subpoints", "depth_slots": 3, "subpoints": 8}
DEEP = {"criterion": "area", "resolver": "subpoints", "depth_slots": 4, "subpoints": 8, "gather": "deep"}
EXACT_DEEP = {"criterion": "area", "resolver": "exact", "depth_slots": 4, "gather": "deep"}


def one_row(label, scene, grid, options, device, repeats):
    lamp = wl.ShiningLamp(grid, device=device, **options)
    pos = wp.array(grid.to_frame(scene.centers).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)

    def update():
        lamp.update(pos, rad, in_frame=True)

    update()
    update()
    counts = lamp.counts_numpy()
    row = {"row": label, "options": options, "hash": hashlib.sha256(counts.tobytes()).hexdigest()[:16]}
    if device.is_cuda:
        with wp.ScopedCapture(device=device) as cap:
            update()
        row["replay_ms"] = 1e3 * time_median_events(lambda: wp.capture_launch(cap.graph), device, repeats=3 * repeats)
        row["kernels_ms"] = activity_times(update, repeats)
    else:
        row["replay_ms"] = 1e3 * time_median_events(update, device, repeats=repeats)
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--quick", action="store_true", help="the specimen's rows only (a CPU check of the script)")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    wp.init()
    device = wp.get_device(args.device)
    spec = scene_sphere_specimen()
    plan = [("specimen C1 at 4", spec, 4, C1), ("specimen C1 at 32", spec, 32, C1)]
    plan += [("specimen S3 at 4", spec, 4, S3), ("specimen S4 deep at 4", spec, 4, DEEP)]
    plan += [("specimen S4 deep at 3", spec, 3, DEEP), ("specimen exact D4 deep at 4", spec, 4, EXACT_DEEP)]
    if not args.quick:
        box = scene_lattice_box(100)
        plan += [("1M C1", box, None, C1), ("1M S4 deep", box, None, DEEP)]
    out = {"device": str(device), "name": device.name, "rows": []}
    for label, scene, k, options in plan:
        if args.quick and label.startswith("specimen C1 at 32"):
            continue
        grid = (
            lattice_grid(scene, 0.25)
            if k is None
            else wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=k)
        )
        row = one_row(label, scene, grid, options, device, args.repeats)
        out["rows"].append(row)
        ks = row.get("kernels_ms", {})
        print(
            f"== {label}: replay {row['replay_ms']:.4f} ms, kernels sum {sum(ks.values()):.4f} ms, counts {row['hash']}"
        )
        print_top(ks, 10)
        sys.stdout.flush()
    if args.out:
        Path(args.out).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
