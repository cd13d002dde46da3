"""What fuse_fp=False costs the lamp on CUDA, and whether CUDA still matches the CPU bitwise with it on."""

import numpy as np
import warp as wp

from warp_lamp.bench import lattice_grid, time_lamp
from warp_lamp.kernels import footprint, lamp
from warp_lamp.lamp import lamp_update
from warp_lamp.scenes import scene_lattice_box

wp.config.log_level = wp.LOG_WARNING

dev = wp.get_device("cuda:0")
scene = scene_lattice_box(100)
grid = lattice_grid(scene, 0.25)
rng = np.random.default_rng(1)
c = rng.uniform(0, 12, (3000, 3))
r = rng.uniform(0.1, 0.9, 3000)
cpu = lamp_update(c, r, cells_per_diameter=8, device="cpu").diagnostics()
for fuse in (False, True):
    for mod in (footprint, lamp):
        wp.set_module_options({"fuse_fp": fuse}, module=mod)
    t = time_lamp(scene, grid, 1, dev, repeats=50)
    gpu = lamp_update(c, r, cells_per_diameter=8, device=dev).diagnostics()
    same = all(np.array_equal(cpu.depths[k], gpu.depths[k], equal_nan=True) for k in cpu.depths)
    print(
        f"fuse_fp={fuse}: replay {t['replay_s'] * 1e3:.4f} ms, depth {t['depth_s'] * 1e3:.4f} ms, "
        f"cold {t['cold_s'] * 1e3:.4f} ms; CPU==CUDA depths bitwise: {same}"
    )
