"""Seeded scenes shared by the tests, the benchmark, the CLI and the examples (no downloads)."""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["Scene", "scene_lattice_ball", "scene_lattice_box", "scene_lone_sphere", "scene_sphere_specimen"]

#: Bump when the packing algorithm changes, so that cached specimens are rebuilt.
_PACKING_VERSION = 1


@dataclass
class Scene:
    """Particles of a scene.

    Attributes:
        name: Short description.
        centers: Particle centres [m], shape (N, 3), float64.
        radii: Particle radii [m], shape (N,), float64.
        center: Centre of the body [m], shape (3,).
        radius: Radius of the body's envelope sphere [m] (0 for bodies that are not spheres).
    """

    name: str
    centers: np.ndarray
    radii: np.ndarray
    center: np.ndarray
    radius: float = 0.0

    @property
    def n(self) -> int:
        return len(self.radii)


def scene_lattice_box(
    n_per_axis=100, *, spacing: float = 1.0, jitter: float = 0.05, rmin: float = 0.4, rmax: float = 0.5, seed: int = 0
) -> Scene:
    """A box body: a cubic lattice of spheres, each centre jittered by up to +-``jitter`` per coordinate.

    The benchmark's reference scene is the default: spacing 1, jitter 0.05, radii uniform in [0.4, 0.5].

    Args:
        n_per_axis: Spheres along each axis, an int or three ints.
        spacing: Lattice spacing [m].
        jitter: Largest displacement per coordinate [m].
        rmin: Smallest radius [m].
        rmax: Largest radius [m].
        seed: Random seed.
    """
    n3 = np.broadcast_to(np.asarray(n_per_axis, dtype=np.int64), (3,))
    rng = np.random.default_rng(seed)
    grid = np.stack(np.meshgrid(*(np.arange(k) for k in n3), indexing="ij"), axis=-1).reshape(-1, 3)
    centers = grid * spacing + rng.uniform(-jitter, jitter, grid.shape)
    radii = rng.uniform(rmin, rmax, len(centers))
    return Scene(f"lattice box {n3[0]}x{n3[1]}x{n3[2]}", centers, radii, (n3 - 1) * spacing / 2.0)


def scene_lattice_ball(
    diameter: float = 0.1, particle_diameter: float = 0.005, *, ratio: float = 1.66, seed: int = 0
) -> Scene:
    """A spherical body cut from a jittered cubic lattice, radii uniform with Rmax/Rmin = ``ratio``.

    A quick, dependency-free stand-in with the memo's SphereTest dimensions (100 mm body, 5 mm particles).

    Args:
        diameter: Body diameter [m].
        particle_diameter: Mean particle diameter [m], also the lattice spacing.
        ratio: Rmax / Rmin.
        seed: Random seed.
    """
    rng = np.random.default_rng(seed)
    k = int(np.ceil(diameter / particle_diameter)) + 1
    axis = (np.arange(k) - (k - 1) / 2.0) * particle_diameter
    pts = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    pts = pts + rng.uniform(-0.05, 0.05, pts.shape) * particle_diameter
    rmean = particle_diameter / 2.0
    rmin = 2.0 * rmean / (1.0 + ratio)
    radii = rng.uniform(rmin, rmin * ratio, len(pts))
    keep = np.linalg.norm(pts, axis=1) + radii <= diameter / 2.0
    return Scene("lattice ball", pts[keep], radii[keep], np.zeros(3), diameter / 2.0)


def scene_lone_sphere(radius: float = 0.5, cell_size: float = 0.25, *, seed: int = 0) -> Scene:
    """One sphere at a random sub-cell offset from the origin (0 <= offset < cell_size per coordinate)."""
    c = np.random.default_rng(seed).uniform(0.0, cell_size, (1, 3))
    return Scene("lone sphere", c, np.array([radius]), c[0], radius)


def _cache_dir() -> Path:
    base = os.environ.get("WARP_LAMP_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "warp_lamp"
    )
    return Path(base)


def scene_sphere_specimen(
    diameter: float = 0.1,
    particle_diameter: float = 0.005,
    *,
    ratio: float = 1.66,
    porosity: float = 0.39,
    seed: int = 0,
    device=None,
    cache: bool = True,
) -> Scene:
    """The memo's SphereTest specimen: a dense random packing of polydisperse spheres in a spherical body.

    Radii are uniform in [Rmin, ratio Rmin] with mean ``particle_diameter / 2``; enough particles are drawn to
    fill the body at ``porosity`` (against the envelope sphere), placed at random inside it at 80% of their size,
    then grown to full size by overlap relaxation on a ``wp.HashGrid`` (Jacobi steps with momentum, each
    particle moving by half of every overlap, the container pushing back) until no overlap exceeds 1% of the
    smaller radius. Porosity 0.39 relaxes in about 1400 steps (seconds on one CPU core); much below 0.38 the
    packing jams before its overlaps fall under 1%.
    The result is cached under ``$WARP_LAMP_CACHE`` (default ``~/.cache/warp_lamp``), keyed by the parameters.

    Args:
        diameter: Body diameter [m].
        particle_diameter: Mean particle diameter [m].
        ratio: Rmax / Rmin.
        porosity: Target porosity of the envelope sphere.
        seed: Random seed.
        device: Warp device for the relaxation (CPU takes a few seconds).
        cache: Read and write the on-disk cache.
    """
    params = dict(d=diameter, pd=particle_diameter, ratio=ratio, phi=porosity, seed=seed, v=_PACKING_VERSION)
    key = hashlib.sha1(json.dumps(params, sort_keys=True).encode()).hexdigest()[:16]
    path = _cache_dir() / f"specimen-{key}.npz"
    R = diameter / 2.0
    if cache and path.exists():
        data = np.load(path)
        return Scene("sphere specimen", data["centers"], data["radii"], np.zeros(3), R)
    centers, radii = _relax_packing(R, particle_diameter / 2.0, ratio, porosity, seed, device)
    if cache:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(tmp, centers=centers, radii=radii)
        os.replace(tmp, path)
    return Scene("sphere specimen", centers, radii, np.zeros(3), R)


MOMENTUM = 0.8


def _relax_packing(R, rmean, ratio, porosity, seed, device, tol=0.0099, max_iter=20000):
    import warp as wp

    from warp_lamp.kernels import packing as K

    rng = np.random.default_rng(seed)
    rmin = 2.0 * rmean / (1.0 + ratio)
    target = (1.0 - porosity) * 4.0 / 3.0 * np.pi * R**3
    mean_volume = 4.0 / 3.0 * np.pi * np.mean(rng.uniform(rmin, ratio * rmin, 100000) ** 3)
    radii = rng.uniform(rmin, ratio * rmin, int(1.5 * target / mean_volume) + 10)
    radii = radii[: int(np.searchsorted(np.cumsum(4.0 / 3.0 * np.pi * radii**3), target)) + 1]
    n = len(radii)
    # Uniform in the ball of radius R - r: direction times R' u^(1/3).
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    x0 = v * ((R - radii) * rng.uniform(0.0, 1.0, n) ** (1.0 / 3.0))[:, None]
    device = wp.get_device(device)
    x = wp.array(x0.astype(np.float32), dtype=wp.vec3, device=device)
    r = wp.array(radii.astype(np.float32), dtype=wp.float32, device=device)
    dx = wp.zeros(n, dtype=wp.vec3, device=device)
    vel = wp.zeros(n, dtype=wp.vec3, device=device)
    worst = wp.zeros(1, dtype=wp.float32, device=device)
    dim = max(8, int(np.ceil(n ** (1.0 / 3.0))))
    grid = wp.HashGrid(dim, dim, dim, device=device)
    query = float(2.0 * ratio * rmin)
    scale, grow = 0.5, 1.004
    for it in range(max_iter):
        grid.build(x, query)
        worst.zero_()
        wp.launch(K.packing_push, dim=n, inputs=[grid.id, x, r, scale, R, query], outputs=[dx, worst], device=device)
        wp.launch(K.packing_move, dim=n, inputs=[dx, MOMENTUM], outputs=[vel, x], device=device)
        if it % 10 == 9:
            w = float(worst.numpy()[0])
            if scale >= 1.0 and w < tol:
                break
            # Grow while overlaps stay moderate; hold the size and relax when they pile up.
            if w < 0.05:
                scale = min(1.0, scale * grow**10)
    else:
        raise RuntimeError(f"packing: did not relax below {tol:.1%} overlap in {max_iter} steps (worst {w:.3%})")
    return x.numpy().astype(np.float64), radii
