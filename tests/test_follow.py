"""A lamp grid that follows its body inside a captured graph (ShiningLamp(follow=True))."""

import numpy as np
import pytest
import warp as wp
from helpers import device_arrays, polydisperse_scene

import warp_lamp as wl

P = 1.0e5


@wp.kernel
def translate(step: wp.vec3, positions: wp.array[wp.vec3]):
    i = wp.tid()
    positions[i] = positions[i] + step


def body(rng, n=120):
    """Particles on a 1/64 lattice (so that float32 positions minus a whole-cell origin are exact), radii ~0.25."""
    c, r = polydisperse_scene(rng, n=n, extent=2.0, rmin=0.15, rmax=0.3)
    return np.round(c * 64) / 64, r


@pytest.mark.parametrize(
    "options", [{}, {"criterion": 0}, {"criterion": "area"}, {"surfaces": "all", "probe_radius": 0.15}], ids=str
)
def test_body_translating_ten_diameters_matches_a_grid_at_the_same_origin(device, rng, options):
    """200 captured steps move the body 10 diameters: after every replay the lamp's frame origin has moved by
    whole cells, no particle is outside, and the forces equal lamp_forces on those positions with a grid at that
    origin, bitwise (float32), for criteria 1, 0 and area and the wetted surface."""
    c, r = body(rng)
    h = 0.125
    grid = wl.LampGrid([-1.0] * 3, [3.0] * 3, h)  # capacity 32^3 cells, the body about 2.5 across
    lamp = wl.ShiningLamp(grid, follow=True, device=device, **options)
    pos, rad = device_arrays(c, r, device)
    forces = wp.zeros(len(r), dtype=wp.vec3, device=device)
    step = wp.vec3(0.025, -0.0125, 0.0375)  # 200 steps: |path| = 9.4 ~ 10 mean diameters (0.45)
    lamp.apply(pos, rad, forces, P)
    with wp.ScopedCapture(device=device) as capture:
        wp.launch(translate, dim=len(r), inputs=[step], outputs=[pos], device=device)
        forces.zero_()
        lamp.apply(pos, rad, forces, P)
    shifts = set()
    for k in range(200):
        wp.capture_launch(capture.graph)
        if k % 20 == 19 or k < 3:
            x = pos.numpy().astype(np.float64)
            origin = lamp.frame_origin()
            shifts.add(tuple(np.round((origin - grid.origin) / h).astype(int)))
            same = wl.LampGrid(origin, origin + 32 * h, h)
            expected = wl.lamp_forces(x, r, P, grid=same, device=device, **options)
            np.testing.assert_array_equal(forces.numpy(), expected.astype(np.float32), err_msg=f"step {k}")
            assert lamp.diagnostics().outside == 0
    assert len(shifts) > 5  # the grid did move, many times


def test_growing_body_past_capacity_is_counted_and_balanced(device, rng):
    """A body that grows past the grid's capacity: while it fits with a cell to spare nothing is outside; once it
    is larger than the capacity the overflow is counted as outside; the forces always sum to zero; no crash."""
    c, r = body(rng)
    h, capacity = 0.125, 3.0
    grid = wl.LampGrid([-1.0] * 3, [-1.0 + capacity] * 3, h)
    lamp = wl.ShiningLamp(grid, follow=True, device=device)
    for scale in (1.0, 1.1, 1.5, 3.0):
        x, rr = (c - 1.0) * scale, r * scale
        extent = (np.max(x + rr[:, None], axis=0) - np.min(x - rr[:, None], axis=0)).max()
        pos, rad = device_arrays(x, rr, device)
        lamp.update(pos, rad)
        d = lamp.diagnostics(pressure=P)
        np.testing.assert_array_equal(d.counts.sum(axis=0), [0, 0, 0])
        np.testing.assert_array_equal(d.force, [0.0, 0.0, 0.0])
        if extent <= capacity - h:
            assert d.outside == 0, (scale, extent)
        if extent > capacity:
            assert d.outside > 0, (scale, extent)


def test_follow_needs_the_box_form_and_refuses_frames():
    """follow=True with a memo-form grid, or with frame averaging, is refused by name."""
    memo = wl.LampGrid.from_grids(np.zeros((3, 2)), np.ones((3, 2)), [[2, 2], [2, 3], [2, 2]])
    with pytest.raises(ValueError, match=r"follow: needs the box form"):
        wl.ShiningLamp(memo, follow=True, device="cpu")
    with pytest.raises(ValueError, match=r"frames: frame averaging with follow=True"):
        wl.ShiningLamp(wl.LampGrid([0, 0, 0], [1, 1, 1], 0.25), follow=True, frames=2, device="cpu")


def test_follow_is_bitwise_the_same_on_cpu_and_cuda(cuda_device, rng):
    """The following grid's shifts and forces are bitwise the same on CUDA as on the CPU."""
    c, r = body(rng)
    grid = wl.LampGrid([-1.0] * 3, [3.0] * 3, 0.125)
    out = []
    for dev in ("cpu", cuda_device):
        lamp = wl.ShiningLamp(grid, follow=True, device=dev)
        pos, rad = device_arrays(c + 0.7, r, dev)
        forces = wp.zeros(len(r), dtype=wp.vec3, device=dev)
        lamp.apply(pos, rad, forces, P)
        out.append((lamp.frame_origin(), forces.numpy()))
    np.testing.assert_array_equal(out[0][0], out[1][0])
    np.testing.assert_array_equal(out[0][1], out[1][1])
