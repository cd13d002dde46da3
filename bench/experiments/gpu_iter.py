"""Quick GPU iteration: the target rows only (lattice, cell 0.25, criterion 1), for kernel work between full runs.

python bench/experiments/gpu_iter.py 100 200          # the default lamp
python bench/experiments/gpu_iter.py --v4 100         # one thread per sphere (the v4 pass)
"""

import json
import os
import sys

import numpy as np
import warp as wp

from warp_lamp.bench import lattice_grid, time_bvh, time_lamp
from warp_lamp.scenes import scene_lattice_box

wp.config.log_level = wp.LOG_WARNING

dev = wp.get_device("cuda:0")
options = {"split": 0, "order": False} if "--v4" in sys.argv else {}
sizes = [int(x) for x in sys.argv[1:] if x != "--v4"] or [100, 200]
rows = []
for m in sizes:
    scene = scene_lattice_box(m)
    grid = lattice_grid(scene, 0.25)
    t = time_lamp(scene, grid, 1, dev, repeats=50, **options)
    if m <= 100:
        t.update(time_bvh(scene, grid, dev, repeats=20))
    t["n"] = scene.n
    rows.append(t)
    fields = ["cold_s", "eager_s", "replay_s", "moving_s", "seed_s", "depth_s", "add_forces_s", "bvh_cast_s"]
    line = "  ".join(f"{k[:-2]} {t.get(k, np.nan) * 1e3:.4f}" for k in fields)
    print(f"n={scene.n:>10,}  {line} ms", flush=True)
out = os.environ.get("OUT")
if out:
    with open(os.path.join(out, "iter.json"), "w") as f:
        json.dump(rows, f, indent=1)
