"""Per-kernel GPU times of one wetted update (Warp's CUDA activity timing, eager updates, median over repeats), for
the bench's scenes at rho = r-bar; variants: the thin chords' list at CUDA's size or off (the walking kernel alone),
and the skin off or on (with it, the update timed is one at rest: the same positions as the reference's).

    python bench/experiments/kernel_times.py --device cuda:0 --only lattice --thin-list 1 0 --out kt.json
    python bench/experiments/kernel_times.py --device cuda:0 --only specimen slot --skin 0 1
"""

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).parent))
from wetted_bench import grid_for, scenes

from warp_lamp.wetted import WettedSurface


def activity_times(update, repeats: int) -> dict:
    """Median GPU time [ms] per kernel name (memsets as one) over ``repeats`` eager calls of ``update``, from
    Warp's CUDA activity timing; a kernel launched several times in one update counts its sum."""
    per = defaultdict(list)
    for _ in range(repeats):
        wp.timing_begin(cuda_filter=wp.TIMING_KERNEL | wp.TIMING_MEMSET)
        update()
        results = wp.timing_end()
        seen = defaultdict(float)
        for r in results:
            seen[r.name.split("_cuda_kernel")[0]] += r.elapsed
        for k, v in seen.items():
            per[k].append(v)
    return {k: float(np.median(v)) for k, v in per.items()}


def print_top(kernels_ms: dict, most: int = 12) -> None:
    """The ``most`` costliest kernels of an ``activity_times`` result, one line each."""
    for k, v in sorted(kernels_ms.items(), key=lambda kv: -kv[1])[:most]:
        print(f"   {k[:44]:44s} {v:9.4f} ms")


def kernel_times(name, scene, cell, device, repeats, thin_list, skin=0):
    rho = float(scene.radii.mean())
    grid = grid_for(scene, cell, rho)
    pos = wp.array((scene.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    surf = WettedSurface(grid, probe_radius=rho, device=device, skin="auto" if skin else False)
    if thin_list == 0:
        surf._thin_list(0)
    surf.update(pos, rad)
    surf.update(pos, rad)
    rows = activity_times(lambda: surf.update(pos, rad), repeats)
    d = surf.diagnostics()
    return {
        "scene": scene.name,
        "thin_list": thin_list,
        "skin": skin,
        "skin_kept": d.skin_kept,
        "skin_held": d.skin_held,
        "thin": d.thin,
        "thin_listed": getattr(d, "thin_listed", None),
        "uncertain": d.uncertain,
        "kernels_ms": rows,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--thin-list", nargs="*", type=int, default=[1])
    ap.add_argument("--skin", nargs="*", type=int, default=[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--quick", action="store_true", help="small stand-in scenes (a CPU check of the script)")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    wp.init()
    device = wp.get_device(args.device)
    out = {"device": str(device), "name": device.name, "rows": []}
    for name, scene, cell in scenes(args.quick):
        if args.only and name not in args.only:
            continue
        for tl in args.thin_list:
            for sk in args.skin:
                row = kernel_times(name, scene, cell, device, args.repeats, tl, sk)
                out["rows"].append(row)
                print(
                    f"== {scene.name} thin list {tl} skin {sk}: thin {row['thin']}, listed {row['thin_listed']}, "
                    f"uncertain {row['uncertain']}, kept {row['skin_kept']}, held {row['skin_held']}"
                )
            print_top(row["kernels_ms"])
            sys.stdout.flush()
    if args.out:
        Path(args.out).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
