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
def cell_span(lo: wp.float32, hi: wp.float32, h: wp.float32, n: wp.int32) -> wp.vec2i:
    """Indices [first, last] of the cells [i h, (i+1) h] that may meet [lo, hi], clamped to [0, n-1].

    Widened by one cell on each side: the caller tests every cell exactly, so the span only has to be a
    superset, and rounding in the division must not drop a cell. Clamping happens in float so that a far
    sphere cannot overflow the int conversion. first > last means no cell.
    """
    nf = wp.float32(n)
    a = wp.clamp(wp.floor(lo / h) - 1.0, -1.0, nf)
    b = wp.clamp(wp.floor(hi / h) + 1.0, -1.0, nf)
    return wp.vec2i(wp.max(wp.int32(a), 0), wp.min(wp.int32(b), n - 1))


@wp.func
def rect_gap(x: wp.float32, lo: wp.float32, hi: wp.float32) -> wp.float32:
    """Distance from x to the interval [lo, hi] (zero inside)."""
    return wp.max(wp.max(lo - x, x - hi), 0.0)


@wp.func
def veltkamp_round26(x: wp.float64) -> wp.float64:
    """x rounded to 26 significant bits (Veltkamp split), so that x times any count below 2**27 is exact."""
    t = x * wp.float64(134217729.0)
    return t - (t - x)
