"""Planar walls that bound the fluid: where a lamp's ray is in the fluid, and who takes each end of it.

A wall is a plane with a unit normal pointing from the wall into the fluid: the fluid is ``n . x > d``. Along a
cell's ray the fluid is the interval (lo, hi) that lies on the fluid side of every wall (``ray_fluid``). The body
on the ray is the span [E, X] from its first sphere's entry to its last sphere's exit (the memo's convention: what
lies between is body). The fluid between a wall and the body pushes both; a wall that crosses the ray inside the
span, or a wall the body rests on, seals that end (``walled_loads``, docs/guide/walls.md).
"""

import warp as wp

from warp_lamp.kernels.grid import LampGridParams

wp.set_module_options({"enable_backward": False, "fuse_fp": False})

#: Most walls a lamp takes.
MAX_WALLS = 8


@wp.struct
class LampWalls:
    """The walls as the kernels read them: planes (n, d), fluid where ``n . x > d``, in the lamp frame (positions
    relative to the frame origin), and their number (0: no walls); ``gap`` per wall the smallest (n . c - d - r) / r
    over the particles (``walls_contact``), and ``rest``: a body whose smallest gap lies in [-rest, rest] rests on
    the wall, which then seals every ray that meets the body."""

    frame: wp.array[wp.vec4]
    n: wp.int32
    gap: wp.array[wp.float32]
    rest: wp.float32


@wp.struct
class RayFluid:
    """The part of a cell's ray in the fluid: coordinates ``lo`` < ``hi`` along its axis, bounded by wall
    ``lo_wall`` / ``hi_wall`` (-1: open to infinity on that side); ``wet`` false where no part of the ray is in
    the fluid."""

    wet: wp.bool
    lo: wp.float64
    hi: wp.float64
    lo_wall: wp.int32
    hi_wall: wp.int32


@wp.func
def plane_value(pl: wp.vec4, x: wp.vec3d) -> wp.float64:
    """The wall's signed distance ``g = n . x - d`` at x (frame coordinates) in float64, in this order: positive on
    the fluid side, negative inside the wall (the normal is the float32 unit normal)."""
    return ((wp.float64(pl[0]) * x[0] + wp.float64(pl[1]) * x[1]) + wp.float64(pl[2]) * x[2]) - wp.float64(pl[3])


@wp.func
def ray_fluid(walls: LampWalls, a: wp.int32, base: wp.vec3d) -> RayFluid:
    """The fluid interval of the ray along axis ``a`` through ``base`` (frame coordinates, ``base[a]`` = 0): above
    every wall whose normal has a positive a-component (the largest crossing bounds it, ties to the lowest wall),
    below every wall whose normal has a negative one; a wall parallel to the ray with the ray behind it (g < 0)
    leaves it dry."""
    out = RayFluid()
    out.wet = True
    out.lo = wp.float64(0.0)
    out.hi = wp.float64(0.0)
    out.lo_wall = -1
    out.hi_wall = -1
    for w in range(walls.n):
        pl = walls.frame[w]
        nn = wp.float64(pl[a])
        g = plane_value(pl, base)
        if nn == wp.float64(0.0):
            if g < wp.float64(0.0):
                out.wet = False
        else:
            t = -g / nn
            if nn > wp.float64(0.0):
                if out.lo_wall < 0 or t > out.lo:
                    out.lo = t
                    out.lo_wall = w
            else:
                if out.hi_wall < 0 or t < out.hi:
                    out.hi = t
                    out.hi_wall = w
    if out.lo_wall >= 0 and out.hi_wall >= 0:
        if out.lo >= out.hi:
            out.wet = False
    return out


@wp.func
def wall_rests(walls: LampWalls, w: wp.int32) -> wp.bool:
    """Whether the body rests on wall w: its smallest gap (``walls_contact``) lies within [-rest, rest]."""
    g = walls.gap[w]
    return g >= -walls.rest and g <= walls.rest


@wp.func
def cell_ray_base(grid: LampGridParams, a: wp.int32, i: wp.int32, j: wp.int32) -> wp.vec3d:
    """The centre ray of cell (i, j) of grid a, as a point with coordinate 0 along a (frame coordinates)."""
    base = wp.vec3d(0.0, 0.0, 0.0)
    base[(a + 1) % 3] = wp.float64(grid.corner_u[a]) + (wp.float64(i) + wp.float64(0.5)) * wp.float64(grid.h_u[a])
    base[(a + 2) % 3] = wp.float64(grid.corner_v[a]) + (wp.float64(j) + wp.float64(0.5)) * wp.float64(grid.h_v[a])
    return base
