"""Lamp frames: rotated grids, stress tensors through their principal frame, and frame averaging."""

import numpy as np
import pytest
import warp as wp
from helpers import device_arrays, polydisperse_scene

import warp_lamp as wl
from warp_lamp.frames import lamp_frame_rotations, lamp_stress_frame
from warp_lamp.scenes import scene_lattice_box, scene_sphere_specimen

P = 1.0e6


def rotation_xyz(ax, ay, az):
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def test_identity_rotation_is_bitwise_the_axis_aligned_lamp(device, rng):
    """rotation=I (as a matrix or a quaternion) gives bitwise the forces of a grid without one."""
    c, r = polydisperse_scene(rng, n=300)
    plain = wl.LampGrid.enclosing(c, r, cells_per_diameter=4)
    for rot in (np.eye(3), [0.0, 0.0, 0.0, 1.0]):
        grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4, rotation=rot)
        a = wl.lamp_forces(c, r, (P, 2 * P, 3 * P), grid=grid, device=device)
        b = wl.lamp_forces(c, r, (P, 2 * P, 3 * P), grid=plain, device=device)
        assert a.tobytes() == b.tobytes()


def test_rotating_body_and_frame_together_rotates_the_forces(device, rng):
    """The body turned by R with the lamp frame turned by R gets the forces of the unturned problem turned by R:
    particle by particle to float32 rounding, owners equal (no near-ties in this scene)."""
    c, r = polydisperse_scene(rng, n=250)
    rot = rotation_xyz(0.3, -0.5, 1.1)
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4)
    turned = wl.LampGrid(grid.origin, grid.origin + grid.box_counts * grid.box_cell, grid.box_cell, rotation=rot)
    f0 = wl.lamp_forces(c, r, P, grid=grid, device=device)
    f1 = wl.lamp_forces(c @ rot.T, r, P, grid=turned, device=device)
    n0 = wl.lamp_update(c, r, grid=grid, device=device).counts_numpy()
    n1 = wl.lamp_update(c @ rot.T, r, grid=turned, device=device).counts_numpy()
    mismatch = np.any(n0 != n1, axis=1)
    assert mismatch.sum() <= 2  # float32 frame coordinates differ in the last bit: at most a near-tie moves
    np.testing.assert_allclose(f1[~mismatch], f0[~mismatch] @ rot.T, rtol=0, atol=1e-7 * np.abs(f0).max())


def test_rotated_forces_balance_exactly_in_world_coordinates(device):
    """In a rotated frame the float64 world forces of 10^5 spheres sum to exactly zero on every axis (the factor
    rows are multiples of one power of two), and the ShiningLamp's float32 forces to float32 rounding."""
    s = scene_lattice_box(46, seed=2)
    rot = rotation_xyz(0.17, 0.35, 0.52)
    c = (s.centers - s.centers.mean(axis=0)) @ rot.T
    grid = wl.LampGrid.enclosing(c, s.radii, cells_per_diameter=3, rotation=rot)
    f = wl.lamp_forces(c, s.radii, P, grid=grid, device=device)
    assert len(f) > 9e4 and np.abs(f).sum() > 0
    np.testing.assert_array_equal(f.sum(axis=0), [0.0, 0.0, 0.0])
    lamp = wl.ShiningLamp(grid, device=device)
    pos, rad = device_arrays(c, s.radii, device)
    forces = wp.zeros(len(s.radii), dtype=wp.vec3, device=device)
    lamp.apply(pos, rad, forces, P)
    total = forces.numpy().astype(np.float64)
    lit_area = np.abs(lamp.counts_numpy()).sum() * grid.cell_area[0] / 2
    assert np.abs(total.sum(axis=0)).max() < 1e-6 * P * lit_area


def test_stress_tensor_equals_principal_pressures_in_its_frame(device, rng):
    """A stress tensor with principal axes R and values (p1, p2, p3) gives the forces of pressure=(p1, p2, p3)
    in frame R, with a grid or without one."""
    c, r = polydisperse_scene(rng, n=200)
    rot = rotation_xyz(0.4, 0.1, -0.7)
    p = np.array([3.0e6, 1.0e6, 2.0e6])
    sigma = rot @ np.diag(p) @ rot.T
    frame, values = lamp_stress_frame(sigma)
    np.testing.assert_allclose(frame @ np.diag(values) @ frame.T, sigma, atol=1e-6 * p.max())
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4, rotation=frame)
    a = wl.lamp_forces(c, r, sigma, grid=grid, device=device)
    b = wl.lamp_forces(c, r, values, grid=grid, device=device)
    np.testing.assert_array_equal(a, b)
    c_free = wl.lamp_forces(c, r, sigma, device=device)
    np.testing.assert_array_equal(c_free, b)


def test_bad_rotations_and_tensors_are_refused_by_name():
    """Not orthonormal, a reflection, NaN, wrong shapes; non-symmetric or NaN tensors, and a tensor with shear in
    the grid's frame: each refused with the argument's name (a pure shear is applied in its principal frame, with
    the mixed-signs warning: tests/test_errors.py)."""
    c, r = np.zeros((1, 3)), [0.5]
    for rot, match in (
        (np.diag([1.0, 1.0, 1.1]), r"rotation: not orthonormal"),
        (np.diag([1.0, 1.0, -1.0]), r"rotation: a reflection"),
        ([[np.nan, 0, 0], [0, 1, 0], [0, 0, 1]], r"rotation: must be finite; flat index 0"),
        ([1.0, 0.0, 0.0], r"rotation: expected a 3 x 3 rotation matrix or a unit quaternion"),
        ([0.0, 0.0, 0.0, 2.0], r"rotation: a quaternion \(x, y, z, w\) must have unit norm"),
    ):
        with pytest.raises(ValueError, match=match):
            wl.LampGrid([0, 0, 0], [1, 1, 1], 0.5, rotation=rot)
    for sigma, match in (
        ([[1.0, 2.0, 0], [0, 1, 0], [0, 0, 1]], r"pressure: stress tensor must be symmetric"),
        ([[1.0, 0, 0], [0, np.nan, 0], [0, 0, 1]], r"pressure: stress tensor must be finite; flat index 4"),
    ):
        with pytest.raises(ValueError, match=match):
            wl.lamp_forces(c, r, sigma)
    grid = wl.LampGrid([-1, -1, -1], [1, 1, 1], 0.25)
    with pytest.raises(ValueError, match=r"pressure: the stress tensor is not diagonal in the lamp frame"):
        wl.lamp_forces(c, r, [[2.0, 0.5, 0], [0.5, 1.0, 0], [0, 0, 1.0]], grid=grid)
    with pytest.warns(UserWarning, match=r"tension"):
        wl.lamp_forces(c, r, np.diag([2.0, -1.0, 1.0]))


def test_rotation_lives_on_the_device_and_replays(device, rng):
    """A captured update reads the frame's rotation at replay: writing a new rotation into lamp.rotation between
    replays gives the forces of a lamp built in that frame."""
    c, r = polydisperse_scene(rng, n=150)
    c = c - 2.5
    grid = wl.LampGrid([-4.0] * 3, [4.0] * 3, 0.125)
    rot = rotation_xyz(0.2, 0.3, 0.4)
    turned = wl.LampGrid([-4.0] * 3, [4.0] * 3, 0.125, rotation=rot)
    lamp = wl.ShiningLamp(grid, device=device)
    pos, rad = device_arrays(c, r, device)
    forces = wp.zeros(len(r), dtype=wp.vec3, device=device)
    lamp.apply(pos, rad, forces, P)
    with wp.ScopedCapture(device=device) as capture:
        forces.zero_()
        lamp.apply(pos, rad, forces, P)
    lamp.rotation.assign(np.array([rot], dtype=np.float32))
    lamp.origin.assign(np.array([turned.world_origin], dtype=np.float32))
    wp.capture_launch(capture.graph)
    other = wl.ShiningLamp(turned, device=device)
    expected = wp.zeros(len(r), dtype=wp.vec3, device=device)
    other.apply(pos, rad, expected, P)
    np.testing.assert_array_equal(forces.numpy(), expected.numpy())


def test_frame_averaging_is_deterministic_balanced_and_reduces_direction_error(device):
    """frames=K: the orientations are fixed (the same K frames every call, nested), the averaged float64 forces
    balance exactly, and on the SphereTest specimen the mean angle between the outer particles' forces and the
    inward radial direction falls from 1 frame to 8 by more than a third (measured 15.5 to 7.5 degrees at 4 cells
    per diameter) while the summed load stays that of one frame; ShiningLamp(frames=K) adds lamp_forces(frames=K) to
    float32 rounding."""
    r4 = lamp_frame_rotations(4)
    np.testing.assert_array_equal(lamp_frame_rotations(8)[:4], r4)
    np.testing.assert_array_equal(r4[0], np.eye(3))
    s = scene_sphere_specimen()
    c, r = s.centers, s.radii
    outer = np.linalg.norm(c, axis=1) > s.radius - 3 * r.mean()
    angles, load = {}, {}
    for k in (1, 8):
        f = wl.lamp_forces(c, r, P, frames=k, cells_per_diameter=4, device=device)
        np.testing.assert_array_equal(f.sum(axis=0), [0.0, 0.0, 0.0])
        load[k] = np.linalg.norm(f, axis=1).sum()
        lit = (np.linalg.norm(f, axis=1) > 0) & outer
        radial = -c[lit] / np.linalg.norm(c[lit], axis=1)[:, None]
        cosine = np.sum(f[lit] * radial, axis=1) / np.linalg.norm(f[lit], axis=1)
        angles[k] = np.degrees(np.arccos(np.clip(cosine, -1, 1))).mean()
    assert angles[8] < 0.67 * angles[1], angles
    assert abs(load[8] / load[1] - 1.0) < 0.05, load  # an average of K frames, each weighted 1/K: the same load
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=2)
    lamp = wl.ShiningLamp(grid, frames=3, device=device)
    pos, rad = device_arrays(c, r, device)
    forces = wp.zeros(len(r), dtype=wp.vec3, device=device)
    lamp.apply(pos, rad, forces, P)
    expected = wl.lamp_forces(c, r, P, grid=grid, frames=3, device=device)
    np.testing.assert_allclose(forces.numpy(), expected, rtol=1e-5, atol=1e-6 * np.abs(expected).max())
    assert lamp.counts_numpy().shape == (3, len(r), 3)


def test_cpu_and_cuda_bitwise_equal_in_a_rotated_frame(cuda_device, rng):
    """Owners, counts and forces in a rotated frame are bitwise the same on CUDA as on the CPU."""
    c, r = polydisperse_scene(rng, n=2000, extent=10.0)
    rot = rotation_xyz(0.1, 0.2, 0.3)
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=6, rotation=rot)
    a = wl.lamp_forces(c, r, P, grid=grid, device="cpu")
    b = wl.lamp_forces(c, r, P, grid=grid, device=cuda_device)
    assert a.tobytes() == b.tobytes()
    pos_c, rad_c = device_arrays(c, r, "cpu")
    pos_g, rad_g = device_arrays(c, r, cuda_device)
    out = []
    for dev, pos, rad in (("cpu", pos_c, rad_c), (cuda_device, pos_g, rad_g)):
        lamp = wl.ShiningLamp(grid, device=dev)
        f = wp.zeros(len(r), dtype=wp.vec3, device=dev)
        lamp.apply(pos, rad, f, P)
        out.append(f.numpy())
    np.testing.assert_array_equal(out[0], out[1])
