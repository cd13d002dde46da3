"""Planar walls that bound the fluid: where a lamp's ray stops, and which lamp cannot shine at all.

A wall is a plane with a unit normal pointing from the wall into the fluid: the fluid is ``n . x > d``. A ray
that starts inside a wall (its lamp sits on the wall's side) reaches the body only through the wall and lights
nothing; a ray that starts in the fluid stops where it first enters a wall, and that wall takes the reaction when
no sphere comes first.
"""

import warp as wp

from warp_lamp.kernels.grid import LampGridParams

wp.set_module_options({"enable_backward": False, "fuse_fp": False})

#: Most walls a lamp takes.
MAX_WALLS = 8

WALL_FREE = wp.constant(0)
WALL_STOPS = wp.constant(1)
WALL_BLOCKS = wp.constant(2)


@wp.struct
class LampWalls:
    """The walls as the kernels read them: planes (n, d), fluid where ``n . x > d``, in the lamp frame (positions
    relative to the frame origin), and their number (0: no walls)."""

    frame: wp.array[wp.vec4]
    n: wp.int32


@wp.struct
class RayStop:
    """Where a lamp's ray ends: ``state`` WALL_FREE (no wall on its way), WALL_STOPS (it enters wall ``wall`` at
    coordinate ``t`` along its axis) or WALL_BLOCKS (it starts inside a wall and lights nothing)."""

    state: wp.int32
    t: wp.float64
    wall: wp.int32


@wp.func
def ray_stop(walls: LampWalls, a: wp.int32, base: wp.vec3d, side: wp.int32) -> RayStop:
    """Where the ray along axis ``a`` through ``base`` (frame coordinates, ``base[a]`` = 0) ends for lamp ``side``
    (0: from minus infinity toward +a; 1: from plus infinity toward -a): the nearest wall it enters, ties to the
    lowest wall."""
    out = RayStop()
    out.state = WALL_FREE
    out.t = wp.float64(0.0)
    out.wall = -1
    for w in range(walls.n):
        pl = walls.frame[w]
        nn = wp.float64(pl[a])
        g = (
            (wp.float64(pl[0]) * base[0] + wp.float64(pl[1]) * base[1])
            + wp.float64(pl[2]) * base[2]
            - wp.float64(pl[3])
        )
        # The ray starts in the wall when its lamp's end of the axis lies on the wall's side.
        starts_inside = g < wp.float64(0.0)
        if nn > wp.float64(0.0):
            starts_inside = side == 0
        elif nn < wp.float64(0.0):
            starts_inside = side == 1
        if starts_inside:
            out.state = WALL_BLOCKS
            return out
        if nn != wp.float64(0.0):
            t = -g / nn
            better = out.state == WALL_FREE
            if not better:
                if side == 0:
                    better = t < out.t
                else:
                    better = t > out.t
            if better:
                out.state = WALL_STOPS
                out.t = t
                out.wall = w
    return out


@wp.func
def cell_ray_base(grid: LampGridParams, a: wp.int32, i: wp.int32, j: wp.int32) -> wp.vec3d:
    """The centre ray of cell (i, j) of grid a, as a point with coordinate 0 along a (frame coordinates)."""
    base = wp.vec3d(0.0, 0.0, 0.0)
    base[(a + 1) % 3] = wp.float64(grid.corner_u[a]) + (wp.float64(i) + wp.float64(0.5)) * wp.float64(grid.h_u[a])
    base[(a + 2) % 3] = wp.float64(grid.corner_v[a]) + (wp.float64(j) + wp.float64(0.5)) * wp.float64(grid.h_v[a])
    return base


@wp.func
def plane_value(pl: wp.vec4, x: wp.vec3d) -> wp.float64:
    """The wall's signed distance ``g = n . x - d`` at x (frame coordinates) in float64, in this order: positive on
    the fluid side, negative inside the wall (``ray_stop``'s expression; the normal is the float32 unit normal)."""
    return ((wp.float64(pl[0]) * x[0] + wp.float64(pl[1]) * x[1]) + wp.float64(pl[2]) * x[2]) - wp.float64(pl[3])
