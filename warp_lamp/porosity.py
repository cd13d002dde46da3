"""Porosity of sphere packings on a CFD grid (Zhang, Xin, Cui and Yu, Processes 2024), on the CPU or a GPU."""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_lamp.kernels import porosity as porosity_kernels
from warp_lamp.validate import (
    DEFAULT_MAX_BYTES,
    check_box,
    check_budget,
    check_particles,
    check_shape,
    check_subdivisions,
)

__all__ = [
    "POROSITY_METHODS",
    "count_bitmap",
    "kozeny_carman",
    "midpoint_choice",
    "porosity",
    "porosity_bitmap_bytes",
    "porosity_mark_union",
]

#: Methods of :func:`porosity`: sum kinds count overlaps twice and may go below zero; union kinds do not.
POROSITY_METHODS = {"centroid": "sum", "polyhedron": "sum", "exact": "sum", "voxel": "union", "midpoint": "union"}


def porosity_bitmap_bytes(shape, subdivisions: int) -> int:
    """Bytes of the sub-cell bitmap the union methods need for ``shape`` cells of ``subdivisions``^3 sub-cells."""
    sx, sy, sz = (int(n) * int(subdivisions) for n in shape)
    return 4 * ((sx + 31) // 32) * sy * sz


def _midpoint_spheres(local, radii, hs):
    """Sphere centres and radii in sub-cell units, as the paper's algorithms take them: the centre goes to the
    sub-cell that holds it, the radius is rounded to the nearest whole number of sub-cells (at least 1)."""
    h = float(np.min(hs))
    centers = np.floor(local / hs).astype(np.int32)
    rad = np.maximum(np.rint(radii / h), 1).astype(np.int32)
    return centers, rad


def midpoint_choice(radii_sub: np.ndarray, n_subcells: int) -> int:
    """The paper's section 2.3 discriminant: Algorithm 2 when sum_r N_r 4/3 pi r^3 > 8 K R^3, else Algorithm 1.

    Its left side is the work of Algorithm 1 (every sphere's sub-cells, overlaps repeated), its right side the
    work of Algorithm 2 (K sub-cells, each searching a cube of side 2R). Radii in sub-cells; R the largest.
    """
    if len(radii_sub) == 0:
        return 1
    r = radii_sub.astype(np.float64)
    return 2 if np.sum(4.0 / 3.0 * np.pi * r**3) > 8.0 * n_subcells * float(r.max()) ** 3 else 1


def porosity(
    centers,
    radii,
    lower,
    upper,
    shape,
    *,
    method: str = "voxel",
    subdivisions: int = 8,
    device=None,
    midpoint_algorithm: int | None = None,
    max_bytes: int = DEFAULT_MAX_BYTES,
) -> np.ndarray:
    """Porosity (1 - solid volume / cell volume) of each cell of a box grid around a sphere packing.

    Methods:
        ``"centroid"`` (sum): PFC's centroid mode; a sphere's whole volume goes to the cell holding its centre.
        ``"polyhedron"`` (sum): PFC's polyhedron mode as the paper describes it; each sphere is replaced by its
            bounding cube, whose overlap with each cell is counted.
        ``"exact"`` (sum): the exact volume of each sphere inside each cell (closed form, float64), summed over
            spheres, so overlapping spheres count twice, as CFD-DEM codes do.
        ``"voxel"`` (union): each cell is cut into ``subdivisions``^3 sub-cells; a sub-cell is solid when its
            true centre lies in any sphere (no rounding of centres or radii), and is counted once.
        ``"midpoint"`` (union): the paper's own algorithm on the same sub-grid: sphere centres go to the sub-cell
            that holds them and radii are rounded to whole sub-cells; Algorithm 1 (traversal sphere, 3D midpoint
            circle) or Algorithm 2 (traversal small-grid), chosen by the discriminant of its section 2.3 unless
            ``midpoint_algorithm`` (1 or 2) forces one. The printed pseudo-code needed these fixes to run:
            (1) the decision parameter starts at p = 5/4 - r (the value the text derives), not the printed 5/4;
            (2) ``circle`` tests ``yr >= x`` with x undefined: it is z, the outer loop's variable; (3) ``circle``
            initialises ``P`` but updates ``p``: one variable; (4) Algorithm 2 keeps one flag per sub-cell and a
            single radius: it needs each centre's own radius, so centres are indexed in a hash grid. ``line``
            is kept as printed, ``for i in range(x)``: its runs stop one sub-cell short of +-x and x = 0 draws
            nothing. That looks like a slip too, but with it Algorithm 1 reproduces every row of the paper's
            Table 1 exactly (r = 10: 4175 sub-cells; r = 25: 64025), and with the ends included it does not
            (4873 and 68075): it is what the authors ran. It leaves spheres slightly under-filled.

    Sum methods may return porosity below zero where spheres overlap or (polyhedron) where cubes overstate the
    spheres: it is returned as is, unclamped, because clamping would hide exactly what the paper reports.

    Args:
        centers: Sphere centres [m], shape (N, 3).
        radii: Sphere radii [m], shape (N,), or one number.
        lower: Lower corner of the box [m], 3 values.
        upper: Upper corner of the box [m], 3 values.
        shape: Cells along x, y, z.
        method: One of :data:`POROSITY_METHODS`.
        subdivisions: Sub-cells per cell edge for the union methods.
        device: Warp device.
        midpoint_algorithm: Force Algorithm 1 or 2 of the midpoint method (default: the paper's discriminant).
        max_bytes: Budget for the union methods' bitmap; a larger one raises ValueError before allocating.

    Returns:
        Porosity, shape ``shape``, float64, indexed [i, j, k] along x, y, z.
    """
    c, r = check_particles(centers, radii)
    lo, hi = check_box(lower, upper)
    shape = check_shape(shape)
    if method not in POROSITY_METHODS:
        raise ValueError(f"method: unknown {method!r}; expected one of {sorted(POROSITY_METHODS)}")
    s = check_subdivisions(subdivisions)
    if midpoint_algorithm not in (None, 1, 2):
        raise ValueError(f"midpoint_algorithm: expected None, 1 or 2, got {midpoint_algorithm!r}")
    device = wp.get_device(device)
    h = (hi - lo) / np.asarray(shape)
    local = c - lo  # float64, so that a box far from the origin loses nothing
    if POROSITY_METHODS[method] == "sum":
        solid = _porosity_sum(method, local, r, h, shape, device)
        return 1.0 - solid / float(np.prod(h))
    need = porosity_bitmap_bytes(shape, s)
    sub = tuple(x * s for x in shape)
    check_budget(
        need,
        max_bytes,
        f"subdivisions: {s} gives {sub[0] * sub[1] * sub[2]:,} sub-cells and a {need:,}-byte bitmap",
        "raise max_bytes or lower subdivisions",
    )
    bits = porosity_mark_union(
        method, local, r, h / s, tuple(x * s for x in shape), device, algorithm=midpoint_algorithm
    )
    counts = wp.zeros(shape, dtype=wp.int32, device=device)
    count_bitmap(bits, shape, s, counts)
    return 1.0 - counts.numpy().astype(np.float64) / float(s**3)


def _porosity_sum(method, local, radii, h, shape, device) -> np.ndarray:
    """Solid volume per cell [m^3] by one of the sum methods, shape ``shape``."""
    solid = wp.zeros(shape, dtype=wp.float64, device=device)
    if len(radii):
        inputs = [
            wp.array(local, dtype=wp.vec3d, device=device),
            wp.array(radii, dtype=wp.float64, device=device),
            wp.vec3d(*h),
            wp.vec3i(*shape),
        ]
        if method == "centroid":
            kernel = porosity_kernels.porosity_centroid
        else:
            kernel = porosity_kernels.porosity_box
            inputs.append(porosity_kernels.BOX_EXACT if method == "exact" else porosity_kernels.BOX_CUBE)
        wp.launch(kernel, dim=len(radii), inputs=inputs, outputs=[solid], device=device)
    return solid.numpy()


def porosity_mark_union(method, local, radii, hs, sub, device, *, algorithm=None, bits=None) -> wp.array:
    """The union methods' first step: the bitmap of solid sub-cells (one bit per sub-cell, rows padded to 32).

    Args:
        method: ``"voxel"`` or ``"midpoint"``.
        local: Sphere centres relative to the box's lower corner [m], shape (N, 3), float64 (numpy), or a warp
            ``vec3d`` array on ``device``.
        radii: Sphere radii [m], shape (N,), float64 (numpy or warp).
        hs: Sub-cell edge per axis [m], 3 values.
        sub: Sub-cells per axis, 3 integers.
        device: Warp device.
        algorithm: Midpoint only: 1 or 2, or None for the paper's discriminant.
        bits: A zeroed bitmap to mark into (``porosity_bitmap_bytes`` / 4 words), or None to allocate one.

    Returns:
        The bitmap, uint32 words: word w of row (j, k) holds sub-cells 32 w ... 32 w + 31 along x.
    """
    device = wp.get_device(device)
    words = (sub[0] + 31) // 32
    if bits is None:
        bits = wp.zeros(words * sub[1] * sub[2], dtype=wp.uint32, device=device)
    n = len(radii)
    if n == 0:
        return bits
    if method == "voxel":
        cen = local if isinstance(local, wp.array) else wp.array(local, dtype=wp.vec3d, device=device)
        rad = radii if isinstance(radii, wp.array) else wp.array(radii, dtype=wp.float64, device=device)
        wp.launch(
            porosity_kernels.voxel_mark,
            dim=n,
            inputs=[cen, rad, wp.vec3d(*hs), wp.vec3i(*sub), words],
            outputs=[bits],
            device=device,
        )
        return bits
    local = local.numpy() if isinstance(local, wp.array) else local
    radii = radii.numpy() if isinstance(radii, wp.array) else radii
    mc, mr = _midpoint_spheres(local, radii, np.asarray(hs))
    algorithm = algorithm or midpoint_choice(mr, sub[0] * sub[1] * sub[2])
    cen = wp.array(mc, dtype=wp.vec3i, device=device)
    rad = wp.array(mr, dtype=wp.int32, device=device)
    if algorithm == 1:
        wp.launch(
            porosity_kernels.midpoint_mark,
            dim=n,
            inputs=[cen, rad, wp.vec3i(*sub), words],
            outputs=[bits],
            device=device,
        )
        return bits
    rmax = int(mr.max())
    grid = wp.HashGrid(*(max(1, min(128, x // max(1, 2 * rmax))) for x in sub), device=device)
    grid.build(wp.array(mc.astype(np.float32), dtype=wp.vec3, device=device), float(rmax))
    # Every centre within the cube |d| <= R is within R sqrt(3) of the sub-cell.
    search = float(rmax) * 1.7321 + 1.0
    wp.launch(
        porosity_kernels.midpoint_grid_mark,
        dim=bits.shape[0],
        inputs=[grid.id, cen, rad, wp.vec3i(*sub), words, search],
        outputs=[bits],
        device=device,
    )
    return bits


def count_bitmap(bits: wp.array, shape, s: int, counts: wp.array) -> None:
    """Add each cell's solid sub-cells (the set bits of the bitmap of ``shape`` cells of s^3 sub-cells) to counts."""
    sub = tuple(int(x) * s for x in shape)
    wp.launch(
        porosity_kernels.bitmap_count,
        dim=(shape[0], shape[1], sub[2]),
        inputs=[bits, wp.vec3i(*sub), (sub[0] + 31) // 32, wp.vec3i(s, s, s)],
        outputs=[counts],
        device=bits.device,
    )


def kozeny_carman(porosity, particle_radius) -> np.ndarray:
    """Kozeny-Carman permeability in the paper's form [m^2]: K = (1/180) e^3 / (1 - e)^2 (2 r)^2 for e <= 0.7,
    and K(0.7) above.

    Args:
        porosity: Porosity e, any shape; every value must be in (0, 1].
        particle_radius: Particle radius r [m], a number or an array broadcastable to ``porosity``.

    Raises:
        ValueError: for porosity <= 0 (the solve the paper describes overflows there), NaN, or above 1, naming
            the first bad index; for a radius <= 0.
    """
    e = np.asarray(porosity, dtype=np.float64)
    r = np.asarray(particle_radius, dtype=np.float64)
    bad = ~(e > 0) | (e > 1)
    if bad.any():
        k = np.unravel_index(int(np.flatnonzero(bad)[0]), e.shape) if e.ndim else ()
        raise ValueError(f"porosity: must be in (0, 1]; index {tuple(int(x) for x in k)} is {e[k]!r}")
    if not (np.isfinite(r) & (r > 0)).all():
        raise ValueError(f"particle_radius: must be finite and > 0, got {particle_radius!r}")
    e = np.minimum(e, 0.7)
    return e**3 / (1.0 - e) ** 2 * (2.0 * r) ** 2 / 180.0
