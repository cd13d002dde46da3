"""Packed (depth, particle) keys: unsigned order is depth order, then lowest particle index.

A key is the order-preserving bit pattern of a float32 depth in the high 32 bits and the particle index in the low
32 bits, so one ``atomic_min`` on a uint64 resolves "nearest sphere, ties to the lowest index" in a single
instruction, and every order of offers gives the same minimum.
"""

import warp as wp

wp.set_module_options({"enable_backward": False, "fuse_fp": False})

#: Key of an empty cell: the identity of atomic_min on uint64.
EMPTY_KEY = wp.constant(wp.uint64(0xFFFFFFFFFFFFFFFF))
SIGN_BIT = wp.constant(wp.uint32(0x80000000))
LOW_WORD = wp.constant(wp.uint64(0xFFFFFFFF))


@wp.func
def ordered_bits(x: wp.float32) -> wp.uint32:
    """Map a finite float32 to a uint32 with the same order; -0 and +0 map alike so that ties stay ties."""
    b = wp.cast(x, wp.uint32)
    if b == SIGN_BIT:
        b = wp.uint32(0)
    if (b & SIGN_BIT) != wp.uint32(0):
        return ~b
    return b | SIGN_BIT


@wp.func
def pack_key(depth: wp.float32, particle: wp.int32) -> wp.uint64:
    """(depth, particle index) packed so that unsigned order is depth order, then lowest index."""
    return (wp.uint64(ordered_bits(depth)) << wp.uint64(32)) | wp.uint64(wp.uint32(particle))


@wp.func
def key_owner(key: wp.uint64) -> wp.int32:
    """The particle index of a key (meaningless for EMPTY_KEY)."""
    return wp.int32(wp.uint32(key & LOW_WORD))


@wp.func
def key_depth(key: wp.uint64) -> wp.float32:
    """The depth of a key (the inverse of ``ordered_bits``; meaningless for EMPTY_KEY)."""
    b = wp.uint32(key >> wp.uint64(32))
    if (b & SIGN_BIT) != wp.uint32(0):
        b = b ^ SIGN_BIT
    else:
        b = ~b
    return wp.cast(b, wp.float32)
