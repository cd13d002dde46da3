"""Porosity of sphere packings on a CFD grid (Zhang, Xin, Cui and Yu, Processes 2024), on the CPU or a GPU."""

from __future__ import annotations

import warnings

import numpy as np
import warp as wp

from warp_lamp.kernels import porosity as porosity_kernels
from warp_lamp.validate import (
    DEFAULT_MAX_BYTES,
    check_box,
    check_budget,
    check_device_match,
    check_max_bytes,
    check_particles,
    check_shape,
    check_subdivisions,
    format_bytes,
    format_value,
    resolve_device,
)

__all__ = [
    "MIDPOINT_MAX_RADIUS",
    "MIDPOINT_VOLUME_FACTOR",
    "POROSITY_METHODS",
    "count_bitmap",
    "kozeny_carman",
    "midpoint_choice",
    "midpoint_subdivisions",
    "porosity",
    "porosity_bitmap_bytes",
    "porosity_mark_union",
    "porosity_nbytes",
    "porosity_plan",
]

#: Methods of :func:`porosity`: sum kinds count overlaps twice and may go below zero; union kinds do not.
POROSITY_METHODS = {"centroid": "sum", "polyhedron": "sum", "exact": "sum", "voxel": "union", "midpoint": "union"}

#: Largest sphere radius, in sub-cells, of the midpoint method: its integer circle arithmetic (4 r^2 in int64,
#: through a float64 square root) is exact up to there.
MIDPOINT_MAX_RADIUS = 1 << 24

#: Most sub-cells along one axis: bitmap rows and sub-cell coordinates are int32 in the kernels.
_MAX_SUB = 1 << 30
#: Algorithm 2 keeps sub-cell coordinates in a float32 hash grid, exact up to 2**24.
_MAX_SUB_HASH = 1 << 24


def _subdivisions(subdivisions) -> tuple[int, int, int]:
    return check_subdivisions(subdivisions)


def porosity_bitmap_bytes(shape, subdivisions) -> int:
    """Bytes of the sub-cell bitmap the union methods need for ``shape`` cells of ``subdivisions`` sub-cells per
    cell edge (one integer, or three along x, y, z)."""
    s = _subdivisions(subdivisions)
    sx, sy, sz = (int(n) * k for n, k in zip(shape, s, strict=True))
    return 4 * ((sx + 31) // 32) * sy * sz


def porosity_nbytes(shape, *, method: str = "voxel", subdivisions=8, n_spheres: int = 0) -> int:
    """Device memory one :func:`porosity` call allocates [bytes], known before anything is allocated.

    Sum methods: the float64 solid volume per cell, and the spheres in float64 (32 B each). Union methods: the
    sub-cell bitmap, an int64 count per cell, and the spheres (float64 for voxel; int32 sub-cell centres and radii
    for midpoint, plus, for its Algorithm 2, a hash grid of up to 128^3 cells and float32 centres). The host's copy
    of the result is the size of the per-cell array again.

    Args:
        shape: Cells along x, y, z.
        method: One of :data:`POROSITY_METHODS`.
        subdivisions: Sub-cells per cell edge (union methods), one integer or three.
        n_spheres: Spheres the call sends to the device.
    """
    cells = int(np.prod([int(x) for x in shape], dtype=object))
    n = int(n_spheres)
    if POROSITY_METHODS[method] == "sum":
        return 8 * cells + 32 * n
    need = porosity_bitmap_bytes(shape, subdivisions) + 8 * cells
    if method == "voxel":
        return need + 32 * n
    return need + 16 * n + 8 * 128**3 + 48 * n


def midpoint_subdivisions(cell, subdivisions, *, per_axis: bool) -> tuple[int, int, int]:
    """Sub-cells per cell edge for the midpoint method, whose sub-cells must be cubes (the paper draws spheres on a
    cubic sub-grid; on stretched sub-cells they would become ellipsoids).

    Args:
        cell: Cell edges [m], 3 values.
        subdivisions: Sub-cells per cell edge: (sx, sy, sz) used as given, or one integer s, the count along the
            cell's shortest edge, the other edges getting as many sub-cells of the same size as fit whole (a
            1 x 1 x 2 cell at s = 8 gives (8, 8, 16)).
        per_axis: ``subdivisions`` was given as three numbers.

    Raises:
        ValueError: when the sub-cells would not be cubes (to 1e-9, relative), naming ``subdivisions``.
    """
    h = np.asarray(cell, dtype=np.float64)
    s = np.asarray(_subdivisions(subdivisions), dtype=np.float64)
    if per_axis:
        edges = h / s
        if edges.max() - edges.min() <= 1e-9 * edges.min():
            return tuple(int(x) for x in s)
        raise ValueError(
            f"subdivisions: midpoint needs cubic sub-cells, but {tuple(int(x) for x in s)} cuts cells of "
            f"{h.tolist()} m into sub-cells of {edges.tolist()} m; choose counts proportional to the cell edges, "
            "or use method='voxel', which is exact for any cell shape"
        )
    want = h / (h.min() / s[0])
    whole = np.rint(want)
    if np.all(np.abs(want - whole) <= 1e-9 * want):
        return tuple(int(x) for x in whole)
    raise ValueError(
        f"subdivisions: midpoint needs cubic sub-cells; cells of {h.tolist()} m with {int(s[0])} along the shortest "
        f"edge would need {want.tolist()} along x, y, z, not whole numbers; pass three subdivisions (x, y, z) whose "
        "sub-cell edges agree, or use method='voxel', which is exact for any cell shape"
    )


def _midpoint_spheres(local, radii, hs):
    """Sphere centres and radii in sub-cell units, as the paper's algorithms take them: the centre goes to the
    sub-cell that holds it, the radius is rounded to the nearest whole number of sub-cells (at least 1). float64
    (whole numbers), so that a far or huge sphere cannot overflow before it is dropped or refused."""
    h = float(np.min(hs))
    centers = np.floor(local / hs)
    rad = np.maximum(np.rint(radii / h), 1.0)
    return centers, rad


def _midpoint_inputs(local, radii, hs, sub):
    """The midpoint method's spheres that can mark a sub-cell, as int32 sub-cell centres and radii: a sphere whose
    cube [c - r, c + r] misses the sub-grid marks nothing in either algorithm and is dropped, so that neither its
    position nor its size can overflow. Returns (centres, radii, all radii in sub-cells as float64)."""
    mc, mr = _midpoint_spheres(local, radii, hs)
    reach = np.all(mc + mr[:, None] >= 0, axis=1) & np.all(mc - mr[:, None] <= np.asarray(sub) - 1, axis=1)
    big = reach & (mr > MIDPOINT_MAX_RADIUS)
    if big.any():
        k = int(np.flatnonzero(big)[0])
        raise ValueError(
            f"radii: sphere {k} is {mr[k]:.4g} sub-cells in radius, over the {MIDPOINT_MAX_RADIUS:,} that the midpoint "
            "method's integer arithmetic holds; use method='voxel', or fewer subdivisions"
        )
    return mc[reach].astype(np.int32), mr[reach].astype(np.int32), mr


def midpoint_choice(radii_sub: np.ndarray, n_subcells: int) -> int:
    """The paper's section 2.3 discriminant: Algorithm 2 when sum_r N_r 4/3 pi r^3 > 8 K R^3, else Algorithm 1.

    Its left side is the work of Algorithm 1 (every sphere's sub-cells, overlaps repeated), its right side the
    work of Algorithm 2 (K sub-cells, each searching a cube of side 2R). Radii in sub-cells; R the largest.
    """
    if len(radii_sub) == 0:
        return 1
    r = np.asarray(radii_sub, dtype=np.float64)
    return 2 if np.sum(4.0 / 3.0 * np.pi * r**3) > 8.0 * float(n_subcells) * float(r.max()) ** 3 else 1


#: How far (a factor, either way) the midpoint method's whole-sub-cell radii may take the spheres' volume from
#: their true volume before :func:`porosity` warns.
MIDPOINT_VOLUME_FACTOR = 2.0


def _midpoint_volume(rounded: np.ndarray) -> np.ndarray:
    """Sub-cells the midpoint method marks for a sphere of whole radius R (its Table 1: 1 for R = 1, then within
    a few per cent of 4/3 pi R^3 from R = 2 on), in sub-cell volumes."""
    return np.where(rounded <= 1.0, 1.0, 4.0 / 3.0 * np.pi * rounded**3)


def _warn_midpoint_rounding(local, radii, hs, sub, s) -> None:
    """Warn, naming ``subdivisions``, when rounding the radii to whole sub-cells moves the spheres' volume by more
    than :data:`MIDPOINT_VOLUME_FACTOR` (spheres much smaller than a sub-cell become one whole sub-cell)."""
    if len(radii) == 0:
        return
    mc, mr = _midpoint_spheres(local, radii, hs)
    reach = np.all(mc + mr[:, None] >= 0, axis=1) & np.all(mc - mr[:, None] <= np.asarray(sub) - 1, axis=1)
    if not reach.any():
        return
    h = float(np.min(hs))
    true_r = radii[reach] / h
    factor = float(np.sum(_midpoint_volume(mr[reach])) / np.sum(4.0 / 3.0 * np.pi * true_r**3))
    if 1.0 / MIDPOINT_VOLUME_FACTOR <= factor <= MIDPOINT_VOLUME_FACTOR:
        return
    median = float(np.median(true_r))
    # Five sub-cells of radius keep the midpoint sphere within about 1% of its volume (Table 1).
    need = int(np.ceil(5.0 / median * min(s)))
    how = f"{factor:,.0f} times" if factor > 1 else f"{factor:.2f} of"
    unit = "sub-cell" if median == 1 else "sub-cells"
    warnings.warn(
        f"subdivisions: with {format_value(tuple(s))} sub-cells per cell the spheres are {median:.3g} {unit} in "
        f"radius (median); the midpoint method rounds radii to whole sub-cells (at least 1), which gives them {how} "
        f"their true volume; use subdivisions >= {need:,} (5 sub-cells per radius), or method='voxel' or 'exact'",
        RuntimeWarning,
        stacklevel=3,
    )


def _warn_outside(c, r, lo, hi) -> None:
    """Warn when the spheres cannot be meant for this box: none reaches it, or they fill under 1e-9 of it."""
    if len(r) == 0:
        return
    outside = np.any((c + r[:, None] <= lo) | (c - r[:, None] >= hi), axis=1)
    if outside.all():
        k = 0
        warnings.warn(
            f"porosity: all {len(r)} spheres lie wholly outside the box {lo.tolist()} .. {hi.tolist()} (sphere {k}: "
            f"centre {c[k].tolist()}, radius {r[k]:g}), so every cell is empty; do the box and the spheres share one "
            "unit (SI: metres)?",
            RuntimeWarning,
            stacklevel=3,
        )
        return
    volume = float(np.sum(4.0 / 3.0 * np.pi * r**3))
    if volume < 1e-9 * float(np.prod(hi - lo)):
        warnings.warn(
            f"porosity: the {len(r)} spheres' volume is {volume / float(np.prod(hi - lo)):.2g} of the box's; do "
            "the box and the spheres share one unit (SI: metres)?",
            RuntimeWarning,
            stacklevel=3,
        )


def porosity_plan(
    lower, upper, shape, method, subdivisions, midpoint_algorithm, n_spheres: int, max_bytes, *, bitmaps: int = 1
) -> tuple:
    """Check :func:`porosity`'s box and options, and its memory before anything is allocated (also for
    ``distributed.porosity_distributed``, whose OR by gathering holds ``bitmaps`` bitmaps).

    Args:
        lower, upper, shape, method, subdivisions, midpoint_algorithm, max_bytes: As :func:`porosity`.
        n_spheres: Spheres sent to the device.
        bitmaps: Sub-cell bitmaps held at once (union methods).

    Returns:
        ``(lower, upper, shape, s, h, sub)``: the box [m] (float64), the cells, sub-cells per cell edge (cubic for
        the midpoint method), the cell edges [m] and the sub-cells along x, y, z.
    """
    lo, hi = check_box(lower, upper)
    shape = check_shape(shape)
    if not isinstance(method, str) or method not in POROSITY_METHODS:
        raise ValueError(f"method: unknown {format_value(method)}; expected one of {sorted(POROSITY_METHODS)}")
    per_axis = not isinstance(subdivisions, (int, np.integer))
    s = _subdivisions(subdivisions)
    if isinstance(midpoint_algorithm, bool) or midpoint_algorithm not in (None, 1, 2):
        raise ValueError(f"midpoint_algorithm: expected None, 1 or 2, got {format_value(midpoint_algorithm)}")
    max_bytes = check_max_bytes(max_bytes)
    h = (hi - lo) / np.asarray(shape)
    if method == "midpoint":
        s = midpoint_subdivisions(h, s if per_axis else s[0], per_axis=per_axis)
    sub = tuple(x * k for x, k in zip(shape, s, strict=True))
    need = porosity_nbytes(shape, method=method, subdivisions=s, n_spheres=n_spheres)
    if POROSITY_METHODS[method] == "sum":
        what = f"shape: {shape} cells and {n_spheres:,} spheres need {format_bytes(need)}"
        check_budget(need, max_bytes, what, "use fewer cells")
    else:
        bitmap = porosity_bitmap_bytes(shape, s)
        need += (bitmaps - 1) * bitmap
        held = f"a {format_bytes(bitmap)} bitmap" if bitmaps == 1 else f"{bitmaps} bitmaps of {format_bytes(bitmap)}"
        what = (
            f"subdivisions: {s} on shape {shape} gives {sub[0] * sub[1] * sub[2]:,} sub-cells and {held}, "
            f"{format_bytes(need)} in all"
        )
        check_budget(need, max_bytes, what, "lower subdivisions or use fewer cells")
        if max(sub) > _MAX_SUB or bitmap // 4 >= 1 << 31:
            raise ValueError(f"subdivisions: {s} on shape {shape} gives {sub} sub-cells, over the int32 indices")
    return lo, hi, shape, s, h, sub


def porosity(
    centers,
    radii,
    lower,
    upper,
    shape,
    *,
    method: str = "voxel",
    subdivisions=8,
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
        ``"voxel"`` (union): each cell is cut into ``subdivisions**3`` sub-cells; a sub-cell is solid when its
            true centre lies in any sphere (no rounding of centres or radii), and is counted once. Exact in the
            limit for any cell shape; sub-cells may be stretched.
        ``"midpoint"`` (union): the paper's own algorithm on the same sub-grid: sphere centres go to the sub-cell
            that holds them and radii are rounded to whole sub-cells; Algorithm 1 (traversal sphere, 3D midpoint
            circle) or Algorithm 2 (traversal small-grid), chosen by the discriminant of its section 2.3 unless
            ``midpoint_algorithm`` (1 or 2) forces one. Its sub-cells must be cubes, or the spheres would become
            ellipsoids: an integer ``subdivisions`` is the count along each cell's shortest edge and the longer
            edges get whole multiples of the same sub-cell (cells 1 x 1 x 2 at 8 give 8 x 8 x 16 sub-cells);
            cells whose edges are not whole multiples of one sub-cell are refused (ValueError naming
            ``subdivisions``), as are three subdivisions that give non-cubic sub-cells. Algorithm 1 is evaluated
            in closed form only on the rows inside the box, so a sphere much larger than the box costs the box's
            rows, not r^2; radii above :data:`MIDPOINT_MAX_RADIUS` sub-cells are refused. The printed pseudo-code
            needed these fixes to run:
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

    Every device allocation (:func:`porosity_nbytes`) is checked against ``max_bytes`` before anything is
    allocated. A RuntimeWarning says when no sphere reaches the box, or when the spheres fill under 1e-9 of it:
    the signs of a box and spheres in different units.

    Args:
        centers: Sphere centres [m], shape (N, 3): NumPy, sequences, or a warp ``vec3``/``vec3d`` array on any
            device (read to the host once, for the checks; the work then runs on that device).
        radii: Sphere radii [m], shape (N,), or one number (NumPy, or a warp array).
        lower: Lower corner of the box [m], 3 values.
        upper: Upper corner of the box [m], 3 values.
        shape: Cells along x, y, z.
        method: One of :data:`POROSITY_METHODS`.
        subdivisions: Sub-cells per cell edge for the union methods: one integer, or three (along x, y, z).
        device: Warp device; by default where warp-array inputs live, else Warp's default.
        midpoint_algorithm: Force Algorithm 1 or 2 of the midpoint method (default: the paper's discriminant).
        max_bytes: Budget for the call's device memory [bytes]; a larger need raises ValueError before
            allocating. ``math.inf`` for none.

    Returns:
        Porosity, shape ``shape``, float64, indexed [i, j, k] along x, y, z.
    """
    device = check_device_match(device, centers=centers, radii=radii)  # a missing GPU: one line, naming device
    c, r = check_particles(centers, radii)
    lo, hi, shape, s, h, sub = porosity_plan(
        lower, upper, shape, method, subdivisions, midpoint_algorithm, len(r), max_bytes
    )
    _warn_outside(c, r, lo, hi)
    local = c - lo  # float64, so that a box far from the origin loses nothing
    if method == "midpoint":
        _warn_midpoint_rounding(local, r, h / np.asarray(s), sub, s)
    if POROSITY_METHODS[method] == "sum":
        solid = _porosity_sum(method, local, r, h, shape, device)
        return 1.0 - solid / float(np.prod(h))
    bits = porosity_mark_union(method, local, r, h / np.asarray(s), sub, device, algorithm=midpoint_algorithm)
    counts = wp.zeros(shape, dtype=wp.int64, device=device)
    count_bitmap(bits, shape, s, counts)
    return 1.0 - counts.numpy().astype(np.float64) / float(s[0] * s[1] * s[2])


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
    device = resolve_device(device)
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
    mc, mr, all_radii = _midpoint_inputs(local, radii, np.asarray(hs), sub)
    algorithm = algorithm or midpoint_choice(all_radii, sub[0] * sub[1] * sub[2])
    if len(mr) == 0:
        return bits
    cen = wp.array(mc, dtype=wp.vec3i, device=device)
    rad = wp.array(mr, dtype=wp.int32, device=device)
    if algorithm == 1:
        wp.launch(
            porosity_kernels.midpoint_mark,
            dim=len(mr),
            inputs=[cen, rad, wp.vec3i(*sub), words],
            outputs=[bits],
            device=device,
        )
        return bits
    rmax = int(mr.max())
    if max(sub) + rmax > _MAX_SUB_HASH:
        raise ValueError(
            f"midpoint_algorithm: Algorithm 2 keeps sub-cell coordinates (up to {max(sub) + rmax:,}) in a float32 "
            "hash grid, exact only to 2**24; use midpoint_algorithm=1 or fewer subdivisions"
        )
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


def count_bitmap(bits: wp.array, shape, s, counts: wp.array) -> None:
    """Add each cell's solid sub-cells (the set bits of the bitmap of ``shape`` cells of ``s`` sub-cells per edge,
    one integer or three) to ``counts``, an int64 warp array of shape ``shape``."""
    s = _subdivisions(s)
    sub = tuple(int(x) * k for x, k in zip(shape, s, strict=True))
    wp.launch(
        porosity_kernels.bitmap_count,
        dim=(shape[0], shape[1], sub[2]),
        inputs=[bits, wp.vec3i(*sub), (sub[0] + 31) // 32, wp.vec3i(*s)],
        outputs=[counts],
        device=bits.device,
    )


def kozeny_carman(porosity, particle_radius) -> np.ndarray:
    """Kozeny-Carman permeability in the paper's form [m^2]: K = (1/180) e^3 / (1 - e)^2 (2 r)^2 for e <= 0.7,
    and K(0.7) above.

    Args:
        porosity: Porosity e, any shape; every value must be in (0, 1].
        particle_radius: The particle radius r of each cell [m]: one number (the mean radius, as the paper uses),
            or an array of ``porosity``'s shape (or one that broadcasts to it), e.g. a per-cell mean radius. Not
            one radius per particle: average them first.

    Raises:
        ValueError: for porosity <= 0 (the solve the paper describes overflows there), NaN, or above 1, naming
            the first bad index; for a radius <= 0, or a radius array that does not match ``porosity``.
    """
    e = np.asarray(porosity, dtype=np.float64)
    try:
        r = np.asarray(particle_radius, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ValueError(f"particle_radius: expected a number or an array of numbers ({err})") from None
    bad = ~(e > 0) | (e > 1)
    if bad.any():
        k = np.unravel_index(int(np.flatnonzero(bad)[0]), e.shape) if e.ndim else ()
        raise ValueError(f"porosity: must be in (0, 1]; index {tuple(int(x) for x in k)} is {format_value(e[k])}")
    try:
        shape = np.broadcast_shapes(e.shape, r.shape)
    except ValueError:
        shape = None
    if shape != e.shape:
        raise ValueError(
            f"particle_radius: shape {r.shape} does not match the porosity's {e.shape}; give one number (the mean "
            "particle radius) or one radius per cell, not one per particle (average them first: "
            "particle_radius=radii.mean())"
        )
    if not (np.isfinite(r) & (r > 0)).all():
        k = int(np.flatnonzero(~(np.isfinite(r) & (r > 0)).ravel())[0]) if r.ndim else 0
        where = f"; flat index {k} is {format_value(r.ravel()[k])}" if r.ndim else f", got {format_value(r[()])}"
        raise ValueError(f"particle_radius: must be finite and > 0{where}")
    e = np.minimum(e, 0.7)
    return e**3 / (1.0 - e) ** 2 * (2.0 * r) ** 2 / 180.0
