"""The lamp grids as the kernels see them: one struct, built once on the host by ``LampGrid.params``."""

import warp as wp

wp.set_module_options({"enable_backward": False, "fuse_fp": False})


@wp.struct
class LampGridParams:
    """Three 2D grids in frame coordinates (positions minus ``origin``).

    Grid ``a`` looks along axis a and spans u = (a+1)%3 and v = (a+2)%3; its cell (i, j) is
    [corner_u[a] + i h_u[a], ...) x [corner_v[a] + j h_v[a], ...), i < n_u[a], j < n_v[a], numbered row-major
    (j n_u + i) from ``offset[a]`` in the flat cell numbering shared by the three grids.
    """

    origin: wp.vec3  # subtracted from positions on the device [m]; zero for positions already in frame coordinates
    corner_u: wp.vec3  # [m], one per grid
    corner_v: wp.vec3
    h_u: wp.vec3  # cell sizes [m]
    h_v: wp.vec3
    n_u: wp.vec3i  # cells per grid along u and v
    n_v: wp.vec3i
    offset: wp.vec3i  # first flat cell of each grid
    n_cells: wp.int32  # cells of the three grids together


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
