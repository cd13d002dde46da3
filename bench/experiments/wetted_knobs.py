"""The exact test's run-time knobs, each setting timed in one module: the classify stage (graph replay on CUDA,
best thread time on the CPU) and a hash of the fluid map per setting, on the bench's scenes at rho = r-bar. The
answer is the same at every setting; only the time differs.

- ``--knob mask_from``: the reach masks from this many near spheres on (``WetBox.mask_from``; 1 << 20: never).
- ``--knob order``: the queued tests in voxel order (1, the default) or as the first pass's atomics take them (0).

    PYTHONPATH=$PWD python bench/experiments/wetted_knobs.py --knob order --device cuda:0 --out $OUT/order.json
"""

import argparse
import hashlib
import json
import time

import numpy as np
import warp as wp
from wetted_bench import grid_for, scenes

from warp_lamp.timing import time_median_events
from warp_lamp.wetted import WettedSurface

#: Settings per knob, and how a surface takes one.
KNOBS = {
    "mask_from": ((1 << 20, 0, 6, 9, 12, 15), lambda surf, v: setattr(surf._box, "mask_from", v)),
    "order": ((1, 0, 1, 0), lambda surf, v: surf._queue_in_order(bool(v))),
}


def stage_time(surf, pos, rad, stop, device, repeats):
    """Seconds of an update that stops after ``stop``: the median graph replay on CUDA, the best thread time of
    ``repeats`` eager updates on the CPU."""
    if device.is_cuda:
        with wp.ScopedCapture(device=device) as cap:
            surf._update(pos, rad, None, stop=stop)
        return time_median_events(lambda: wp.capture_launch(cap.graph), device, repeats=repeats)
    best = float("inf")
    for _ in range(repeats):
        t = time.thread_time()
        surf._update(pos, rad, None, stop=stop)
        best = min(best, time.thread_time() - t)
    return best


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--knob", choices=sorted(KNOBS), required=True)
    ap.add_argument("--device", default=None)
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    device = wp.get_device(args.device)
    settings, apply = KNOBS[args.knob]
    rows = []
    for name, sc, cell in scenes(args.quick):
        if args.only and name not in args.only:
            continue
        rho = float(sc.radii.mean())
        grid = grid_for(sc, cell, rho)
        pos = wp.array((sc.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
        rad = wp.array(sc.radii.astype(np.float32), dtype=wp.float32, device=device)
        surf = WettedSurface(grid, probe_radius=rho, device=device)
        surf.update(pos, rad)
        base = stage_time(surf, pos, rad, "dilate", device, args.repeats)
        for v in settings:
            apply(surf, v)
            t = stage_time(surf, pos, rad, "classify", device, args.repeats) - base
            surf._update(pos, rad, None, stop="thin")
            h = hashlib.sha1(surf.diagnostics().fluid.tobytes()).hexdigest()[:12]
            rows.append({"scene": name, "particles": sc.n, args.knob: v, "classify_s": t, "fluid_hash": h})
            print(f"{name:10s} {args.knob} {v:>8d}: classify {t * 1e3:8.3f} ms  fluid {h}", flush=True)
        del surf
    with open(args.out, "w") as f:
        json.dump({"device": str(device), "name": getattr(device, "name", ""), "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
