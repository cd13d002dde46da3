"""Scenes and device helpers shared by the tests (fixtures live in conftest.py)."""

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING
wp.init()

#: CUDA devices present, by alias.
CUDA_DEVICES = [d.alias for d in wp.get_cuda_devices()]
#: Every device a test runs on: the CPU always, each CUDA device when there is one.
DEVICES = ["cpu", *CUDA_DEVICES]


def polydisperse_scene(rng, n=150, extent=5.0, rmin=0.2, rmax=0.6):
    """n spheres with centres uniform in [0, extent]^3 and radii uniform in [rmin, rmax] (overlaps allowed)."""
    centers = rng.uniform(0.0, extent, (n, 3))
    radii = rng.uniform(rmin, rmax, n)
    return centers, radii


def device_arrays(centers, radii, device):
    """float32 ``vec3`` positions and ``float32`` radii on ``device``, as a simulator holds them."""
    pos = wp.array(np.asarray(centers, dtype=np.float32), dtype=wp.vec3, device=device)
    return pos, wp.array(np.asarray(radii, dtype=np.float32), dtype=wp.float32, device=device)
