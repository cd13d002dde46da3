"""Seeded scenes shared by the tests, the benchmark, the CLI and the examples (no downloads)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Scene", "scene_lattice_ball", "scene_lattice_box", "scene_lone_sphere"]


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
