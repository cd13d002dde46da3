"""Seeded scenes shared by the tests, the benchmark, the CLI and the examples (no downloads)."""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = [
    "CutScene",
    "Scene",
    "box_porosity",
    "relax_packing",
    "scene_box_specimen",
    "scene_cavity_block",
    "scene_cylinder_specimen",
    "scene_lattice_ball",
    "scene_lattice_box",
    "scene_lone_sphere",
    "scene_overlapping_box",
    "scene_overlapping_polydisperse",
    "scene_slot_block",
    "scene_sphere_specimen",
    "scene_tunnel_block",
    "specimen_cached",
    "specimen_porosity_floor",
]

#: Bump when the packing algorithm changes, so that cached specimens are rebuilt.
_PACKING_VERSION = 2


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


def _device_kind(device) -> str:
    """ "cpu" or "cuda": packings relaxed on the two differ in their last digits, so the cache keeps them apart."""
    import warp as wp

    return "cuda" if wp.get_device(device).is_cuda else "cpu"


def _cache_path(kind: str, params: dict) -> Path:
    key = hashlib.sha1(json.dumps({**params, "v": _PACKING_VERSION}, sort_keys=True).encode()).hexdigest()[:16]
    return _cache_dir() / f"{kind}-{key}.npz"


def _cached_packing(kind: str, params: dict, build, *, cache: bool) -> tuple[np.ndarray, np.ndarray]:
    """(centres, radii) of a packing: read from the disk cache, keyed by ``kind`` and ``params``, or made by
    ``build()`` and written there atomically (so that concurrent processes never read half a file)."""
    path = _cache_path(kind, params)
    if cache and path.exists():
        data = np.load(path)
        return data["centers"], data["radii"]
    centers, radii = build()
    if cache:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(tmp, centers=centers, radii=radii)
        os.replace(tmp, path)
    return centers, radii


#: The memo's specimen porosity, reached from 20 particle diameters across.
SPECIMEN_POROSITY = 0.39
#: Bodies narrower than this many particle diameters hold a few dozen particles, whose packing is luck.
SPECIMEN_MIN_DIAMETERS = 5.0


def specimen_porosity_floor(diameters: float) -> float:
    """The densest envelope porosity the specimen generator reaches in a ball ``diameters`` mean particle
    diameters across: particles against the curved wall pack loosely, so the envelope holds less solid the
    smaller the ball. A fit to the bulk porosity 0.36 times the wall layer's loss, 1 - 0.64 (1 - 0.33 d/D)^3,
    measured (two seeds each, 4000 steps) at 3, 4, 6, 8, 10, 12, 14, 17 and 20 diameters across to within 0.01:
    0.55 at 3, 0.42 at 10, 0.40 at 14, 0.39 at 20. With 0.01 added (the default of :func:`scene_sphere_specimen`
    below 20 across), three seeds relaxed at every whole number of diameters from 5 to 19."""
    return 1.0 - 0.64 * (1.0 - 0.33 / float(diameters)) ** 3


def _specimen_porosity(porosity, diameter: float, particle_diameter: float) -> float:
    """The porosity to pack at: the memo's 0.39 where it is reachable (from 20 diameters across), else the densest
    reachable plus 0.01; a porosity asked for that cannot be reached is refused at once, with the reason."""
    x = diameter / particle_diameter
    if not x >= SPECIMEN_MIN_DIAMETERS:
        raise ValueError(
            f"diameter: a body of {diameter:g} m is {x:.3g} particle diameters ({particle_diameter:g} m) across, under "
            f"the {SPECIMEN_MIN_DIAMETERS:g} a packing needs; make it larger or the particles smaller"
        )
    floor = specimen_porosity_floor(x)
    if porosity is None:
        return SPECIMEN_POROSITY if x >= 20.0 else round(floor + 0.01, 3)
    if isinstance(porosity, bool) or not isinstance(porosity, (int, float, np.floating)) or not 0.0 < porosity < 1.0:
        raise ValueError(f"porosity: expected a number in (0, 1), got {porosity!r}")
    if porosity < floor - 0.005:
        raise ValueError(
            f"porosity: {float(porosity):g} cannot be reached in a body {x:.3g} particle diameters across: the "
            f"particles against its curved wall pack loosely, and the densest this generator reaches there is about "
            f"{floor:.3f} ({SPECIMEN_POROSITY} from 20 diameters across); leave porosity=None for the densest "
            "reachable, ask for more, or make the body larger against its particles"
        )
    return float(porosity)


def scene_sphere_specimen(
    diameter: float = 0.1,
    particle_diameter: float = 0.005,
    *,
    ratio: float = 1.66,
    porosity: float | None = None,
    seed: int = 0,
    device=None,
    cache: bool = True,
) -> Scene:
    """The memo's SphereTest specimen: a dense random packing of polydisperse spheres in a spherical body.

    Radii are uniform in [Rmin, ratio Rmin] with mean ``particle_diameter / 2``; enough particles are drawn to
    fill the body at ``porosity`` (against the envelope sphere), placed at random inside it at 80% of their size,
    then grown to full size by overlap relaxation on a ``wp.HashGrid`` (Jacobi steps with momentum, each
    particle moving by half of every overlap, the container pushing back) until no overlap exceeds 1% of the
    smaller radius. Porosity 0.39 relaxes in about 1400 steps (seconds on one CPU core) in the memo's body, 20
    particle diameters across. Smaller bodies cannot be packed as densely (the particles against the curved wall
    pack loosely: :func:`specimen_porosity_floor`), so by default they get the densest porosity the generator
    reaches at their size, and a porosity below it is refused at once rather than after a long relaxation.
    The result is cached under ``$WARP_LAMP_CACHE`` (default ``~/.cache/warp_lamp``), keyed by the parameters.

    Args:
        diameter: Body diameter [m], at least 5 particle diameters.
        particle_diameter: Mean particle diameter [m].
        ratio: Rmax / Rmin.
        porosity: Target porosity of the envelope sphere; None: 0.39 (the memo's) from 20 particle diameters
            across, else the densest reachable plus 0.01 (0.41 at 14 across, 0.46 at 6).
        seed: Random seed.
        device: Warp device for the relaxation: the CPU by default (a few seconds), so that the specimen is the same
            on every machine; a GPU relaxes it faster but rounds differently (contracted multiply-adds, the order
            of atomic sums), so its packing differs in the last digits of what is measured on it.
        cache: Read and write the on-disk cache (keyed by the parameters and the device kind).

    Raises:
        ValueError: a body under 5 particle diameters across, or a porosity it cannot reach, at once.
    """
    diameter = float(diameter)
    particle_diameter = float(particle_diameter)
    porosity = _specimen_porosity(porosity, diameter, particle_diameter)
    device = "cpu" if device is None else device
    R = diameter / 2.0
    params = dict(d=diameter, pd=particle_diameter, ratio=ratio, phi=porosity, seed=seed, on=_device_kind(device))
    centers, radii = _cached_packing(
        "specimen",
        params,
        lambda: _relax_packing(R, particle_diameter / 2.0, ratio, porosity, seed, device),
        cache=cache,
    )
    return Scene("sphere specimen", centers, radii, np.zeros(3), R)


def specimen_cached(**kwargs) -> bool:
    """Whether :func:`scene_sphere_specimen` with these arguments would load from the disk cache (no packing)."""
    diameter = float(kwargs.get("diameter", 0.1))
    particle_diameter = float(kwargs.get("particle_diameter", 0.005))
    porosity = _specimen_porosity(kwargs.get("porosity"), diameter, particle_diameter)
    on = _device_kind("cpu" if kwargs.get("device") is None else kwargs["device"])
    params = dict(
        d=diameter,
        pd=particle_diameter,
        ratio=kwargs.get("ratio", 1.66),
        phi=porosity,
        seed=kwargs.get("seed", 0),
        on=on,
    )
    return _cache_path("specimen", params).exists()


MOMENTUM = 0.8


def relax_packing(
    x0: np.ndarray,
    radii: np.ndarray,
    *,
    body_radius: float = 0.0,
    box=None,
    tol: float = 0.0099,
    scale: float = 0.5,
    grow: float = 1.004,
    max_iter: int = 20000,
    device=None,
) -> np.ndarray:
    """Overlap relaxation on a ``wp.HashGrid``: grow the particles from ``scale`` to full size while pushing
    overlapping pairs apart (Jacobi steps with momentum) and the container back, until no overlap exceeds
    ``tol`` of the smaller radius. Returns the centres, float64.

    Args:
        x0: Initial centres [m], shape (N, 3).
        radii: Radii [m], shape (N,).
        body_radius: Container ball about the origin [m], or 0 to use ``box``.
        box: Container box ``(lower, upper)`` [m] when ``body_radius`` is 0.
        tol: Largest overlap left, as a fraction of the smaller radius of the pair.
        scale: Starting size, as a fraction of the radii.
        grow: Size factor per 10 steps while overlaps are moderate.
        max_iter: Steps before giving up with RuntimeError.
        device: Warp device.
    """
    import warp as wp

    from warp_lamp.kernels import packing as packing_kernels

    device = wp.get_device(device)
    n = len(radii)
    lo, hi = (np.zeros(3), np.zeros(3)) if box is None else (np.asarray(box[0]), np.asarray(box[1]))
    x = wp.array(np.asarray(x0, dtype=np.float32), dtype=wp.vec3, device=device)
    r = wp.array(np.asarray(radii, dtype=np.float32), dtype=wp.float32, device=device)
    dx = wp.zeros(n, dtype=wp.vec3, device=device)
    vel = wp.zeros(n, dtype=wp.vec3, device=device)
    worst = wp.zeros(1, dtype=wp.float32, device=device)
    dim = max(8, min(128, int(np.ceil(n ** (1.0 / 3.0)))))
    grid = wp.HashGrid(dim, dim, dim, device=device)
    query = float(2.0 * np.max(radii))
    w = np.inf
    for it in range(max_iter):
        grid.build(x, query)
        worst.zero_()
        wp.launch(
            packing_kernels.packing_push,
            dim=n,
            inputs=[grid.id, x, r, scale, body_radius, wp.vec3(*lo), wp.vec3(*hi), query],
            outputs=[dx, worst],
            device=device,
        )
        wp.launch(packing_kernels.packing_move, dim=n, inputs=[dx, MOMENTUM], outputs=[vel, x], device=device)
        if it % 10 == 9:
            w = float(worst.numpy()[0])
            if scale >= 1.0 and w < tol:
                break
            # Grow while overlaps stay moderate; hold the size and relax when they pile up.
            if w < max(0.05, 2.0 * tol):
                scale = min(1.0, scale * grow**10)
    else:
        raise RuntimeError(f"packing: did not relax below {tol:.1%} overlap in {max_iter} steps (worst {w:.3%})")
    return x.numpy().astype(np.float64)


def _relax_packing(R, rmean, ratio, porosity, seed, device):
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
    return relax_packing(x0, radii, body_radius=R, device=device), radii


def scene_overlapping_box(
    radius: float,
    size=(0.1, 0.1, 0.2),
    *,
    solid_fraction: float = 0.6,
    max_overlap: float = 0.1,
    seed: int = 0,
    device=None,
    cache: bool = True,
) -> Scene:
    """The paper's section 3.2 set-up: a box filled densely with equal spheres that overlap.

    Enough spheres of ``radius`` to make the summed sphere volume ``solid_fraction`` of the box, placed at random
    at 80% size and relaxed in Warp (as :func:`relax_packing`) until no overlap exceeds ``max_overlap`` of a
    radius: dense, and overlapping as soft DEM contacts do. Cached on disk like the specimen.

    Args:
        radius: Sphere radius [m] (the paper: 1, 2.5 and 5 mm).
        size: Box edges [m]; the box spans [0, size].
        solid_fraction: Summed sphere volume over box volume.
        max_overlap: Largest overlap kept, as a fraction of the radius.
        seed: Random seed.
        device: Warp device for the relaxation (a CPU and a GPU packing differ in their last digits; the cache
            keeps them apart).
        cache: Read and write the on-disk cache.
    """
    size = np.asarray(size, dtype=np.float64)

    def build():
        rng = np.random.default_rng(seed)
        n = round(float(solid_fraction * np.prod(size) / (4.0 / 3.0 * np.pi * radius**3)))
        radii = np.full(n, radius)
        x0 = rng.uniform(radius, size - radius, (n, 3))
        centers = relax_packing(x0, radii, box=(np.zeros(3), size), tol=max_overlap, scale=0.8, device=device)
        return centers, radii

    params = dict(kind="box", r=radius, size=size.tolist(), phi=solid_fraction, ov=max_overlap, seed=seed)
    params["on"] = _device_kind(device)
    centers, radii = _cached_packing("box", params, build, cache=cache)
    return Scene(f"overlapping box, r = {radius * 1e3:g} mm", centers, radii, size / 2.0)


def scene_overlapping_polydisperse(
    n: int = 1000,
    *,
    mean_radius: float = 0.5,
    ratio: float = 3.0,
    max_overlap: float = 0.3,
    solid_fraction: float = 0.6,
    seed: int = 0,
) -> Scene:
    """A ball of strongly overlapping polydisperse spheres, as in bonded or cemented DEM packings.

    ``n`` radii uniform in [Rmin, ``ratio`` Rmin] with mean ``mean_radius``, placed one by one, largest first
    (random sequential addition), at uniform random points of a ball sized so that the summed sphere volume is
    ``solid_fraction`` of it; a point is taken when every overlap with the spheres already placed is at most
    ``max_overlap`` of the smaller radius of the pair (the pair's depth of interpenetration, ``r_i + r_j - d``),
    else another is drawn. Overlaps then spread from 0 to ``max_overlap``, a few spheres overlap nothing, and
    none is nested in another.

    Args:
        n: Number of spheres.
        mean_radius: Mean radius [m].
        ratio: Rmax / Rmin.
        max_overlap: Largest overlap, as a fraction of the smaller radius of the pair.
        solid_fraction: Summed sphere volume over the ball's volume (0.6 places 1,000 spheres in about 3 s; 0.7
            takes minutes; below about 80 spheres the wall leaves too little room at 0.6).
        seed: Random seed.
    """
    rng = np.random.default_rng(seed)
    rmin = 2.0 * mean_radius / (1.0 + ratio)
    # Largest first (the small ones fill the gaps); the indices are shuffled at the end.
    radii = np.sort(rng.uniform(rmin, ratio * rmin, n))[::-1]
    R = float(np.cbrt(np.sum(radii**3) / solid_fraction))
    reach = 2.0 * ratio * rmin
    cells: dict[tuple, list[int]] = {}
    centers = np.zeros((n, 3))
    for i, r in enumerate(radii):
        for _ in range(100000):
            p = rng.normal(size=3)
            p *= (R - r) * rng.uniform() ** (1.0 / 3.0) / np.linalg.norm(p)
            key = tuple(np.floor(p / reach).astype(int))
            near = [
                k
                for dx in (-1, 0, 1)
                for dy in (-1, 0, 1)
                for dz in (-1, 0, 1)
                for k in cells.get((key[0] + dx, key[1] + dy, key[2] + dz), ())
            ]
            if near:
                d = np.linalg.norm(centers[near] - p, axis=1)
                if np.any(radii[near] + r - d > max_overlap * np.minimum(radii[near], r)):
                    continue
            break
        else:
            raise RuntimeError(f"solid_fraction: sphere {i} found no place; lower solid_fraction or raise max_overlap")
        centers[i] = p
        cells.setdefault(key, []).append(i)
    order = rng.permutation(n)
    return Scene("overlapping polydisperse ball", centers[order], radii[order], np.zeros(3), R)


def scene_cylinder_specimen(
    diameter: float = 0.05,
    height: float | None = None,
    *,
    particles: int = 10000,
    ratio: float = 1.66,
    porosity: float = 0.40,
    seed: int = 0,
    device=None,
    cache: bool = True,
) -> Scene:
    """A triaxial specimen: a dense random packing of polydisperse spheres in a cylinder about the z axis.

    ``particles`` radii are drawn uniform in [Rmin, ratio Rmin] and scaled together so that they fill the
    cylinder at ``porosity``; they are placed at random inside it and grown to full size by the overlap relaxation
    of :func:`relax_packing` (the cylinder as its container: ``body_radius = -diameter/2``, the end faces from
    ``box``) until no overlap exceeds 1% of the smaller radius. The cylinder spans z in [-height/2, height/2].
    With the defaults (50 mm x 100 mm, 10,000 particles) the mean particle diameter is 2.8 mm, 18 across the
    diameter. Cached on disk like :func:`scene_sphere_specimen`.

    Args:
        diameter: Cylinder diameter [m].
        height: Cylinder height [m]; twice the diameter by default.
        particles: Number of particles.
        ratio: Rmax / Rmin.
        porosity: Porosity of the cylinder (1 - particle volume / cylinder volume).
        seed: Random seed.
        device: Warp device for the relaxation: the CPU by default (about 7 s for 10,000 particles on one core), so
            that the specimen is the same on every machine; a GPU packing differs in its last digits (the cache
            keeps them apart).
        cache: Read and write the on-disk cache.
    """
    device = "cpu" if device is None else device
    height = 2.0 * diameter if height is None else float(height)
    if int(particles) < 1:
        raise ValueError(f"particles: need at least 1, got {particles!r}")

    def build():
        rng = np.random.default_rng(seed)
        R = diameter / 2.0
        radii = rng.uniform(1.0, ratio, int(particles))
        radii *= ((1.0 - porosity) * np.pi * R * R * height / (4.0 / 3.0 * np.pi * np.sum(radii**3))) ** (1.0 / 3.0)
        # Uniform in the cylinder shrunk by each radius: sqrt for the radial coordinate.
        rho = (R - radii) * np.sqrt(rng.uniform(0.0, 1.0, len(radii)))
        phi = rng.uniform(0.0, 2.0 * np.pi, len(radii))
        z = rng.uniform(-0.5 * height + radii, 0.5 * height - radii)
        x0 = np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1)
        box = (np.array([-R, -R, -0.5 * height]), np.array([R, R, 0.5 * height]))
        return relax_packing(x0, radii, body_radius=-R, box=box, device=device), radii

    params = dict(kind="cylinder", d=diameter, h=height, n=int(particles), ratio=ratio, phi=porosity, seed=seed)
    params["on"] = _device_kind(device)
    centers, radii = _cached_packing("cylinder", params, build, cache=cache)
    name = f"cylinder specimen {diameter * 1e3:g} x {height * 1e3:g} mm, {int(particles)} particles"
    return Scene(name, centers, radii, np.zeros(3))


def box_porosity(particles: int) -> float:
    """Porosity a box of ``particles`` polydisperse spheres (Rmax/Rmin = 1.66) is packed at by default: near the
    densest that the overlap relaxation reaches below 1% overlap, which rises as the walls take a larger share
    (the cylinder specimen's rule plus 0.01 for the corners: 0.415 at 5,000 particles, 0.445 at 450)."""
    return 0.39 + 0.35 * (1.8 / max(int(particles), 1)) ** (1.0 / 3.0)


def scene_box_specimen(
    size,
    particle_diameter: float,
    *,
    ratio: float = 1.66,
    porosity: float | None = None,
    seed: int = 0,
    device=None,
    cache: bool = True,
) -> Scene:
    """A rock slab or a test prism: a dense random packing of polydisperse spheres in the box [0, size].

    Radii are drawn uniform in [Rmin, ratio Rmin] and scaled together so that the spheres fill the box at
    ``porosity`` with a mean diameter close to ``particle_diameter``; they are placed at random inside it and grown
    to full size by the overlap relaxation of :func:`relax_packing` (the box as container) until no overlap exceeds
    1% of the smaller radius. Cached on disk like :func:`scene_sphere_specimen`.

    Args:
        size: Box edges [m], three numbers; the box spans [0, size].
        particle_diameter: Mean particle diameter [m] aimed at.
        ratio: Rmax / Rmin.
        porosity: Porosity of the box; :func:`box_porosity` of the particle count by default.
        seed: Random seed.
        device: Warp device for the relaxation: the CPU by default, so that the specimen is the same on every
            machine (a GPU packing differs in its last digits; the cache keeps them apart).
        cache: Read and write the on-disk cache.
    """
    size = np.asarray(size, dtype=np.float64).reshape(-1)
    if size.shape != (3,) or not np.all(np.isfinite(size) & (size > 0)):
        raise ValueError(f"size: expected three positive box edges [m], got {size.tolist()}")
    if not (np.isfinite(particle_diameter) and particle_diameter > 0 and particle_diameter < size.min()):
        raise ValueError(f"particle_diameter: expected a number in (0, {size.min()}) [m], got {particle_diameter!r}")
    device = "cpu" if device is None else device
    # Mean of d^3 for diameters uniform in [dmin, ratio dmin] with mean particle_diameter.
    dmin = 2.0 * particle_diameter / (1.0 + ratio)
    mean_d3 = dmin**3 * (ratio**4 - 1.0) / (4.0 * (ratio - 1.0)) if ratio != 1.0 else dmin**3
    volume = float(np.prod(size))
    if porosity is None:
        porosity = box_porosity(round(0.58 * volume / (np.pi / 6.0 * mean_d3)))
    if not 0.0 < porosity < 1.0:
        raise ValueError(f"porosity: expected a number in (0, 1), got {porosity!r}")
    count = max(1, round((1.0 - porosity) * volume / (np.pi / 6.0 * mean_d3)))

    def build():
        rng = np.random.default_rng(seed)
        radii = rng.uniform(1.0, ratio, count)
        radii *= ((1.0 - porosity) * volume / (4.0 / 3.0 * np.pi * np.sum(radii**3))) ** (1.0 / 3.0)
        x0 = rng.uniform(radii[:, None], size - radii[:, None])
        return relax_packing(x0, radii, box=(np.zeros(3), size), device=device), radii

    params = dict(kind="box-specimen", size=size.tolist(), pd=particle_diameter, ratio=ratio, phi=porosity, seed=seed)
    params["on"] = _device_kind(device)
    centers, radii = _cached_packing("boxspec", params, build, cache=cache)
    name = f"box specimen {' x '.join(f'{s * 1e3:g}' for s in size)} mm, {len(radii)} particles"
    return Scene(name, centers, radii, size / 2.0)


# --- cut blocks for the wetted-surface mode (warp_lamp.wetted) --------------------------------------------


@dataclass
class CutScene(Scene):
    """A jittered lattice block (:func:`scene_lattice_box`) with lattice sites removed.

    Attributes:
        index: Lattice index (ix, iy, iz) of each particle, shape (N, 3), int64.
        kept: Index of each particle in the uncut block ``full()``, shape (N,), int64.
        cut: What was cut, in lattice units times the spacing [m] (see each scene function).
        block: Arguments of :func:`scene_lattice_box` that rebuild the uncut block.
    """

    index: np.ndarray = None
    kept: np.ndarray = None
    cut: dict = None
    block: dict = None

    def full(self) -> Scene:
        """The same block without the cut: the same seed, so every kept particle is bitwise the same."""
        return scene_lattice_box(**self.block)


def _lattice_spacing(lattice: dict) -> float:
    """The spacing a cut-block scene's ``**lattice`` keywords give :func:`scene_lattice_box` [m]."""
    unknown = set(lattice) - {"spacing", "jitter", "rmin", "rmax", "seed"}
    if unknown:
        raise TypeError(f"{sorted(unknown)[0]}: not a keyword of scene_lattice_box")
    return float(lattice.get("spacing", 1.0))


def _cut_block(name, n_per_axis, remove, cut, lattice: dict) -> CutScene:
    block = dict(n_per_axis=n_per_axis, **lattice)
    full = scene_lattice_box(**block)
    n3 = np.broadcast_to(np.asarray(n_per_axis, dtype=np.int64), (3,))
    index = np.stack(np.meshgrid(*(np.arange(k) for k in n3), indexing="ij"), axis=-1).reshape(-1, 3)
    keep = ~remove(index)
    kept = np.flatnonzero(keep)
    return CutScene(
        name,
        full.centers[kept],
        full.radii[kept],
        full.center,
        index=index[kept],
        kept=kept,
        cut=cut,
        block=block,
    )


def scene_slot_block(
    n_per_axis=(30, 30, 20),
    *,
    width: int = 6,
    depth: int = 8,
    **lattice,
) -> CutScene:
    """The slot block of the wetted-surface checks: a jittered cubic block with a slot cut along x into its top face.

    The slot removes the ``width`` middle columns in y (iy in [j0, j0 + width)) of the top ``depth`` layers in z,
    over the whole length in x. ``cut`` holds ``length`` L, ``width`` w, ``depth`` D (in lattice spacings times
    the spacing [m]), the removed columns ``j0``, ``j1`` (exclusive), the first removed layer ``k0``, the wall
    columns ``wall_lo`` = j0 - 1 and ``wall_hi`` = j1, and the ``floor`` layer k0 - 1: the particles the fluid in
    the slot pushes on (laterally P L D on each wall, downward P L w on the floor).

    Args:
        n_per_axis: Spheres along x, y, z.
        width: Slot width [lattice spacings].
        depth: Slot depth [lattice spacings].
        **lattice: ``spacing``, ``jitter``, ``rmin``, ``rmax``, ``seed``, as for :func:`scene_lattice_box`.
    """
    spacing = _lattice_spacing(lattice)
    nx, ny, nz = (int(x) for x in np.broadcast_to(np.asarray(n_per_axis), (3,)))
    if not (0 < width < ny - 1 and 0 < depth < nz):
        raise ValueError(f"width, depth: need 0 < width < {ny - 1} and 0 < depth < {nz}, got {width}, {depth}")
    j0 = (ny - width) // 2
    j1 = j0 + width
    k0 = nz - depth
    cut = dict(
        kind="slot",
        length=nx * spacing,
        width=width * spacing,
        depth=depth * spacing,
        j0=j0,
        j1=j1,
        k0=k0,
        wall_lo=j0 - 1,
        wall_hi=j1,
        floor=k0 - 1,
    )

    def remove(idx):
        return (idx[:, 1] >= j0) & (idx[:, 1] < j1) & (idx[:, 2] >= k0)

    return _cut_block(f"slot block {nx}x{ny}x{nz}, slot {width} x {depth}", (nx, ny, nz), remove, cut, lattice)


def scene_cavity_block(
    n_per_axis=16,
    *,
    cavity_radius: float = 3.0,
    **lattice,
) -> CutScene:
    """A jittered cubic block with a sealed spherical cavity at its centre.

    The cavity removes every lattice site within ``cavity_radius`` [m] of the block's centre (unjittered
    positions). ``cut`` holds ``center`` and ``radius``. It is sealed for any probe that cannot pass the
    lattice's windows (rho above about sqrt(2)/2 spacing - r, i.e. 0.25 at r = 0.45). ``**lattice``: as for
    :func:`scene_slot_block`.
    """
    spacing = _lattice_spacing(lattice)
    n3 = np.broadcast_to(np.asarray(n_per_axis, dtype=np.int64), (3,))
    centre = (n3 - 1) / 2.0

    def remove(idx):
        return np.linalg.norm(idx - centre, axis=1) * spacing < cavity_radius

    return _cut_block(
        f"cavity block {n3[0]}x{n3[1]}x{n3[2]}, cavity r = {cavity_radius:g}",
        tuple(int(x) for x in n3),
        remove,
        dict(kind="cavity", center=centre * spacing, radius=float(cavity_radius)),
        lattice,
    )


def scene_tunnel_block(
    n_per_axis=(20, 16, 16),
    *,
    tunnel_radius: float = 2.5,
    **lattice,
) -> CutScene:
    """A jittered cubic block with a straight tunnel bored along x through its whole length (open both ends).

    The tunnel removes every lattice site within ``tunnel_radius`` [m] of the line through the block's centre
    along x (unjittered positions). ``cut`` holds ``axis`` (y, z of the line [m]), ``radius``, ``length`` (the
    block's x extent, n_x spacings) and ``width``, the span in y of the removed sites plus one spacing (the
    free width between the walls' sphere centres minus one diameter, uncertain by about one diameter).
    ``**lattice``: as for :func:`scene_slot_block`.
    """
    spacing = _lattice_spacing(lattice)
    n3 = np.broadcast_to(np.asarray(n_per_axis, dtype=np.int64), (3,))
    centre = (n3 - 1) / 2.0

    def remove(idx):
        return np.hypot(idx[:, 1] - centre[1], idx[:, 2] - centre[2]) * spacing < tunnel_radius

    nx, ny, nz = (int(x) for x in n3)
    iy, iz = np.meshgrid(np.arange(ny), np.arange(nz), indexing="ij")
    gone = np.hypot(iy - centre[1], iz - centre[2]) * spacing < tunnel_radius
    span = iy[gone].max() - iy[gone].min() + 1 if gone.any() else 0
    cut = dict(
        kind="tunnel",
        axis=centre[1:] * spacing,
        radius=float(tunnel_radius),
        length=nx * spacing,
        width=float(span * spacing),
    )
    return _cut_block(f"tunnel block {nx}x{ny}x{nz}, tunnel r = {tunnel_radius:g}", (nx, ny, nz), remove, cut, lattice)
