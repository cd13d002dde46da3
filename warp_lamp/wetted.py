"""Every wetted surface loaded: a rolling-probe fluid region on the lamp's voxel grid.

The lamp loads only what each lamp sees first (the memo's limitation 1) and its rays reach deep particles
through the channels between spheres (limitation 2). This mode loads the boundary of a fluid region instead:

- **Allowed** probe centres: points z with ``|z - c_i| >= r_i + rho`` for every sphere (``rho`` is the probe
  radius, :attr:`WettedSurface.probe_radius`); at voxel centres they make the ``blocked`` map's complement.
- **Reached**: allowed voxel centres 6-connected to the outside of the box; everything beyond the box is allowed
  and reached.
- **Fluid** (wetted) voxel centres x, decided exactly: x is fluid when a reachable probe centre lies within rho
  of it. Within rho of a reached voxel centre (the offset set of :func:`dilation_table`) it is; strictly inside a
  sphere (``|x - c_i|^2 < r_i^2``, the ``solid`` map) it is not; farther than :func:`band_radius` (rho plus one
  voxel diagonal) from every reached voxel it is not; in between (the *uncertain band*) exact distances decide:
  the candidate probe centres are the critical points of the union of inflated balls near x (radial projections
  of x onto the inflated spheres, the nearest points of their pairwise intersection circles, their triple points),
  and one counts when it is within rho of x, outside every other inflated ball, and reachable: a reached corner
  of the voxel-centre cube that holds it joins it by a segment that enters no inflated ball. ``rho = 0``: fluid =
  reached (up to voxel centres exactly on a sphere).
- **Crossings**: along every voxel row of the three lamp grids, with virtual fluid beyond both ends of the box,
  every change from fluid to dry going +a is a +1 on axis a for the low lamp (``"-a"``, pushing +a), every change
  from dry to fluid a -1 for the high lamp. **Thin chords**: a sphere chord that holds no voxel centre, between
  two fluid samples of a row, is a dry interval the samples miss; thin chords between the same two samples merge
  where they overlap or where the gap between them is dry (the exact test at its midpoint), and each merged
  interval is one crossing of each direction. Crossings alternate along a row, so with both lamps of an axis on,
  the counts of that axis sum to exactly zero.
- **Attribution**: a crossing goes to the sphere nearest to the face between the two voxel centres, by
  ``|p - c_i| - r_i`` in float64, ties to the lowest index (never farther than :func:`attribution_bound`); a thin
  interval's entry to the sphere whose chord starts it, its exit to the one whose chord reaches furthest.

- **Walls** (planes with the fluid where ``g = n . x - d > 0``): the probe centre keeps
  ``g >= rho`` from every wall, a voxel centre with ``g < 0`` is solid, beyond the box only the points that keep rho
  from every wall are reached and only those within rho of them are fluid (the walls' own fluid: ``g >= 0`` for one
  wall). The offset planes are more candidates of the exact test. A crossing goes to the nearest wall that cuts its axis
  when that wall is nearer than every sphere (``g(p)`` against ``|p - c| - r``, ties to the sphere); a sphere
  wholly inside a wall is part of it. Per axis, particles and walls together take exactly the rays with one end in
  the fluid and the other in a wall; on an axis no wall cuts, the particles' counts still sum to zero.

A lone sphere, or spheres the probe can go around, thus take on each low lamp exactly the cells criterion 1 gives
them, for every rho >= 0 (bench/experiments/WETTED.md). :class:`WettedSurface` runs the mode on the device,
capture-safe; ``ShiningLamp(grid, surfaces="all", probe_radius=rho)`` and :func:`warp_lamp.lamp_forces` use it;
``warp_lamp.reference.wetted`` is the float64 NumPy/scipy reference.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_lamp.frames import pressure_area
from warp_lamp.grid import LampGrid
from warp_lamp.kernels import wetted as K
from warp_lamp.kernels import wetted_base as KB
from warp_lamp.kernels import wetted_cross as KC
from warp_lamp.kernels import wetted_sweeps as KS
from warp_lamp.kernels.walls import LampWalls
from warp_lamp.validate import (
    DEFAULT_MAX_BYTES,
    LAMPS,
    check_budget,
    check_particle_arrays,
    check_walls,
    check_warp_array,
    lamp_mask,
)

__all__ = [
    "WettedDiagnostics",
    "WettedSurface",
    "attribution_bound",
    "band_radius",
    "check_probe_radius",
    "cross_list_capacity",
    "dilation_table",
    "exact_queue_capacity",
    "queued_threads",
    "skin_distance",
    "thin_list_capacity",
    "unpack_bits",
    "voxel_box",
    "voxel_diagonal",
    "wetted_nbytes",
    "witness_capacity",
]

#: Device bytes per particle: 3 int64 counts, one int32 hit count, one int32 bin link, one int32 exposure flag.
BYTES_PER_PARTICLE = 36
#: ... and on CUDA: the thin chords' list (:func:`thin_list_capacity`: 16 bytes per :data:`THIN_LIST_PER`
#: sphere-axes, at least :data:`THIN_LIST_MIN` entries) and 3 int32 for where each sphere-axis's chords left it.
CUDA_BYTES_PER_PARTICLE = 18
#: Most bins of the nearest-sphere search (int32 heads); larger boxes get larger bins.
MAX_BINS = 1 << 24
#: Default bound on connectivity rounds; a solve that needs more stops there and is counted.
DEFAULT_MAX_ROUNDS = 200
#: Device bytes per wall: its plane in the frame (one vec4) and its signed counts (3 int64).
BYTES_PER_WALL = 40
#: The skin's default distance (``skin="auto"``) in voxel edges, at most half the probe radius: a dry decision's
#: certificate holds while no sphere has moved this far since it was made.
SKIN_CELLS = 0.1
#: Fewest slots of the skin's witness table (:func:`witness_capacity`).
WITNESS_MIN = 16384
#: Device bytes per particle of the skin's reference: position, radius, activity.
SKIN_BYTES_PER_PARTICLE = 20
#: The exact test's queue (CUDA) holds one voxel in this many of the box (the specimen's tests: one in 60) ...
EXACT_QUEUE_PER = 16
#: ... and at least this many.
EXACT_QUEUE_MIN = 4096
#: Threads per SM that run the queued exact tests (CUDA): at 255 registers a thread, 4 blocks of
#: :data:`SPARSE_BLOCK_DIM` fill an SM's registers. Each has a row of :data:`~warp_lamp.kernels.wetted_base.GATHER`
#: int32 for its gathered spheres; thread t tests slot t, then takes the queue's next untaken slot past them whenever
#: it finishes one.
QUEUED_THREADS_PER_SM = 256
#: Threads per block of the launches whose work sits in few threads (the queued exact tests and the listed crossings,
#: packed at the front of their launch; the thin chords, a thread per sphere and axis): at 146-255 registers a
#: thread, one block of 256 fills an SM's registers, so on the specimen 15,915 queued tests ran on 63 of the H200's
#: 132 SMs and the thin chords on 55 (Nsight Compute, 2026-11-28); blocks of 64 spread them over every SM.
SPARSE_BLOCK_DIM = 64
#: The crossing list (CUDA) holds one crossing per this many voxel faces (the bench's scenes cross about one face in
#: 60 to 110; past the list the crossings are loaded where they are found) ...
CROSS_LIST_PER = 32
#: ... and at least this many.
CROSS_LIST_MIN = 4096
#: The thin chords' list (CUDA) holds one chord per this many (sphere, axis) pairs (the 1M lattice lists about one
#: in 60; past the list a chord is walked where it was found) ...
THIN_LIST_PER = 8
#: ... and at least this many.
THIN_LIST_MIN = 4096


def check_probe_radius(probe_radius) -> float:
    """``probe_radius`` as a float, or ValueError: it must be finite and >= 0."""
    try:
        rho = float(probe_radius)
    except (TypeError, ValueError):
        raise ValueError(f"probe_radius: expected a number [m], got {probe_radius!r}") from None
    if not (np.isfinite(rho) and rho >= 0.0):
        raise ValueError(f"probe_radius: must be finite and >= 0, got {probe_radius!r}")
    return rho


def voxel_box(grid: LampGrid) -> tuple[np.ndarray, np.ndarray]:
    """Voxels per axis (3,) int64 and voxel edge h (3,) float64 of a box-form grid.

    The mode needs the three lamp grids to be the faces of one voxel grid: grid a's rows must be the voxel rows
    along a. ``LampGrid(lower, upper, cell_size)`` always is; the memo's 18-number form is refused unless its
    grids share corners, cells and counts exactly.
    """
    if not isinstance(grid, LampGrid):
        raise TypeError(f"grid: expected a LampGrid, got {type(grid).__name__}")
    # Axis b is grid (b+2)%3's u axis and grid (b+1)%3's v axis.
    n = np.array([grid.counts[(b + 2) % 3, 0] for b in range(3)], dtype=np.int64)
    h = np.array([grid.cell[(b + 2) % 3, 0] for b in range(3)], dtype=np.float64)
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        same = (
            grid.counts[a, 0] == n[u]
            and grid.counts[a, 1] == n[v]
            and grid.cell[a, 0] == h[u]
            and grid.cell[a, 1] == h[v]
            and grid.corner[a, 0] == grid.origin[u]
            and grid.corner[a, 1] == grid.origin[v]
        )
        if not same:
            raise ValueError(
                f"grid: the wetted-surface mode needs one voxel grid (LampGrid(lower, upper, cell_size)); grid {a} "
                f"of this memo-form grid has its own corner, cell or counts ({grid.corner[a].tolist()}, "
                f"{grid.cell[a].tolist()}, {grid.counts[a].tolist()})"
            )
    return n, h


def dilation_table(h, probe_radius) -> np.ndarray:
    """The probe's voxel offsets, as a table: ``table[|dy|, |dz|]`` = the largest |dx| of the set, or -1.

    Offset (i, j, k) belongs to the set when, in float64 and in exactly this order,
    ``((i hx)^2 + (j hy)^2) + (k hz)^2 <= rho^2 (1 + 1e-9)``, each square as ``t * t`` of ``t = n * h`` (the slack
    keeps ties in, in any unit of length). Float64 rounding is
    monotone, so the set is closed toward zero on every axis and the table describes it whole. The kernels and
    the reference both use this table: the dilation radius is decided once, on the host, with no float32 step.

    Args:
        h: Voxel edge per axis [m], 3 values.
        probe_radius: rho [m], >= 0.

    Returns:
        int64 array, shape (wy + 1, wz + 1), wy and wz the half-widths along y and z.
    """
    hx, hy, hz = (float(x) for x in h)
    # Ties (an offset exactly rho away, as when rho is a whole number of voxels) are in: the relative slack makes
    # that so whatever the rounding of h and rho, which depends on the unit of length (rho = 2 h in metres and in
    # millimetres must give one table).
    rho2 = float(probe_radius) * float(probe_radius) * (1.0 + 1e-9)

    def inside(i, j, k):
        return ((i * hx) * (i * hx) + (j * hy) * (j * hy)) + (k * hz) * (k * hz) <= rho2

    def half_width(step):
        n = 0
        while inside(*(s * (n + 1) for s in step)):
            n += 1
        return n

    wy = half_width((0, 1, 0))
    wz = half_width((0, 0, 1))
    wx = half_width((1, 0, 0))
    table = np.full((wy + 1, wz + 1), -1, dtype=np.int64)
    for j in range(wy + 1):
        for k in range(wz + 1):
            i = -1
            while i < wx and inside(i + 1, j, k):
                i += 1
            table[j, k] = i
    return table


def voxel_diagonal(h) -> float:
    """The voxel diagonal ``sqrt(hx^2 + hy^2 + hz^2)`` [m] (float64, in this order)."""
    hx, hy, hz = (float(x) for x in h)
    return float(np.sqrt((hx * hx + hy * hy) + hz * hz))


def band_radius(h, probe_radius) -> float:
    """Radius of the uncertain band [m]: ``(rho + diagonal) (1 + 1e-9)``. A voxel centre x is fluid through a probe
    centre z within rho of it, reachable from a corner of the voxel-centre cube that holds z (within one diagonal of
    z), so every fluid voxel lies within rho + diagonal of a reached one; the factor covers float64 rounding."""
    return (float(probe_radius) + voxel_diagonal(h)) * (1.0 + 1e-9)


def attribution_bound(h, probe_radius) -> np.ndarray:
    """Largest possible distance ``|p - c| - r`` from a crossing point on lamp axis a to its nearest sphere, per
    axis: ``B_a = rho + sqrt((rho + h_a/2 + g)^2 + (h_a/2)^2)`` [m], g the voxel diagonal (at most ``2 rho + h_a +
    g``), shape (3,).

    Proof. Let a crossing join fluid voxel x_f and dry voxel x_d along axis a, p the face between them
    (``|x_d - p| = h_a / 2``). Fluid means a reached point y (a voxel centre, or a lattice point outside the box)
    within rho + g of x_f: either within rho (the dilation), or a probe centre z within rho of x_f is reachable from
    a corner y of the voxel-centre cube holding z (``|y - z| <= g``). So ``|y - p| <= rho + g + h_a/2``. Suppose
    every sphere has ``|p - c_i| - r_i > B_a``. A staircase lattice path from y to x_d stays in the axis-aligned box
    spanned by y and x_d; each of its points w has, per coordinate, ``|w - p|`` at most the larger of y's and
    x_d's, so ``|w - p|^2 <= |y - p|^2 + |x_d - p|^2 <= (B_a - rho)^2``. Then ``|w - c_i| > r_i + rho`` for every
    sphere: every voxel on the path is allowed, so x_d is reached, hence fluid: a contradiction. The virtual fluid
    beyond the row ends is the case y = x_f. The kernels add a relative margin of 1e-9 for float64 rounding.
    Crossings of thin chords go to the chord's sphere and need no search.

    Args:
        h: Voxel edge per axis [m], 3 values.
        probe_radius: rho [m].
    """
    g = voxel_diagonal(h)
    rho = float(probe_radius)
    half = 0.5 * np.asarray(h, dtype=np.float64)
    return rho + np.hypot(rho + half + g, half)


def unpack_bits(words: np.ndarray, shape) -> np.ndarray:
    """A bitmap of 32-bit x-row words (row-major z, y, word) as a bool array indexed [x, y, z]."""
    nx, ny, nz = (int(s) for s in shape)
    nwx = (nx + 31) // 32
    w = np.ascontiguousarray(words[: nwx * ny * nz], dtype=np.uint32).reshape(nz, ny, nwx)
    bits = np.unpackbits(w.view(np.uint8), axis=-1, bitorder="little").reshape(nz, ny, nwx * 32)[..., :nx]
    return np.ascontiguousarray(bits.astype(bool).transpose(2, 1, 0))


def _layout(grid: LampGrid, rho: float) -> dict:
    n, h = voxel_box(grid)
    nwx = int((n[0] + 31) // 32)
    n_words = nwx * int(n[1]) * int(n[2])
    if n_words >= 2**31 // 8 or int(n.prod()) >= 2**31 - 1:
        size = n * h
        if 2.0 * rho >= 0.5 * float(size.min()):
            # The probe's margin is most of the grid: the probe radius is what to change, not the cells.
            raise ValueError(
                f"probe_radius: {rho:.6g} takes a margin of {rho:.6g} on every side, half the grid or more, and "
                f"makes {int(n.prod()):,} voxels, too many for the wetted-surface mode (int32 indices): take a "
                "smaller probe_radius (a quarter to two mean particle radii) or larger cells"
            )
        raise ValueError(f"grid: {int(n.prod()):,} voxels are too many for the wetted-surface mode (int32 indices)")
    table = dilation_table(h, rho)
    table_band = dilation_table(h, band_radius(h, rho))
    size = n * h
    bound = attribution_bound(h, rho)
    # float64 rounding of the allowed test and of the distances is far below this margin.
    bound_search = bound + 1e-9 * (bound + float(np.linalg.norm(size)))
    edge = max(float(bound.max()), 2.0 * float(h.max()))
    bins = np.maximum(np.ceil(size / edge), 1).astype(np.int64)
    while int(bins.prod()) > MAX_BINS:
        edge *= 1.25
        bins = np.maximum(np.ceil(size / edge), 1).astype(np.int64)
    # The two dilations share the planes; the band's table is the wider.
    planes = max(table.shape[1], table_band.shape[1])
    # Wall runs along x are walked exactly this far past the box: beyond every index a kernel asks about (a word's
    # padding, a dilation's reach, a candidate's cube corner).
    pad = int(max(table_band.max(), table_band.shape[0], table_band.shape[1])) + 64
    small = 4 * (table.size + table_band.size) + 4 * (KB.N_DIAG + 4)  # offset tables, diagnostics, r_max, flags
    # Segments of about sqrt(n) rows: summary, carry and apply threads then each walk ~2 sqrt(n) words.
    seg = [0] + [max(4, round(float(np.sqrt(float(n[a]))))) for a in (1, 2)]
    n_seg = [0] + [-(-int(n[a]) // seg[a]) for a in (1, 2)]
    columns = [0, nwx * int(n[2]), nwx * int(n[1])]
    scan = max(columns[1] * n_seg[1], columns[2] * n_seg[2])
    nbytes = 4 * n_words * (5 + planes) + 4 * int(bins.prod()) + 4 * grid.n_cells + 3 * 4 * scan + small
    faces = [int(grid.counts[a].prod()) * (int(n[a]) + 1) for a in range(3)]
    return dict(
        n=n,
        h=h,
        nwx=nwx,
        n_words=n_words,
        table=table,
        table_band=table_band,
        planes=planes,
        bound=bound_search,
        edge=edge,
        bins=bins,
        nbytes=nbytes,
        faces=faces,
        seg=seg,
        n_seg=n_seg,
        columns=columns,
        scan=scan,
        pad=pad,
    )


def wetted_nbytes(
    grid: LampGrid, probe_radius: float, *, keep_owners: bool = False, n_walls: int = 0, device=None, skin=None
) -> int:
    """Device bytes of the mode's grid-sized buffers [bytes], known before allocation: five bitmaps (blocked,
    solid, reached, fluid, band) and one per |dz| of the band's offsets (one bit per voxel each), three words per
    segment (about sqrt(n) rows) of the column scans, the search bins and the per-ray crossing counts, a few
    scalars; with ``keep_owners``, two int32 per voxel face of the three axes (the crossing's sphere, the thin
    chords there); :data:`BYTES_PER_WALL` per wall; on a CUDA ``device``, the exact test's queue (one int32 per
    :data:`EXACT_QUEUE_PER` voxels, three words per bitmap word that place its tests in voxel order, and a row of
    gathered spheres per queued thread, :func:`queued_threads`) and the crossing list (two int32 per
    :data:`CROSS_LIST_PER` voxel faces, :func:`cross_list_capacity`); with a ``skin`` (:func:`skin_distance`), one
    more bitmap, its state and the witness and crossing-owner tables (:func:`witness_capacity` slots each, 28 bytes
    a slot together).
    Particles add :data:`BYTES_PER_PARTICLE` each (on CUDA :data:`CUDA_BYTES_PER_PARTICLE` more, and
    :data:`SKIN_BYTES_PER_PARTICLE` with the skin)."""
    rho = check_probe_radius(probe_radius)
    lay = _layout(grid, rho)
    on = skin_distance(skin, lay["h"], rho) > 0.0
    return _nbytes(lay, keep_owners, int(n_walls), wp.get_device(device), on)


def _nbytes(lay: dict, keep_owners: bool, n_walls: int, device, skin: bool = False) -> int:
    """:func:`wetted_nbytes` of a layout: what the surface allocates for its grid-sized buffers."""
    # The exact-test queue, its count and the slots taken, its order (each word's uncertain bits, their count and
    # its prefix sum), the crossing list, and three int32 counters (crossings and thin chords listed, thin chords
    # left over).
    cap = exact_queue_capacity(lay["n"], device)
    queue = 4 * (cap + 2) + (12 * lay["n_words"] if cap > 0 else 0)
    queue += 4 * KB.GATHER * queued_threads(cap, device)
    queue += 8 * cross_list_capacity(lay["faces"], device) + 12
    # Per table slot: a witness's key, (i, j, k, t) and margin (``WitMargin``), and a crossing's key and owner.
    slot = 4 + 16 + ctypes.sizeof(KB.WitMargin.ctype) + 8
    kept = 4 * (2 * lay["n_words"] + KB.N_SKIN) + slot * witness_capacity(lay["n"]) if skin else 0
    return lay["nbytes"] + (8 * sum(lay["faces"]) if keep_owners else 0) + BYTES_PER_WALL * n_walls + queue + kept


def skin_distance(skin, h, probe_radius) -> float:
    """The skin's distance [m] from the ``skin`` argument: None or False: off (0.0); ``"auto"`` or True:
    :data:`SKIN_CELLS` voxel edges, at most half the probe radius (off when rho = 0); a number: that distance, in
    (0, min(h) / 4] and at most rho. ValueError naming ``skin`` otherwise."""
    rho = float(probe_radius)
    hmin = float(np.min(np.asarray(h, dtype=np.float64)))
    if skin is None or skin is False:
        return 0.0
    if skin is True or skin == "auto":
        return min(SKIN_CELLS * hmin, 0.5 * rho) if rho > 0.0 else 0.0
    try:
        d = float(skin)
    except (TypeError, ValueError):
        raise ValueError(f"skin: expected None, 'auto' or a distance [m], got {skin!r}") from None
    if not (np.isfinite(d) and 0.0 < d <= 0.25 * hmin and d <= rho):
        raise ValueError(
            f"skin: a distance in (0, {min(0.25 * hmin, rho):.6g}] m (a quarter voxel edge and at most the probe "
            f"radius), got {skin!r}"
        )
    return d


def witness_capacity(shape) -> int:
    """Slots of the skin's witness table for a box of ``shape`` voxels: the power of two at or above one voxel in
    :data:`EXACT_QUEUE_PER`, at least :data:`WITNESS_MIN`; 76 bytes each: key, witness and margin (the crossings'
    owner table has as many slots, 8 bytes each). (The specimen's 7,500 wet tests in 0.8 M
    voxels take a ninth of its 65,536; the table is wiped when three quarters are taken.)"""
    n_vox = int(np.prod(np.asarray(shape, dtype=np.int64)))
    return 1 << int(np.ceil(np.log2(max(WITNESS_MIN, n_vox // EXACT_QUEUE_PER))))


def _packed_capacity(total: int, per: int, least: int, device, *, capped: bool = True) -> int:
    """Slots of a CUDA work list over ``total`` items: one per ``per``, at least ``least``, at most ``total`` when
    ``capped`` (an item takes one slot); none on the CPU, where one thread runs a launch and packing the work gains
    nothing (``device`` None: CUDA's rule)."""
    if device is not None and not device.is_cuda:
        return 0
    slots = max(least, int(total) // per)
    return min(int(total), slots) if capped else slots


def exact_queue_capacity(shape, device) -> int:
    """Voxels the exact test's queue holds on ``device`` for a box of ``shape`` voxels: one in
    :data:`EXACT_QUEUE_PER`, at least :data:`EXACT_QUEUE_MIN`, on CUDA; none on the CPU; ``device`` None: CUDA's
    rule."""
    n_vox = int(np.prod(np.asarray(shape, dtype=np.int64)))
    return _packed_capacity(n_vox, EXACT_QUEUE_PER, EXACT_QUEUE_MIN, device)


def queued_threads(capacity: int, device) -> int:
    """Threads that run a queue of ``capacity`` exact tests on ``device``: :data:`QUEUED_THREADS_PER_SM` per SM on
    CUDA, at most ``capacity``; one on the CPU (a launch runs on one thread there)."""
    if int(capacity) <= 0:
        return 0
    if not device.is_cuda:
        return 1
    return min(int(capacity), QUEUED_THREADS_PER_SM * int(device.sm_count))


def cross_list_capacity(faces, device) -> int:
    """Crossings the crossing list holds on ``device`` for voxel faces ``faces`` (per axis): one per
    :data:`CROSS_LIST_PER` faces, at least :data:`CROSS_LIST_MIN`, on CUDA; none on the CPU; ``device`` None:
    CUDA's rule."""
    return _packed_capacity(sum(int(f) for f in faces), CROSS_LIST_PER, CROSS_LIST_MIN, device)


def thin_list_capacity(n: int, device) -> int:
    """Thin chords the list holds on ``device`` for ``n`` particles: one per :data:`THIN_LIST_PER` (sphere, axis)
    pairs, at least :data:`THIN_LIST_MIN` (a sphere-axis may hold several), on CUDA; none on the CPU; ``device``
    None: CUDA's rule."""
    return _packed_capacity(3 * int(n), THIN_LIST_PER, THIN_LIST_MIN, device, capped=False)


@dataclass
class WettedDiagnostics:
    """What the last update found; built on demand from device arrays, outside the hot path.

    Attributes:
        counts: Signed crossing counts per particle and axis, shape (N, 3), int64.
        hits: Crossings attributed to each particle, both lamps and all axes, shape (N,), int64.
        surface: Particles that took at least one crossing, shape (N,), bool.
        fluid: Wetted voxels, shape (nx, ny, nz), bool (indexed [x, y, z], centres at lower + (index + 1/2) h).
        allowed: Voxels where the probe centre may stand, shape (nx, ny, nz), bool.
        reachable: Allowed voxels the connectivity solve joined to the outside, shape (nx, ny, nz), bool.
        band: Voxels within :func:`band_radius` of a reached one (the only ones that can be fluid), shape
            (nx, ny, nz), bool.
        crossings: Per lamp grid a (0, 1, 2), fluid-to-dry crossings on each ray, shape (n_u, n_v) like the lamp's
            owner maps (the dry-to-fluid crossings are as many).
        loaded: Per lamp name, crossings it loaded (0 for a lamp that is off).
        invalid: Particles skipped as invalid (non-finite position or radius, radius <= 0).
        outside: Particles whose sphere pokes out of the box.
        tight: Particles whose sphere inflated by rho reaches past the first layer of voxel centres outside the
            box, which the mode takes as allowed and reachable: the box is too tight for the probe there, and
            the fluid there may differ from that of a larger box (give the box a margin of rho + one cell).
        unattributed: Crossings with no sphere found (never expected; each breaks the balance by one count).
        uncertain: Voxels of the band that the dilation by rho left dry and the exact test decided.
        rescued: Of those, the ones it found fluid.
        thin: Thin dry intervals loaded (merged sphere chords between two fluid samples that hold no voxel
            centre); each is one crossing of each direction on its ray.
        gap_tests: Exact tests of the gaps between thin chords (work done, counted by every thread that made one).
        rounds: Connectivity rounds of the last update.
        nonconverged: Whether the last connectivity solve stopped at ``max_rounds`` (reachable is then too small).
        nonconverged_total: Connectivity solves cut short since construction.
        wall_counts: Signed counts per wall and axis, shape (W, 3), int64, as ``counts`` (the crossings each wall
            took: the fluid's push on it); (0, 3) without walls.
        skin_kept: With the skin, voxels of ``uncertain`` kept dry from an earlier update without a test (0 without).
        skin_certified: With the skin, voxels tested dry in this update that got a certificate to be kept.
        skin_reset: With the skin, whether this update took a new reference (every kept decision dropped).
        skin_resets: With the skin, references taken since construction (the first update takes one).
        skin_witnessed: With the skin, voxels of ``rescued`` kept wet by re-checking the one candidate an earlier
            update found them wet by (the others were tested).
        skin_held: With the skin, voxels of ``skin_witnessed`` kept by their witness's margin alone, without a search
            (the candidate recomputed, its clearance from every other ball measured when it was found).
        skin_cross_kept: With the skin, crossings whose owner was kept without a search (none with walls).
        crossings_listed: Crossings loaded through the crossing list (CUDA), one thread each; the rest were loaded
            where they were found (all of them on the CPU, or past the list's capacity).
        thin_listed: Thin chords with fluid on both sides walked through the thin list (CUDA), one thread each.
        owners: With ``keep_owners``, per lamp grid a, the sphere each crossing went to, shape (n_u, n_v, n_a + 1)
            indexed by the ray's cell and the face (between voxels face-1 and face along a): -2 where no crossing
            was loaded, -1 where none was found, -3 where a wall took it; else None.
        wall_owners: With ``keep_owners``, per lamp grid a, the wall that took each face's crossing (-1: none),
            shaped as ``owners``; else None.
        thin_faces: With ``keep_owners``, per lamp grid a, the thin dry intervals between the samples on either
            side of each face, shape (n_u, n_v, n_a + 1); else None.
        force: Resultant force on the particles [N], shape (3,), when a pressure was given.
        wall_forces: Force on each wall [N], shape (W, 3), when a pressure was given (world coordinates when the
            lamp gives it, ``ShiningLamp.diagnostics``; else the frame's).
    """

    counts: np.ndarray
    hits: np.ndarray
    surface: np.ndarray
    fluid: np.ndarray
    allowed: np.ndarray
    reachable: np.ndarray
    band: np.ndarray
    crossings: dict
    loaded: dict
    invalid: int
    outside: int
    tight: int
    unattributed: int
    uncertain: int
    rescued: int
    thin: int
    gap_tests: int
    rounds: int
    nonconverged: bool
    nonconverged_total: int
    wall_counts: np.ndarray | None = None
    skin_kept: int = 0
    skin_certified: int = 0
    skin_reset: bool = False
    skin_resets: int = 0
    skin_witnessed: int = 0
    skin_held: int = 0
    skin_cross_kept: int = 0
    crossings_listed: int = 0
    thin_listed: int = 0
    owners: dict | None = None
    wall_owners: dict | None = None
    thin_faces: dict | None = None
    force: np.ndarray | None = None
    wall_forces: np.ndarray | None = None


class WettedSurface:
    """The wetted-surface mode on the device: every crossing of the probe-closed fluid boundary is loaded.

    ``update`` writes signed crossing counts per particle into :attr:`counts` (3 int32 per particle, laid out like
    ``ShiningLamp.counts``); the force on particle i along axis a is ``P_a A_a counts[3 i + a]``. Nothing in
    ``update`` allocates (after :meth:`reserve` or a first update at that particle count) or reads device data on
    the host, so it can be recorded with ``wp.ScopedCapture``; the connectivity solve is a ``wp.capture_while``
    loop (one host read of its flag per round when run eagerly on CUDA, none in a graph). Invalid particles are
    skipped and counted, never raised.

    Accuracy: fluid and dry are decided exactly at every voxel centre, and chords shorter than a cell are loaded,
    so a lone sphere (or spheres the probe can go around) takes exactly the cells criterion 1 gives it, for every
    rho; the loads converge like criterion 1's as the cells shrink. The topology (which pores the probe reaches)
    is the voxel connectivity's: near a packing's window size it still moves with the cells.

    Choosing ``probe_radius`` (rho): the probe cannot pass a pore window narrower than itself, and the fluid's
    boundary bridges gaps between surface particles narrower than about 2 rho. Dense packings keep it out of their
    pores from rho of about a quarter to a third of the mean diameter (measured: a jittered cubic lattice is
    sealed from 0.33 d, the random SphereTest packing has no wetted particle deeper than a diameter from 0.3 d).
    For a membrane that follows the surface particles, take that up to one mean radius (the slot block's walls and
    floor then get 0.94 and 0.96-0.97 of P A, the same at 4, 6 and 8 cells per diameter). For mud, which fills a
    trough several diameters wide but not the pores, one to two mean radii: a larger probe rounds concave corners
    to radius rho, and as rho grows the loaded surface becomes the convex hull. rho -> 0 lets the fluid into every
    connected pore. Give the box a margin of rho plus a cell beyond the particles (``diagnostics().tight`` counts
    those closer).
    """

    def __init__(
        self,
        grid: LampGrid,
        *,
        probe_radius: float,
        lamps="all",
        max_rounds: int = DEFAULT_MAX_ROUNDS,
        keep_owners: bool = False,
        device=None,
        max_bytes: int = DEFAULT_MAX_BYTES,
        walls=None,
        skin=None,
    ):
        """Allocate the voxel bitmaps of ``grid`` on ``device``.

        Args:
            grid: Box-form lamp grid; the voxels are its cells (see :func:`voxel_box`). Its box should reach
                rho + one cell past every particle, so that the probe can come in from outside on every side;
                particles closer to its faces are counted in ``diagnostics().tight``.
            probe_radius: rho [m], >= 0.
            lamps: "all", or names from :data:`warp_lamp.LAMPS`; a lamp that is off loads none of its crossings.
            max_rounds: Bound on connectivity rounds (each one sweep along x, y and z); a solve that needs more stops
                there, is counted in :meth:`diagnostics`, and under-fills the fluid (balance still holds).
            keep_owners: Also record the sphere each crossing went to, per voxel face (4 bytes per voxel and
                axis; for tests and pictures, :attr:`WettedDiagnostics.owners`).
            device: Warp device; the current default when None.
            max_bytes: Budget for the voxel buffers [bytes] (:func:`wetted_nbytes`); over it, ValueError before
                anything is allocated.
            walls: Walls that bound the fluid, ``[(point, normal), ...]`` in world coordinates [m], the normal
                pointing from the wall into the fluid (:func:`~warp_lamp.validate.check_walls`; or its planes, shape
                (W, 4)). The probe keeps rho from every wall, the fluid beyond the box is only on the fluid side of
                every wall, and a crossing goes to a wall when the wall is nearer than every sphere
                (:attr:`wall_counts`). Placed in the frame once, in float64 (positions are frame coordinates);
                :meth:`update` may take the walls placed elsewhere (``ShiningLamp`` places them on the device).
            skin: Keep decisions between updates (:func:`skin_distance`: None off, ``"auto"``, or a distance
                [m]). A voxel the exact test finds dry gets, where it can, a certificate that it stays dry while no
                sphere moves the skin distance; later updates keep it untested until a particle has moved half the
                skin from the reference (or changed its radius or activity, or the particle count changed), when
                every kept dry decision is dropped and a new reference taken. A voxel found wet keeps the candidate
                that made it wet and how far every other sphere kept from it; under the same reference it stays wet
                by that margin alone while the margin exceeds the candidate's move plus the skin, else the candidate
                is re-checked before the voxel is tested. Without walls, a crossing whose nearest sphere leads the
                runner-up by more than twice the skin keeps it as its owner until the next reference. A new
                reference right after another (particles outrunning the skin every update) keeps and measures
                nothing. Results are bitwise those without it; it pays in a run of small moves (two more bitmaps,
                witness and owner tables of :func:`witness_capacity` slots, :data:`SKIN_BYTES_PER_PARTICLE` per
                particle).
        """
        self.probe_radius = check_probe_radius(probe_radius)
        if isinstance(walls, np.ndarray) and walls.ndim == 2 and walls.shape[1] == 4:
            planes = np.asarray(walls, dtype=np.float64)
        else:
            planes = check_walls(walls)
        if isinstance(max_rounds, bool) or not isinstance(max_rounds, (int, np.integer)) or max_rounds < 1:
            raise ValueError(f"max_rounds: expected an int >= 1, got {max_rounds!r}")
        self.grid = grid
        self.lamp_mask = lamp_mask(lamps)
        self.max_rounds = int(max_rounds)
        self.device = wp.get_device(device)
        lay = _layout(grid, self.probe_radius)
        #: The skin's distance [m]; 0.0: off.
        self.skin = skin_distance(skin, lay["h"], self.probe_radius)
        #: Walls that bound the fluid.
        self.n_walls = len(planes)
        self.nbytes = _nbytes(lay, keep_owners, self.n_walls, self.device, self.skin > 0.0)
        self._faces = lay["faces"]
        self._seg = lay["seg"]
        self._n_seg = lay["n_seg"]
        nwx, ny, nz = lay["nwx"], int(lay["n"][1]), int(lay["n"][2])
        self._face_words = [ny * nz * (nwx + 1), nwx * (ny + 1) * nz, nwx * ny * (nz + 1)]
        self._slices = None  # threads per sphere in rasterize; None: chosen per update from N
        total = sum(self._face_words)
        # Bits per crossing and per exact-test thread. On CUDA, one nearest-sphere search (or exact test) per thread
        # while that stays under ~8M threads (latency rules small grids); large grids, whose crossings are spread
        # over millions of threads anyway, take more bits per thread. The CPU runs a launch on one thread: a word
        # per thread there.
        self._bits = 32
        if self.device.is_cuda:
            self._bits = 32 // int(min(32, max(1, 2 ** int(np.log2(max(1, (1 << 23) // total))))))
        self._columns = lay["columns"]
        check_budget(
            self.nbytes,
            max_bytes,
            f"grid: the wetted-surface buffers need {self.nbytes:,} bytes",
            "raise max_bytes, use larger cells or a smaller probe_radius",
        )
        self.shape = tuple(int(x) for x in lay["n"])
        self.h = lay["h"]
        self.table = lay["table"]
        self.table_band = lay["table_band"]
        box = KB.WetBox()
        box.n = wp.vec3i(*self.shape)
        box.nwx = lay["nwx"]
        box.n_words = lay["n_words"]
        box.h = wp.vec3d(*self.h)
        box.rho = self.probe_radius
        box.diag = voxel_diagonal(self.h)
        box.near_list = KB.NEAR_LIST
        box.prune_from = KB.PRUNE_FROM
        box.mask_from = KB.MASK_FROM
        box.gather = KB.GATHER
        box.skip = 0
        box.bound = wp.vec3d(*lay["bound"])
        box.bin_n = wp.vec3i(*(int(x) for x in lay["bins"]))
        box.bin_edge = lay["edge"]
        box.lamp_mask = self.lamp_mask
        box.offset = wp.vec3i(*(int(x) for x in grid.offsets))
        box.face_offset = wp.vec3i(0, self._faces[0], self._faces[0] + self._faces[1])
        box.pad = lay["pad"]
        self._box = box
        d = self.device
        # The walls in the frame, in float64 with the grid's own pose, as ShiningLamp places them for positions
        # already in the frame (``LampFrame``): n_f = R^T n, d_f = d - n . o.
        n_frame = planes[:, :3] @ grid.rotation
        d_frame = planes[:, 3] - planes[:, :3] @ grid.world_origin
        static = np.concatenate([n_frame, d_frame[:, None]], axis=1).astype(np.float32).reshape(-1, 4)
        #: The walls' planes in the frame, one ``vec4`` (n, d) each, fluid where n . x > d.
        self.walls_frame = wp.array(static, dtype=wp.vec4, device=d)
        self.walls_view = LampWalls()
        self.walls_view.frame = self.walls_frame
        self.walls_view.n = self.n_walls
        self.walls_view.gap = wp.empty(0, dtype=wp.float32, device=d)  # the memo's mode's contact; unread here
        self.walls_view.rest = 0.0
        #: Signed counts per wall and axis of the last update (3 int64 per wall), laid out like :attr:`counts`.
        self.wall_counts = wp.zeros(3 * self.n_walls, dtype=wp.int64, device=d)
        nw = lay["n_words"]
        self.blocked = wp.zeros(nw, dtype=wp.uint32, device=d)
        self.reach = wp.zeros(nw, dtype=wp.uint32, device=d)
        self.fluid = wp.zeros(nw, dtype=wp.uint32, device=d)
        self.band = wp.zeros(nw, dtype=wp.uint32, device=d)
        self.solid = wp.zeros(nw, dtype=wp.uint32, device=d)
        self.seg_pass = wp.zeros(lay["scan"], dtype=wp.uint32, device=d)
        self.seg_up = wp.zeros(lay["scan"], dtype=wp.uint32, device=d)
        self.seg_down = wp.zeros(lay["scan"], dtype=wp.uint32, device=d)
        self.planes = wp.zeros(nw * lay["planes"], dtype=wp.uint32, device=d)
        self.heads = wp.full(int(lay["bins"].prod()), -1, dtype=wp.int32, device=d)
        self.rays = wp.zeros(grid.n_cells, dtype=wp.int32, device=d)
        self.owners = wp.full(sum(self._faces) if keep_owners else 0, -2, dtype=wp.int32, device=d)
        self.thin_faces = wp.zeros(sum(self._faces) if keep_owners else 0, dtype=wp.int32, device=d)
        self._table = wp.array(self.table.ravel().astype(np.int32), dtype=wp.int32, device=d)
        self._table_band = wp.array(self.table_band.ravel().astype(np.int32), dtype=wp.int32, device=d)
        self.diag = wp.zeros(KB.N_DIAG, dtype=wp.int32, device=d)
        # The exact test's queue (CUDA): the band's undecided voxels packed for as many threads as fit the GPU at
        # once (queued_threads), up to one voxel in EXACT_QUEUE_PER of the box (at least EXACT_QUEUE_MIN); past it
        # the classify thread tests the voxel itself, as every thread does on the CPU, where a launch runs on one
        # thread and packing gains nothing.
        self._ordered = True
        self._exact_queue(exact_queue_capacity(lay["n"], d))
        # The crossing list (CUDA): the crossings found by the face-word threads, loaded by a thread each.
        self._cross_list(cross_list_capacity(self._faces, d))
        # The thin chords' list (CUDA), sized with the particles (``reserve``); None: thin_list_capacity's rule.
        self._thin_capacity = None
        self.thin_list = wp.zeros(0, dtype=wp.vec4i, device=d)
        self.thin_listed = wp.zeros(1, dtype=wp.int32, device=d)
        # Per sphere-axis, 1 + the first of its chords the list could not hold (0: none), and whether any.
        self.thin_from = wp.zeros(0, dtype=wp.int32, device=d)
        self.thin_over = wp.zeros(1, dtype=wp.int32, device=d)
        self.rmax = wp.zeros(1, dtype=wp.float32, device=d)
        self.cond = wp.zeros(1, dtype=wp.int32, device=d)
        self.frontier = wp.zeros(1, dtype=wp.int32, device=d)
        self.nonconverged_total = wp.zeros(1, dtype=wp.int32, device=d)
        self.counts = wp.zeros(0, dtype=wp.int64, device=d)
        self.hits = wp.zeros(0, dtype=wp.int32, device=d)
        self.next_in_bin = wp.zeros(0, dtype=wp.int32, device=d)
        self.exposed = wp.zeros(0, dtype=wp.int32, device=d)
        self._no_active = wp.empty(0, dtype=wp.int32, device=d)
        # The skin: certified dry voxels, its state (kernels/wetted_base.py SKIN_*) and the reference particles.
        self.kept = wp.zeros(nw if self.skin else 0, dtype=wp.uint32, device=d)
        # Dry voxels whose certificate failed under this reference: not tried again until the next one (on a GPU
        # a failed attempt costs about a test, and at rest it fails again).
        self._tried = wp.zeros(nw if self.skin else 0, dtype=wp.uint32, device=d)
        self._skin_state = wp.zeros(KB.N_SKIN if self.skin else 0, dtype=wp.int32, device=d)
        cap = witness_capacity(self.shape) if self.skin else 0
        self._wit_keys = wp.full(cap, -1, dtype=wp.int32, device=d)
        self._wits = wp.zeros(cap, dtype=wp.vec4i, device=d)
        self._wit_margins = wp.zeros(cap, dtype=KB.WitMargin, device=d)
        # Kept crossing owners by face (int32 key, int32 owner), as many slots as witnesses.
        self._cross_keys = wp.full(cap, -1, dtype=wp.int32, device=d)
        self._cross_owners = wp.zeros(cap, dtype=wp.int32, device=d)
        self._ref_pos = wp.zeros(0, dtype=wp.vec3, device=d)
        self._ref_rad = wp.zeros(0, dtype=wp.float32, device=d)
        self._ref_act = wp.zeros(0, dtype=wp.int32, device=d)
        self.n = 0

    def forget(self) -> None:
        """Drop every decision the skin keeps (the next update takes a new reference and runs as from scratch), for
        benchmarks that time cold updates at fixed positions; results are the same. Without the skin: nothing."""
        if self.skin:
            # Unprimed: the next update takes a new reference and wipes the witness table (the reference count,
            # which dates the margins, goes on).
            state = self._skin_state.numpy()
            state[KB.SKIN_PRIMED] = 0
            self._skin_state.assign(state)

    def _exact_queue(self, capacity: int, threads: int | None = None) -> None:
        """Queue up to ``capacity`` exact tests (0: none) for ``threads`` threads (None: :func:`queued_threads`'s
        rule); the tests and the benchmark's A/B set them on either device. The answer is the same."""
        self._capacity = int(capacity)
        self.queue = wp.zeros(self._capacity, dtype=wp.int32, device=self.device)
        # The queue's count, then how many of its slots past the threads' first the queued tests have taken.
        self.queued = wp.zeros(2, dtype=wp.int32, device=self.device)
        # The queued tests' gathered spheres: a row per thread, so that their checks read it with no copy.
        rows = queued_threads(self._capacity, self.device) if threads is None else min(int(threads), self._capacity)
        self._gathered = wp.zeros(KB.GATHER * rows, dtype=wp.int32, device=self.device)
        self._queue_in_order(self._ordered)

    def _queue_in_order(self, ordered: bool) -> None:
        """Queue the exact tests in voxel order (a prefix sum of each word's count; the default) or in the order
        the first pass's atomics take them (a benchmark's A/B); the answer is the same."""
        self._ordered = bool(ordered)
        nw = self._box.n_words if self._capacity > 0 and self._ordered else 0
        self._uncertain = wp.zeros(nw, dtype=wp.uint32, device=self.device)
        self._unc_counts = wp.zeros(nw, dtype=wp.int32, device=self.device)
        self._unc_offsets = wp.zeros(nw, dtype=wp.int32, device=self.device)

    def _cross_list(self, capacity: int) -> None:
        """List up to ``capacity`` crossings for a loading thread each (0: none, every crossing loaded where it is
        found; the tests set it on either device); the answer is the same."""
        self._list_capacity = int(capacity)
        self.cross_list = wp.zeros(self._list_capacity, dtype=wp.vec2i, device=self.device)
        self.cross_listed = wp.zeros(1, dtype=wp.int32, device=self.device)

    def _thin_list(self, capacity: int | None) -> None:
        """List up to ``capacity`` thin chords for a walking thread each (0: none; None: the device's rule for the
        reserved particles; the tests set it on either device); the answer is the same."""
        self._thin_capacity = capacity
        self._thin_buffers(self.hits.shape[0])

    def _thin_buffers(self, n: int) -> None:
        cap = thin_list_capacity(n, self.device) if self._thin_capacity is None else int(self._thin_capacity)
        self.thin_list = wp.zeros(cap, dtype=wp.vec4i, device=self.device)
        self.thin_from = wp.zeros(3 * n if cap > 0 else 0, dtype=wp.int32, device=self.device)

    def _auto_slices(self, n: int) -> int:
        if not self.device.is_cuda:
            return 1
        return int(min(8, max(1, 2 ** int(np.log2(max(1, (1 << 16) // max(n, 1)))))))

    def reserve(self, n: int) -> None:
        """Make room for ``n`` particles now, so that a later captured update need not allocate."""
        if n > self.hits.shape[0]:
            if self.device.is_cuda and self.device.is_capturing:
                raise RuntimeError(
                    f"positions: {n} particles exceed the {self.hits.shape[0]} reserved; call "
                    "WettedSurface.reserve(n) or one eager update before wp.ScopedCapture"
                )
            self.counts = wp.zeros(3 * n, dtype=wp.int64, device=self.device)
            self.hits = wp.zeros(n, dtype=wp.int32, device=self.device)
            self.next_in_bin = wp.zeros(n, dtype=wp.int32, device=self.device)
            self.exposed = wp.zeros(n, dtype=wp.int32, device=self.device)
            self._thin_buffers(n)
            if self.skin:
                self._ref_pos = wp.zeros(n, dtype=wp.vec3, device=self.device)
                self._ref_rad = wp.zeros(n, dtype=wp.float32, device=self.device)
                self._ref_act = wp.zeros(n, dtype=wp.int32, device=self.device)
                # Zeroed reference arrays: every active particle differs from them (activity 0), so the next update
                # takes a new reference.

    def _check_array(self, name, arr, dtype, n=None):
        check_warp_array(name, arr, dtype, self.device, "the wetted surface", n)

    def update(
        self, positions: wp.array, radii: wp.array, active: wp.array | None = None, *, walls: LampWalls | None = None
    ) -> None:
        """Recompute the fluid region, its crossings, and each particle's signed crossing counts.

        Args:
            positions: Particle centres in frame coordinates (minus ``grid.origin``) [m], warp array of vec3
                (float32), shape (N,), on the surface's device.
            radii: Particle radii [m], warp array of float32, shape (N,).
            active: Optional warp array of int32, shape (N,): 0 makes a particle absent (no solid, no force).
            walls: The same walls placed in the frame elsewhere, as the kernels read them (``LampFrame.walls_view``:
                planes on the device that a simulator may move between replays); None: those given at
                construction.
        """
        self._update(positions, radii, active, walls=walls)

    #: Stages of an update, in order; ``_update(..., stop=s)`` runs the stages up to and including s (benchmarks).
    STAGES = ("rasterize", "connect", "dilate", "classify", "cross", "thin")

    def _update(self, positions, radii, active, stop: str = "thin", walls: LampWalls | None = None) -> None:
        last = self.STAGES.index(stop)
        n = check_particle_arrays(positions, radii, active, self.device, "the wetted surface")
        if walls is None:
            walls = self.walls_view
        elif walls.n != self.n_walls:
            raise ValueError(f"walls: the surface was built for {self.n_walls} walls, got {walls.n}")
        if active is None:
            active = self._no_active
        self.reserve(n)
        self.n = n
        d = self.device
        box = self._box
        ny, nz = self.shape[1], self.shape[2]
        nw = box.n_words
        wp.launch(
            KS.wet_clear,
            dim=max(n, KB.N_DIAG, 1),
            inputs=[n],
            outputs=[self.counts, self.hits, self.diag, self.rmax, self.cond, self.wall_counts],
            device=d,
        )
        self.blocked.zero_()
        self.solid.zero_()
        self.reach.zero_()
        self.rays.zero_()
        self.heads.fill_(-1)
        if self.owners.shape[0] > 0:
            self.owners.fill_(-2)
            self.thin_faces.zero_()
        if n > 0:
            # Enough threads to fill a GPU: a small body gets up to 8 per sphere, one per few z layers.
            slices = self._slices or self._auto_slices(n)
            wp.launch(
                KS.wet_rasterize,
                dim=n * slices,
                inputs=[positions, radii, active, box, slices],
                outputs=[self.blocked, self.solid, self.heads, self.next_in_bin, self.rmax, self.diag],
                device=d,
            )
        if self.n_walls:
            wp.launch(
                KS.wet_rasterize_walls, dim=ny * nz, inputs=[box, walls], outputs=[self.blocked, self.solid], device=d
            )

        def round_body():
            wp.launch(
                KS.wet_sweep_x,
                dim=ny * nz,
                inputs=[box, walls, self.blocked, self.cond],
                outputs=[self.reach],
                device=d,
            )
            for axis in (1, 2):
                seg, n_seg, cols = self._seg[axis], self._n_seg[axis], self._columns[axis]
                segs = [self.seg_pass, self.seg_up, self.seg_down]
                wp.launch(
                    KS.wet_scan_summary,
                    dim=cols * n_seg,
                    inputs=[box, axis, seg, n_seg, self.blocked, self.reach, self.cond],
                    outputs=segs,
                    device=d,
                )
                wp.launch(
                    KS.wet_scan_carry,
                    dim=cols,
                    inputs=[box, axis, walls, n_seg, self.seg_pass, self.cond],
                    outputs=segs[1:],
                    device=d,
                )
                wp.launch(
                    KS.wet_scan_apply,
                    dim=cols * n_seg,
                    inputs=[box, axis, seg, n_seg, self.blocked, self.seg_up, self.seg_down, self.cond],
                    outputs=[self.reach],
                    device=d,
                )
            wp.launch(
                KS.wet_frontier,
                dim=nw,
                inputs=[box, walls, self.blocked, self.reach, self.cond],
                outputs=[self.frontier],
                device=d,
            )
            wp.launch(
                KS.wet_round_end,
                dim=1,
                inputs=[self.max_rounds],
                outputs=[self.frontier, self.cond, self.diag, self.nonconverged_total],
                device=d,
            )

        if last < 1:
            return
        if d.is_cuda and d.is_capturing and not wp.is_conditional_graph_supported():
            # No conditional graph nodes: record every round; rounds after convergence return at once.
            for _ in range(self.max_rounds):
                round_body()
        else:
            wp.capture_while(self.cond, round_body)
        if last < 2:
            return
        for table, dims, out in (
            (self._table, self.table.shape, self.fluid),
            (self._table_band, self.table_band.shape, self.band),
        ):
            wy, wz = dims[0] - 1, dims[1] - 1
            wp.launch(
                KS.wet_dilate_y, dim=nw, inputs=[box, walls, wy, wz, self.reach, table], outputs=[self.planes], device=d
            )
            wp.launch(KS.wet_dilate_z, dim=nw, inputs=[box, walls, wy, wz, self.planes, table], outputs=[out], device=d)
        if last < 3:
            return
        if self.skin:
            # A new reference when the particle count changed or a particle moved half the skin.
            cap = self._wit_keys.shape[0]
            wp.launch(K.wet_skin_start, dim=1, inputs=[n, cap, cap], outputs=[self._skin_state], device=d)
            if n > 0:
                wp.launch(
                    K.wet_skin_moved,
                    dim=n,
                    inputs=[positions, radii, active, self._ref_pos, self._ref_rad, self._ref_act, 0.5 * self.skin],
                    outputs=[self._skin_state],
                    device=d,
                )
            wp.launch(
                K.wet_skin_clear,
                dim=max(nw, cap),
                inputs=[self._skin_state],
                outputs=[self.kept, self._tried, self._wit_keys, self._cross_keys],
                device=d,
            )
        if n > 0:
            self.exposed.zero_()
            slices = self._slices or self._auto_slices(n)
            wp.launch(
                K.wet_expose,
                dim=n * slices,
                inputs=[positions, radii, active, box, self.reach, slices],
                outputs=[self.exposed],
                device=d,
            )
        if self._capacity > 0:
            self.queued.zero_()
            if self._ordered:
                wp.launch(
                    KS.wet_uncertain_words,
                    dim=nw,
                    inputs=[self.band, self.fluid, self.solid, self.kept, self._skin_state, box],
                    outputs=[self._uncertain, self._unc_counts],
                    device=d,
                )
                wp.utils.array_scan(self._unc_counts, self._unc_offsets, inclusive=False)
        wp.launch(
            K.wet_classify,
            dim=nw * (32 // self._bits),
            inputs=[
                positions,
                radii,
                box,
                walls,
                self.reach,
                self.band,
                self.solid,
                self.heads,
                self.next_in_bin,
                self.rmax,
                self.exposed,
                self._bits,
                self._capacity,
                self.skin,
                n,
                self._uncertain,
                self._unc_offsets,
            ],
            outputs=[
                self.fluid,
                self.diag,
                self.queue,
                self.queued,
                self.kept,
                self._tried,
                self._skin_state,
                self._wit_keys,
                self._wits,
                self._wit_margins,
            ],
            device=d,
        )
        # What the queued tests and the margins search: the particles, the box and its walls, the reach, the bins.
        searched = [positions, radii, box, walls, self.reach, self.heads, self.next_in_bin, self.rmax, self.exposed]
        if self._capacity > 0:
            wp.launch(
                K.wet_classify_queued,
                dim=self._gathered.shape[0] // KB.GATHER,
                inputs=[*searched, self.queue, self.skin, n],
                outputs=[
                    self.queued,
                    self._gathered,
                    self.fluid,
                    self.diag,
                    self.kept,
                    self._tried,
                    self._skin_state,
                    self._wit_keys,
                    self._wits,
                    self._wit_margins,
                ],
                device=d,
                block_dim=SPARSE_BLOCK_DIM,
            )
        if self.skin:
            wp.launch(
                K.wet_skin_margins,
                dim=self._wit_keys.shape[0],
                inputs=[*searched, self.skin, n, self._wit_keys, self._wits, self._skin_state],
                outputs=[self._wit_margins],
                device=d,
            )
            wp.launch(
                K.wet_skin_rebase,
                dim=max(n, 1),
                inputs=[positions, radii, active, n],
                outputs=[self._ref_pos, self._ref_rad, self._ref_act, self._skin_state],
                device=d,
            )
        if last < 4:
            return
        # With the list, a thread per face word only finds the crossings (the searches run a thread each below);
        # without it, a thread per `_bits` bits searches what it finds.
        bits = 32 if self._list_capacity else self._bits
        per_word = 32 // bits
        first = wp.vec3i(0, self._face_words[0] * per_word, (self._face_words[0] + self._face_words[1]) * per_word)
        loads = [
            self.counts,
            self.hits,
            self.rays,
            self.diag,
            self.owners,
            self.wall_counts,
            self._cross_keys,
            self._cross_owners,
            self._skin_state,
        ]
        if self._list_capacity:
            self.cross_listed.zero_()
        wp.launch(
            KC.wet_cross,
            dim=sum(self._face_words) * per_word,
            inputs=[
                positions,
                radii,
                box,
                walls,
                first,
                bits,
                self.fluid,
                self.heads,
                self.next_in_bin,
                self.rmax,
                self.skin,
                n,
            ],
            outputs=[*loads, self.cross_list, self.cross_listed],
            device=d,
        )
        if self._list_capacity:
            wp.launch(
                KC.wet_cross_listed,
                dim=self._list_capacity,
                inputs=[
                    positions,
                    radii,
                    box,
                    walls,
                    self.heads,
                    self.next_in_bin,
                    self.rmax,
                    self.skin,
                    n,
                    self.cross_list,
                    self.cross_listed,
                ],
                outputs=loads,
                device=d,
                block_dim=SPARSE_BLOCK_DIM,
            )
        if last < 5 or n == 0:
            return
        loads = [self.counts, self.hits, self.rays, self.diag, self.thin_faces]
        # wet_thin's inputs; wet_thin_listed's are these less active and fluid.
        ins = [positions, radii, active, box, walls, self.fluid, self.reach, self.heads, self.next_in_bin]
        ins += [self.rmax, self.exposed]

        def walk():
            # Every sphere-axis's chords, or (with the list) those from its first one the list could not hold.
            wp.launch(
                K.wet_thin,
                dim=3 * n,
                inputs=[*ins, self.thin_from],
                outputs=loads,
                device=d,
                block_dim=SPARSE_BLOCK_DIM,
            )

        if self.thin_list.shape[0] == 0:
            walk()
            return
        # Listed (CUDA): a light scan lists the chords with fluid on both sides, a thread walks each, and the
        # walking kernel runs over the sphere-axes only when some chord did not fit in the list.
        self.thin_listed.zero_()
        self.thin_over.zero_()
        wp.launch(
            K.wet_thin_scan,
            dim=3 * n,
            inputs=[positions, radii, active, box, walls, self.fluid],
            outputs=[self.thin_list, self.thin_listed, self.thin_from, self.thin_over],
            device=d,
        )
        wp.launch(
            K.wet_thin_listed,
            dim=self.thin_list.shape[0],
            inputs=[*ins[:2], box, walls, *ins[6:], self.thin_list, self.thin_listed],
            outputs=loads,
            device=d,
            block_dim=SPARSE_BLOCK_DIM,
        )
        wp.capture_if(self.thin_over, on_true=walk)

    def counts_numpy(self) -> np.ndarray:
        """Signed crossing counts of the last update, shape (N, 3), int64 (copies to the host)."""
        return self.counts.numpy()[: 3 * self.n].reshape(self.n, 3)

    def wall_counts_numpy(self) -> np.ndarray:
        """Signed counts per wall and axis of the last update, shape (W, 3), int64 (copies to the host)."""
        return self.wall_counts.numpy().reshape(-1, 3).copy()

    def diagnostics(self, pressure=None) -> WettedDiagnostics:
        """Voxel maps, per-ray crossings, skip counters and the connectivity outcome (host copies).

        Args:
            pressure: Pressure [Pa] (a number or three), for the resultant force.
        """
        g = self.grid
        counts = self.counts_numpy()
        hits = self.hits.numpy()[: self.n].astype(np.int64)
        diag = self.diag.numpy()
        rays = self.rays.numpy()
        crossings, loaded = {}, {}
        for a in range(3):
            nu, nv = (int(x) for x in g.counts[a])
            o = int(g.offsets[a])
            crossings[a] = rays[o : o + nu * nv].reshape(nv, nu).T.copy()
            total = int(crossings[a].sum())
            for side in range(2):
                name = LAMPS[2 * a + side]
                loaded[name] = total if (self.lamp_mask >> (2 * a + side)) & 1 else 0
        out = WettedDiagnostics(
            counts=counts,
            hits=hits,
            surface=hits > 0,
            fluid=unpack_bits(self.fluid.numpy(), self.shape),
            allowed=~unpack_bits(self.blocked.numpy(), self.shape),
            reachable=unpack_bits(self.reach.numpy(), self.shape),
            band=unpack_bits(self.band.numpy(), self.shape),
            crossings=crossings,
            loaded=loaded,
            invalid=int(diag[KB.DIAG_INVALID]),
            outside=int(diag[KB.DIAG_OUTSIDE]),
            tight=int(diag[KB.DIAG_TIGHT]),
            unattributed=int(diag[KB.DIAG_UNATTRIBUTED]),
            uncertain=int(diag[KB.DIAG_UNCERTAIN]),
            rescued=int(diag[KB.DIAG_RESCUED]),
            thin=int(diag[KB.DIAG_THIN]),
            gap_tests=int(diag[KB.DIAG_GAPS]),
            rounds=int(diag[KB.DIAG_ROUNDS]),
            nonconverged=bool(diag[KB.DIAG_NONCONVERGED]),
            nonconverged_total=int(self.nonconverged_total.numpy()[0]),
            wall_counts=self.wall_counts_numpy(),
        )
        if self._list_capacity:
            out.crossings_listed = min(int(self.cross_listed.numpy()[0]), self._list_capacity)
        if self.thin_list.shape[0] > 0:
            out.thin_listed = min(int(self.thin_listed.numpy()[0]), self.thin_list.shape[0])
        if self.skin:
            st = self._skin_state.numpy()
            out.skin_kept = int(st[KB.SKIN_KEPT])
            out.skin_certified = int(st[KB.SKIN_CERTIFIED])
            out.skin_reset = bool(st[KB.SKIN_RESET])
            out.skin_resets = int(st[KB.SKIN_RESETS])
            out.skin_witnessed = int(st[KB.SKIN_WITNESSED])
            out.skin_held = int(st[KB.SKIN_HELD])
            out.skin_cross_kept = int(st[KB.SKIN_CROSS_KEPT])
        if self.owners.shape[0] > 0:
            own = self.owners.numpy()
            thin = self.thin_faces.numpy()
            out.owners, out.thin_faces, out.wall_owners = {}, {}, {}
            start = 0
            for a in range(3):
                nu, nv = (int(x) for x in g.counts[a])
                for src, dst in ((own, out.owners), (thin, out.thin_faces)):
                    block = src[start : start + self._faces[a]].reshape(nv, nu, self.shape[a] + 1)
                    dst[a] = block.transpose(1, 0, 2).copy()
                start += self._faces[a]
                walled = out.owners[a] <= KB.WALL_OWNER
                out.wall_owners[a] = np.where(walled, KB.WALL_OWNER - out.owners[a], -1)
                out.owners[a][walled] = KB.WALL_OWNER
        if pressure is not None:
            out.force = (counts * pressure_area(pressure, g)).sum(axis=0)
            out.wall_forces = out.wall_counts * pressure_area(pressure, g)
        return out
