"""Rigid owners made of spheres (an engine's clumps): sphere centres from owner poses, owner loads from sphere forces.

An owner o holds the spheres ``start[o] <= s < start[o + 1]``; sphere s sits at ``offset[s]`` in the owner's own
(principal) frame, so its world centre is ``p[o] + q[o] offset[s]``, with ``q[o]`` the owner's local-to-global
rotation. One thread per sphere or per owner; each owner sums its own spheres in order (no atomics), so the loads
do not depend on scheduling.
"""

import warp as wp

wp.set_module_options({"enable_backward": False, "fuse_fp": False})


@wp.kernel
def sphere_centers_from_owners(
    owner_pos: wp.array[wp.vec3],
    owner_rot: wp.array[wp.quat],
    sphere_owner: wp.array[wp.int32],
    sphere_offset: wp.array[wp.vec3],
    reference: wp.vec3,
    rotate: wp.int32,
    # outputs
    centers: wp.array[wp.vec3],
):
    """centers[s] = p[o] + q[o] offset[s] - reference (o the owner of s); without ``rotate`` the offsets are
    taken as they are (one-sphere owners, whose offsets are zero)."""
    s = wp.tid()
    o = sphere_owner[s]
    d = sphere_offset[s]
    if rotate != 0:
        d = wp.quat_rotate(owner_rot[o], d)
    centers[s] = owner_pos[o] + d - reference


@wp.kernel
def owner_accelerations(
    sphere_force: wp.array[wp.vec3],
    sphere_offset: wp.array[wp.vec3],
    owner_start: wp.array[wp.int32],
    owner_rot: wp.array[wp.quat],
    owner_mass: wp.array[wp.float32],
    owner_moi: wp.array[wp.vec3],
    torques: wp.int32,
    # outputs
    owner_acc: wp.array[wp.vec3],
    owner_ang_acc: wp.array[wp.vec3],
):
    """Owner o's linear acceleration sum F / m (world frame) and, with ``torques``, its angular acceleration in
    its own principal frame, (q^-1 sum r x F) / I componentwise, r = q offset (the sphere's arm about the owner's
    centre of mass)."""
    o = wp.tid()
    f = wp.vec3(0.0, 0.0, 0.0)
    t = wp.vec3(0.0, 0.0, 0.0)
    q = wp.quat_identity()
    if torques != 0:
        q = owner_rot[o]
    for s in range(owner_start[o], owner_start[o + 1]):
        fs = sphere_force[s]
        f = f + fs
        if torques != 0:
            t = t + wp.cross(wp.quat_rotate(q, sphere_offset[s]), fs)
    owner_acc[o] = f / owner_mass[o]
    if torques != 0:
        tl = wp.quat_rotate_inv(q, t)
        i = owner_moi[o]
        owner_ang_acc[o] = wp.vec3(tl[0] / i[0], tl[1] / i[1], tl[2] / i[2])
