"""The rock cut's wetted update, stage by stage (issue 32: measure before fixing): the study's slab on its lamp
grid (the following grid's capacity: the slab's box with room for the broken material), the particles as packed
(before any cut) and, optionally, with a fraction of them thrown as debris to the domain's edges.

    PYTHONPATH=$PWD python bench/experiments/rockcut_wetted_profile.py --device cpu
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "examples"))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--device", default=None)
    ap.add_argument("--tiny", action="store_true")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--debris", type=float, nargs="*", default=[0.0, 0.1])
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    import rock_cutting as rc

    from warp_lamp.timing import time_median_events
    from warp_lamp.wetted import WettedSurface

    device = wp.get_device(args.device)
    cut = rc.RockCutting(rc.TINY if args.tiny else rc.STUDY, surfaces="all", device=device)
    grid = cut.grid
    x0 = np.asarray(cut.rock.centers, dtype=np.float64) - cut.frame_center
    r = np.asarray(cut.rock.radii, dtype=np.float64)
    lo = grid.origin
    hi = grid.origin + grid.box_counts * grid.box_cell
    rows = []
    rng = np.random.default_rng(1)
    for frac in args.debris:
        x = x0.copy()
        k = rng.choice(len(x), int(frac * len(x)), replace=False)
        # Debris: spread over the domain above and beside the slab (the following grid's room for it).
        x[k] = rng.uniform(lo + 2 * r.max(), hi - 2 * r.max(), (len(k), 3))
        surf = WettedSurface(grid, probe_radius=cut.probe_radius, device=device)
        pos = wp.array((x - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
        rad = wp.array(r.astype(np.float32), dtype=wp.float32, device=device)
        surf.update(pos, rad)
        d = surf.diagnostics()
        row = dict(debris=frac, particles=len(r), voxels=list(surf.shape), rounds=d.rounds, tested=d.uncertain)
        prev = 0.0
        for s in surf.STAGES:
            if device.is_cuda:
                with wp.ScopedCapture(device=device) as cap:
                    surf._update(pos, rad, None, stop=s)
                t = time_median_events(lambda g=cap.graph: wp.capture_launch(g), device, repeats=20)
            else:
                t = float("inf")
                for _ in range(args.repeats):
                    a = time.thread_time()
                    surf._update(pos, rad, None, stop=s)
                    t = min(t, time.thread_time() - a)
            row[f"{s}_s"] = t - prev
            prev = t
        row["total_s"] = prev
        rows.append(row)
        st = ", ".join(f"{s} {row[f'{s}_s'] * 1e3:.1f}" for s in surf.STAGES)
        print(
            f"debris {frac:.2f}: {row['voxels']} voxels, {row['particles']} particles, {row['rounds']} rounds, "
            f"{row['tested']} tested; total {prev * 1e3:.1f} ms: {st}",
            flush=True,
        )
    if args.out:
        with open(args.out, "w") as f:
            json.dump({"device": str(device), "name": getattr(device, "name", ""), "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
