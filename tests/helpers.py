"""Scenes and device helpers shared by the tests (fixtures live in conftest.py)."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING
wp.init()

#: CUDA devices present, by alias.
CUDA_DEVICES = [d.alias for d in wp.get_cuda_devices()]
#: Every device a test runs on: the CPU always, each CUDA device when there is one.
DEVICES = ["cpu", *CUDA_DEVICES]
#: The repository's examples/ folder: no package, so the tests load its scripts by path.
EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def load_example(name: str):
    """examples/<name>.py as a module, loaded once and kept in ``sys.modules`` under its name (as the examples
    load their sibling ``dem``)."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def polydisperse_scene(rng, n=150, extent=5.0, rmin=0.2, rmax=0.6):
    """n spheres with centres uniform in [0, extent]^3 and radii uniform in [rmin, rmax] (overlaps allowed)."""
    centers = rng.uniform(0.0, extent, (n, 3))
    radii = rng.uniform(rmin, rmax, n)
    return centers, radii


def device_arrays(centers, radii, device):
    """float32 ``vec3`` positions and ``float32`` radii on ``device``, as a simulator holds them."""
    pos = wp.array(np.asarray(centers, dtype=np.float32), dtype=wp.vec3, device=device)
    return pos, wp.array(np.asarray(radii, dtype=np.float32), dtype=wp.float32, device=device)


def bvh_owners(grid, centers, radii, device):
    """The BVH ray caster's owners per lamp (one ray per cell, no footprint: an independent algorithm) for world
    centres [m], shape (N, 3), and radii [m]; returns (owners by lamp name, the caster)."""
    from warp_lamp.peers import BvhLamp

    peer = BvhLamp(grid, len(radii), device=device)
    local = grid.to_frame(centers).astype(np.float32)
    peer.build(
        wp.array(local, dtype=wp.vec3, device=device), wp.array(np.asarray(radii, dtype=np.float32), device=device)
    )
    peer.cast()
    return peer.owners(), peer
