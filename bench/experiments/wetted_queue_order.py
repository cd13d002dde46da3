"""The queued exact tests in voxel order (``WettedSurface._queue_in_order(True)``, the default: a prefix sum places
them) or in the order the first pass's atomics take them: the classify stage (graph replay on CUDA, best thread
time on the CPU) and a hash of the fluid map, per order, on the bench's scenes at rho = r-bar. The answer is the
same in either order; only the time differs (a warp's 32 tests take the union of their paths).

    PYTHONPATH=$PWD python bench/experiments/wetted_queue_order.py --device cuda:0 --out $OUT/queue_order.json
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

SETTINGS = (1, 0, 1, 0)  # in voxel order, as the atomics take them, twice


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--device", default=None)
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    device = wp.get_device(args.device)
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

        def timed(stop, surf=surf, pos=pos, rad=rad):
            if device.is_cuda:
                with wp.ScopedCapture(device=device) as cap:
                    surf._update(pos, rad, None, stop=stop)
                return time_median_events(lambda: wp.capture_launch(cap.graph), device, repeats=args.repeats)
            best = float("inf")
            for _ in range(args.repeats):
                t = time.thread_time()
                surf._update(pos, rad, None, stop=stop)
                best = min(best, time.thread_time() - t)
            return best

        base = timed("dilate")
        for mf in SETTINGS:
            surf._queue_in_order(bool(mf))
            t = timed("classify") - base
            surf._update(pos, rad, None, stop="thin")
            h = hashlib.sha1(surf.diagnostics().fluid.tobytes()).hexdigest()[:12]
            rows.append(dict(scene=name, particles=sc.n, order=mf, classify_s=t, fluid_hash=h))
            print(f"{name:10s} order {mf}: classify {t * 1e3:8.3f} ms  fluid {h}", flush=True)
        del surf
    with open(args.out, "w") as f:
        json.dump({"device": str(device), "name": getattr(device, "name", ""), "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
