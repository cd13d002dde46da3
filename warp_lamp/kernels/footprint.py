"""Sphere-to-cell footprint functions shared by the lamp and the porosity kernels."""

import warp as wp

wp.set_module_options({"enable_backward": False, "fuse_fp": False})

# Key of an empty cell: the identity of atomic_min on uint64.
EMPTY_KEY = wp.constant(wp.uint64(0xFFFFFFFFFFFFFFFF))
SIGN_BIT = wp.constant(wp.uint32(0x80000000))
ALL_BITS = wp.constant(wp.uint32(0xFFFFFFFF))


@wp.func
def ordered_bits(x: wp.float32) -> wp.uint32:
    """Map a finite float32 to a uint32 with the same order; -0 and +0 map alike so that ties stay ties."""
    b = wp.cast(x, wp.uint32)
    if b == SIGN_BIT:
        b = wp.uint32(0)
    if (b & SIGN_BIT) != wp.uint32(0):
        return b ^ ALL_BITS
    return b | SIGN_BIT


@wp.func
def pack_key(depth: wp.float32, pid: wp.int32) -> wp.uint64:
    """(depth, particle id) packed so that unsigned order is depth order, then lowest id."""
    return (wp.uint64(ordered_bits(depth)) << wp.uint64(32)) | wp.uint64(wp.uint32(pid))


@wp.func
def key_owner(key: wp.uint64) -> wp.int32:
    return wp.int32(wp.uint32(key & wp.uint64(0xFFFFFFFF)))


@wp.func
def cell_axis(c: wp.int32, offset: wp.vec3i) -> wp.int32:
    """The grid (axis) that flat cell c belongs to, from the grids' first cells."""
    if c >= offset[2]:
        return 2
    if c >= offset[1]:
        return 1
    return 0


@wp.func
def cell_span(lo: wp.float32, hi: wp.float32, h: wp.float32, n: wp.int32, centre: wp.int32) -> wp.vec2i:
    """Indices [first, last] of the cells that may meet [lo, hi], clamped to [0, n-1]; first > last if none.

    centre=1: cells whose centre (i + 1/2) h lies in [lo, hi]; centre=0: cells [i h, (i+1) h] that overlap it.
    The span is padded by a tolerance above the float32 rounding of the divisions (2^-10 of a cell, plus 16 ulps
    of the coordinates in cells), so that no cell the caller's exact test accepts is left out, and it costs at
    most one extra test per end instead of a whole widened cell. Clamping happens in float, so a far sphere
    cannot overflow the int conversion.
    """
    x = lo / h
    y = hi / h
    tol = 0.0009765625 + (wp.abs(x) + wp.abs(y)) * 9.5367431640625e-07
    a = float(0.0)
    b = float(0.0)
    if centre != 0:
        a = wp.ceil(x - 0.5 - tol)
        b = wp.floor(y - 0.5 + tol)
    else:
        a = wp.ceil(x - 1.0 - tol)
        b = wp.floor(y + tol)
    nf = wp.float32(n)
    a = wp.clamp(a, 0.0, nf)
    b = wp.clamp(b, -1.0, nf - 1.0)
    return wp.vec2i(wp.int32(a), wp.int32(b))


@wp.func
def cell_index_span(lo: wp.float64, hi: wp.float64, h: wp.float64, n: wp.int32) -> wp.vec2i:
    """Cells [i h, (i+1) h) of 0..n-1 that [lo, hi] reaches, clamped (in float, so far spheres cannot overflow)."""
    nf = wp.float64(n)
    a = wp.clamp(wp.floor(lo / h), wp.float64(0.0), nf)
    b = wp.clamp(wp.floor(hi / h), wp.float64(-1.0), nf - wp.float64(1.0))
    return wp.vec2i(wp.int32(a), wp.int32(b))


@wp.func
def rect_gap(x: wp.float32, lo: wp.float32, hi: wp.float32) -> wp.float32:
    """Distance from x to the interval [lo, hi] (zero inside)."""
    return wp.max(wp.max(lo - x, x - hi), 0.0)


@wp.func
def veltkamp_round26(x: wp.float64) -> wp.float64:
    """x rounded to 26 significant bits (Veltkamp split), so that x times any count below 2**27 is exact."""
    t = x * wp.float64(134217729.0)
    return t - (t - x)


@wp.func
def cell_offset(i: wp.int32, h: wp.float32, x: wp.float32, criterion: wp.int32) -> wp.float32:
    """Transverse offset between cell i of width h and a sphere centre at x: from the cell centre (criterion 1)
    or the distance to the cell's interval (criterion 0)."""
    if criterion == 1:
        return (float(i) + 0.5) * h - x
    return rect_gap(x, float(i) * h, float(i + 1) * h)


@wp.func
def lamp_reach(rem: wp.float32, du: wp.float32, criterion: wp.int32) -> wp.float32:
    """Half-length of the sphere along a lit cell's ray (criterion 1), or 0 (criterion 0: depth at the centre).

    ``rem = r^2 - dv^2`` of the cell's row; the cell is lit when ``du^2 <= rem``. Every kernel that decides a
    cell (depth pass, seeding, BVH peer) goes through this and ``cell_offset``, so their float32 roundings agree.
    """
    if criterion == 1:
        return wp.sqrt(rem - du * du)
    return 0.0
