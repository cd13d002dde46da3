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


def worst_overlap(centers, radii) -> float:
    """The largest overlap of any two particles over the smaller radius (negative: none touch), all pairs, float64."""
    c, r = np.asarray(centers, dtype=np.float64), np.asarray(radii, dtype=np.float64)
    d = np.linalg.norm(c[:, None] - c[None], axis=2)
    overlap = (r[:, None] + r[None] - d) / np.minimum(r[:, None], r[None])
    np.fill_diagonal(overlap, -np.inf)
    return float(overlap.max())


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


def first_surface_raster(centers, radii, rect, n, *, by_centre=False):
    """Visible areas by brute force: an n x n raster of rays over ``rect`` along the third coordinate (from
    -infinity), each ray's pixel to the sphere with the smallest entry depth z - sqrt(r^2 - d^2), ties to the
    lower index (a z-buffer filled sphere by sphere over its bounding box); also the pixel side. Independent of
    the references: no ordering, no clipping. ``by_centre``: the centre depth z instead (the rule before issue 19)."""
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(radii, dtype=np.float64)
    x0, y0, x1, y1 = rect
    hx, hy = (x1 - x0) / n, (y1 - y0) / n
    best = np.full((n, n), np.inf)
    who = np.full((n, n), len(r))
    for k in range(len(r)):
        i0, i1 = (int(np.clip(np.floor((c[k, 0] + s * r[k] - x0) / hx), 0, n)) for s in (-1, 1))
        j0, j1 = (int(np.clip(np.floor((c[k, 1] + s * r[k] - y0) / hy), 0, n)) for s in (-1, 1))
        xs = x0 + (np.arange(i0, min(i1 + 1, n)) + 0.5) * hx
        ys = y0 + (np.arange(j0, min(j1 + 1, n)) + 0.5) * hy
        s2 = r[k] ** 2 - (xs[:, None] - c[k, 0]) ** 2 - (ys[None, :] - c[k, 1]) ** 2
        depth = np.where(s2 >= 0, c[k, 2] - (0.0 if by_centre else np.sqrt(np.maximum(s2, 0.0))), np.inf)
        window = (slice(i0, i0 + len(xs)), slice(j0, j0 + len(ys)))
        better = depth < best[window]
        best[window] = np.where(better, depth, best[window])
        who[window] = np.where(better, k, who[window])
    return np.bincount(who.ravel(), minlength=len(r) + 1)[: len(r)] * hx * hy, max(hx, hy)


def raster_tolerance(radii, pixel):
    """A raster's error bound on one sphere's area: half a pixel along its whole outline (generous: the errors of
    the pixels along a boundary are of either sign)."""
    return 0.5 * pixel * 2 * np.pi * np.asarray(radii)


def raster_visible_areas(centers, radii, rays, *, by_centre=False):
    """Visible area of every sphere from each of the six lamps by :func:`first_surface_raster`, ``rays`` rays per
    mean diameter over the body's bounding square per axis: shape (N, 6) in ``LAMPS`` order, and the pixel side."""
    c = np.asarray(centers, dtype=np.float64)
    r = np.asarray(radii, dtype=np.float64)
    lo, hi = (c - r[:, None]).min(axis=0), (c + r[:, None]).max(axis=0)
    side = float((hi - lo).max())
    n = int(np.ceil(side / (2 * r.mean()) * rays))
    out = np.zeros((len(r), 6))
    for lamp in range(6):
        a, high = divmod(lamp, 2)
        u, v = (a + 1) % 3, (a + 2) % 3
        view = np.column_stack([c[:, u], c[:, v], -c[:, a] if high else c[:, a]])
        rect = (lo[u], lo[v], lo[u] + side, lo[v] + side)
        out[:, lamp], pixel = first_surface_raster(view, r, rect, n, by_centre=by_centre)
    return out, pixel


def device_arrays(centers, radii, device):
    """float32 ``vec3`` positions and ``float32`` radii on ``device``, as a simulator holds them."""
    pos = wp.array(np.asarray(centers, dtype=np.float32), dtype=wp.vec3, device=device)
    return pos, wp.array(np.asarray(radii, dtype=np.float32), dtype=wp.float32, device=device)


def bvh_owners(grid, centers, radii, device):
    """The BVH ray caster's owners per lamp (one ray per cell, no footprint: an independent algorithm) for world
    centres [m], shape (N, 3), and radii [m]; returns (owners by lamp name, the caster)."""
    from warp_lamp.bench.peers import BvhLamp

    peer = BvhLamp(grid, len(radii), device=device)
    local = grid.to_frame(centers).astype(np.float32)
    peer.build(
        wp.array(local, dtype=wp.vec3, device=device), wp.array(np.asarray(radii, dtype=np.float32), device=device)
    )
    peer.cast()
    return peer.owners(), peer
