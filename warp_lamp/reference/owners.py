"""Float64 references for :mod:`warp_lamp.kernels.owners`: clump spheres from owner poses, owner loads."""

from __future__ import annotations

import numpy as np

__all__ = ["owner_loads_reference", "quaternion_matrices", "sphere_centers_reference"]


def quaternion_matrices(quats) -> np.ndarray:
    """Rotation matrices of unit quaternions in (x, y, z, w) order, shape (K, 3, 3) (normalised first)."""
    q = np.asarray(quats, dtype=np.float64).reshape(-1, 4)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    x, y, z, w = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
        ],
        axis=1,
    )


def sphere_centers_reference(owner_pos, owner_quat, sphere_owner, sphere_offset) -> np.ndarray:
    """World centres p[o] + R(q[o]) offset[s] of each sphere s of owner o = sphere_owner[s], shape (S, 3)."""
    p = np.asarray(owner_pos, dtype=np.float64)
    o = np.asarray(sphere_owner, dtype=np.int64)
    d = np.asarray(sphere_offset, dtype=np.float64)
    rot = quaternion_matrices(owner_quat)
    return np.array([p[o[s]] + rot[o[s]] @ d[s] for s in range(len(o))]).reshape(-1, 3)


def owner_loads_reference(sphere_force, sphere_offset, sphere_owner, owner_quat, mass, moi):
    """Per owner, one loop over its spheres: (acc, ang_acc), acc = sum F / m in the world frame and ang_acc =
    R^T (sum (R offset) x F) / I componentwise in the owner's principal frame; each shape (K, 3)."""
    f = np.asarray(sphere_force, dtype=np.float64)
    d = np.asarray(sphere_offset, dtype=np.float64)
    o = np.asarray(sphere_owner, dtype=np.int64)
    m = np.asarray(mass, dtype=np.float64)
    inertia = np.asarray(moi, dtype=np.float64).reshape(-1, 3)
    rot = quaternion_matrices(owner_quat)
    k = len(m)
    force, torque = np.zeros((k, 3)), np.zeros((k, 3))
    for s in range(len(o)):
        force[o[s]] += f[s]
        torque[o[s]] += np.cross(rot[o[s]] @ d[s], f[s])
    acc = force / m[:, None]
    ang = np.array([rot[i].T @ torque[i] for i in range(k)]).reshape(-1, 3) / inertia
    return acc, ang
