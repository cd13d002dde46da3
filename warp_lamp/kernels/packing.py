"""Overlap relaxation for dense random sphere packings inside a container: a ball, a box or a cylinder."""

import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.kernel
def packing_push(
    grid: wp.uint64,
    x: wp.array[wp.vec3],
    radii: wp.array[wp.float32],
    scale: wp.float32,
    body_radius: wp.float32,
    box_lower: wp.vec3,
    box_upper: wp.vec3,
    query_radius: wp.float32,
    # outputs
    dx: wp.array[wp.vec3],
    worst: wp.array[wp.float32],
):
    """Jacobi step: each particle moves by half of every overlap it has, and back inside the container: the ball
    of ``body_radius`` about the origin when it is > 0; when it is < 0, the cylinder of radius ``-body_radius``
    about the z axis between ``box_lower[2]`` and ``box_upper[2]``; when it is 0, the box [box_lower, box_upper]."""
    i = wp.tid()
    xi = x[i]
    ri = radii[i] * scale
    d = wp.vec3(0.0)
    q = wp.hash_grid_query(grid, xi, query_radius)
    j = int(0)
    while wp.hash_grid_query_next(q, j):
        if j != i:
            rij = xi - x[j]
            dist = wp.length(rij)
            rj = radii[j] * scale
            ov = ri + rj - dist
            if ov > 0.0:
                n = wp.vec3(1.0, 0.0, 0.0)
                if dist > 0.0:
                    n = rij / dist
                elif i < j:
                    n = wp.vec3(-1.0, 0.0, 0.0)
                d += 0.5 * ov * n
                wp.atomic_max(worst, 0, ov / wp.min(ri, rj))
    if body_radius > 0.0:
        dc = wp.length(xi)
        excess = dc + ri - body_radius
        if excess > 0.0 and dc > 0.0:
            d -= excess * xi / dc
            wp.atomic_max(worst, 0, excess / ri)
    elif body_radius < 0.0:
        rho = wp.sqrt(xi[0] * xi[0] + xi[1] * xi[1])
        excess = rho + ri + body_radius
        if excess > 0.0 and rho > 0.0:
            d[0] = d[0] - excess * xi[0] / rho
            d[1] = d[1] - excess * xi[1] / rho
            wp.atomic_max(worst, 0, excess / ri)
        low = box_lower[2] + ri - xi[2]
        high = xi[2] + ri - box_upper[2]
        if low > 0.0:
            d[2] = d[2] + low
            wp.atomic_max(worst, 0, low / ri)
        elif high > 0.0:
            d[2] = d[2] - high
            wp.atomic_max(worst, 0, high / ri)
    else:
        for a in range(3):
            low = box_lower[a] + ri - xi[a]
            high = xi[a] + ri - box_upper[a]
            if low > 0.0:
                d[a] = d[a] + low
                wp.atomic_max(worst, 0, low / ri)
            elif high > 0.0:
                d[a] = d[a] - high
                wp.atomic_max(worst, 0, high / ri)
    dx[i] = d


@wp.kernel
def packing_move(
    dx: wp.array[wp.vec3],
    momentum: wp.float32,
    # outputs
    v: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
):
    """Heavy-ball step: plain Jacobi crawls once the packing nears jamming; momentum carries it through."""
    i = wp.tid()
    vi = momentum * v[i] + dx[i]
    v[i] = vi
    x[i] = x[i] + vi
