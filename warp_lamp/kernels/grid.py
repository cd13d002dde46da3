"""The lamp grids as the kernels see them: one struct, built once on the host by ``LampGrid.params``."""

import warp as wp

wp.set_module_options({"enable_backward": False, "fuse_fp": False})


@wp.struct
class LampGridParams:
    """Three 2D grids in frame coordinates: a particle at world position x sits at R^T (x - o), with o =
    ``origin[0]`` (the frame origin in world coordinates) and R = ``rotation[0]`` (columns: the lamp axes in world
    coordinates). Both live in device arrays, so that a simulator can move and turn the frame between replays of
    a captured graph.

    Grid ``a`` looks along axis a and spans u = (a+1)%3 and v = (a+2)%3; its cell (i, j) is
    [corner_u[a] + i h_u[a], ...) x [corner_v[a] + j h_v[a], ...), i < n_u[a], j < n_v[a], numbered row-major
    (j n_u + i) from ``offset[a]`` in the flat cell numbering shared by the three grids.
    """

    origin: wp.array[wp.vec3]  # one value [m]: zero for positions already in frame coordinates
    rotation: wp.array[wp.mat33]  # one value: the identity for positions already in frame coordinates
    corner_u: wp.vec3  # [m], one per grid
    corner_v: wp.vec3
    h_u: wp.vec3  # cell sizes [m]
    h_v: wp.vec3
    n_u: wp.vec3i  # cells per grid along u and v
    n_v: wp.vec3i
    offset: wp.vec3i  # first flat cell of each grid
    n_cells: wp.int32  # cells of the three grids together


@wp.func
def grid_to_frame(grid: LampGridParams, x: wp.vec3) -> wp.vec3:
    """Frame coordinates R^T (x - o) of a world position (:func:`frame_point` with the grid's frame)."""
    return frame_point(grid.origin[0], grid.rotation[0], x)


@wp.func
def frame_point(o: wp.vec3, r: wp.mat33, x: wp.vec3) -> wp.vec3:
    """Frame coordinates R^T (x - o) of a world position, in a fixed order of operations, so that the identity
    leaves x - o bitwise as it is: 1 q + 0 + 0 = q. A loop over many particles reads o and R once and calls this."""
    q = x - o
    return wp.vec3(
        r[0, 0] * q[0] + r[1, 0] * q[1] + r[2, 0] * q[2],
        r[0, 1] * q[0] + r[1, 1] * q[1] + r[2, 1] * q[2],
        r[0, 2] * q[0] + r[1, 2] * q[1] + r[2, 2] * q[2],
    )


@wp.func
def grid_cell(grid: LampGridParams, c: wp.int32) -> wp.vec3i:
    """(axis a, i, j) of flat cell c."""
    a = int(0)
    if c >= grid.offset[2]:
        a = 2
    elif c >= grid.offset[1]:
        a = 1
    local = c - grid.offset[a]
    j = local / grid.n_u[a]
    return wp.vec3i(a, local - j * grid.n_u[a], j)
