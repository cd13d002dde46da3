"""The rock cut's wetted update, stage by stage (issue 32: measure before fixing): the study's slab on its lamp
grid (the following grid's capacity: the slab's box with room for the broken material), the particles as packed
(before any cut) and, optionally, with a fraction of them thrown as debris to the domain's edges.

    PYTHONPATH=$PWD python bench/experiments/rockcut_wetted_profile.py --device cpu
"""

import argparse
import hashlib
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
    import warp_lamp as wl
    from warp_lamp.scenes import scene_box_specimen

    # The example's slab and lamp grid (RockCutting.__init__), without its DEM: no DEM module compiles here.
    c = rc.TINY if args.tiny else rc.STUDY
    dd = c.particle_diameter
    size = np.array([c.length, c.width, c.height]) * dd
    scene = scene_box_specimen(size, dd, seed=c.seed)
    r = np.asarray(scene.radii, dtype=np.float64) * (1.0 - rc.rock_mod.SHRINK)
    d_mean = 2.0 * float(r.mean())
    probe = c.probe_radius * 0.5 * d_mean
    depth = c.depth * dd
    frame_center = np.asarray(scene.center, dtype=np.float64)
    side = rc.DOMAIN_SIDE * depth + dd
    domain = (np.array([-side, -side, -dd]), size + np.array([side, side, rc.DOMAIN_TOP * depth]))
    cell = d_mean / c.cells_per_diameter
    pad = float(r.max()) + probe + cell
    grid = wl.LampGrid(domain[0] - frame_center - pad, domain[1] - frame_center + pad, cell)
    x0 = np.asarray(scene.centers, dtype=np.float64) - frame_center
    lo = grid.origin
    hi = grid.origin + grid.box_counts * grid.box_cell
    rows = []
    rng = np.random.default_rng(1)
    for frac in args.debris:
        x = x0.copy()
        k = rng.choice(len(x), int(frac * len(x)), replace=False)
        # Debris: spread over the domain above and beside the slab (the following grid's room for it).
        x[k] = rng.uniform(lo + 2 * r.max(), hi - 2 * r.max(), (len(k), 3))
        surf = WettedSurface(grid, probe_radius=probe, device=device)
        pos = wp.array((x - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
        rad = wp.array(r.astype(np.float32), dtype=wp.float32, device=device)
        surf.update(pos, rad)
        d = surf.diagnostics()
        row = dict(debris=frac, particles=len(r), voxels=list(surf.shape), rounds=d.rounds, tested=d.uncertain)
        # Fluid map, rays and counts, to compare two versions bitwise.
        raw = surf.fluid.numpy().tobytes() + surf.rays.numpy().tobytes() + surf.counts_numpy().tobytes()
        row["hash"] = hashlib.sha1(raw).hexdigest()
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
