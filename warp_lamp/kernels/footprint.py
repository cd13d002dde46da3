"""Sphere-to-cell footprint functions shared by the lamp and the porosity kernels.

Both walk the cells that a sphere's projected disk (lamp) or a sphere's rows of sub-cells (voxel porosity) cover:
the span of cells whose centre, or whose extent, meets an interval (``cell_span``), and the offset between a
cell and a sphere centre (``cell_offset``). The functions are generic over the float width: the lamp works in
float32, the porosity kernels in float64.
"""

from typing import Any

import warp as wp

wp.set_module_options({"enable_backward": False, "fuse_fp": False})


#: Where a cell's ray sits (the ``ray`` argument): a cell is lit where its rectangle meets the projected disk
#: (the memo's criterion 0), or where its ray through the cell centre (criterion 1) or through its lower corner
#: (the area criterion's sample rays, one per cell corner) meets the sphere.
RAY_OVERLAP = wp.constant(0)
RAY_CENTRE = wp.constant(1)
RAY_CORNER = wp.constant(2)


@wp.func
def cell_span(lo: Any, hi: Any, h: Any, n: wp.int32, ray: wp.int32) -> wp.vec2i:
    """Indices [first, last] of the cells of width h that may meet [lo, hi], clamped to [0, n-1]; first > last if
    none. ``RAY_CENTRE``: cells whose centre (i + 1/2) h lies in [lo, hi]; ``RAY_CORNER``: cells whose corner i h
    does; ``RAY_OVERLAP``: cells [i h, (i+1) h] that overlap it.

    A superset, never short: the span is padded by a tolerance above the float32 rounding of the divisions
    (2^-10 of a cell, plus 16 float32 ulps of the coordinates in cells), so that no cell the caller's exact test
    accepts is left out, at the cost of at most one extra test per end. Clamping happens in float, so that a far
    sphere cannot overflow the int conversion.
    """
    one = type(lo)(1.0)
    x = lo / h
    y = hi / h
    tol = type(lo)(0.0009765625) + (wp.abs(x) + wp.abs(y)) * type(lo)(9.5367431640625e-07)
    a = wp.ceil(x - one - tol)
    b = wp.floor(y + tol)
    if ray == RAY_CENTRE:
        a = wp.ceil(x - type(lo)(0.5) - tol)
        b = wp.floor(y - type(lo)(0.5) + tol)
    elif ray == RAY_CORNER:
        a = wp.ceil(x - tol)
    nf = type(lo)(n)
    a = wp.clamp(a, type(lo)(0.0), nf)
    b = wp.clamp(b, -one, nf - one)
    return wp.vec2i(wp.int32(a), wp.int32(b))


@wp.func
def rect_gap(x: Any, lo: Any, hi: Any) -> Any:
    """Distance from x to the interval [lo, hi] (zero inside)."""
    return wp.max(wp.max(lo - x, x - hi), type(x)(0.0))


@wp.func
def cell_offset(i: wp.int32, h: Any, x: Any, ray: wp.int32) -> Any:
    """Offset between cell i of width h and a sphere centre at x along one axis: from the cell centre
    (``RAY_CENTRE``) or corner (``RAY_CORNER``), or the distance from x to the cell's interval (``RAY_OVERLAP``)."""
    if ray == RAY_CENTRE:
        return (type(h)(i) + type(h)(0.5)) * h - x
    if ray == RAY_CORNER:
        return type(h)(i) * h - x
    return rect_gap(x, type(h)(i) * h, type(h)(i + 1) * h)


@wp.func
def lamp_reach(rem: wp.float32, du: wp.float32, ray: wp.int32) -> wp.float32:
    """Half-length of the sphere along a lit cell's ray, or 0 for ``RAY_OVERLAP`` (depth at the centre).

    ``rem = r^2 - dv^2`` of the cell's row; the cell is lit when ``du^2 <= rem``. Every kernel that decides a
    cell (depth pass, seeding) goes through this and ``cell_offset``, so their float32 roundings agree (the BVH
    peer writes the same arithmetic out on its own).
    """
    if ray != RAY_OVERLAP:
        return wp.sqrt(rem - du * du)
    return 0.0
