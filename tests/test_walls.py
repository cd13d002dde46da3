"""Walls that bound the fluid (issue 19, part 2): a ray stops at a wall, which takes the reaction."""

import numpy as np
import pytest
import warp as wp
from helpers import device_arrays, polydisperse_scene

import warp_lamp as wl
from warp_lamp.lamp import lamp_update
from warp_lamp.reference import lamp_reference
from warp_lamp.scenes import scene_lattice_box

P = 2e6


def block_on_platen(rng, n=6):
    """A jittered cubic block of n^3 spheres resting on a platen at z = 0 (its lowest sphere touches it)."""
    scene = scene_lattice_box(n, spacing=1.0, jitter=0.05, seed=int(rng.integers(1 << 30)))
    c, r = scene.centers.copy(), scene.radii.copy()
    c[:, 2] -= (c[:, 2] - r).min()
    return c, r


@pytest.mark.parametrize("criterion", [0, 1])
def test_a_wall_under_the_whole_body_equals_the_lamps_without_minus_z(device, rng, criterion):
    """The memo's mode: a platen under the whole body gives bitwise the forces of the five lamps without -z."""
    c, r = block_on_platen(rng)
    platen = [((0.0, 0.0, -0.25), (0.0, 0.0, 1.0))]
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4)
    with_wall = wl.lamp_forces(c, r, P, grid=grid, criterion=criterion, walls=platen, device=device)
    five = wl.lamp_forces(c, r, P, grid=grid, criterion=criterion, lamps=["-x", "+x", "-y", "+y", "+z"], device=device)
    np.testing.assert_array_equal(with_wall, five)
    # ShiningLamp on world positions, the walls placed on the device, gives the same float64 forces.
    lamp = wl.ShiningLamp(grid, criterion=criterion, walls=platen, device=device)
    lamp.update(*device_arrays(c, r, device))
    np.testing.assert_array_equal(lamp.forces_numpy(P), five)


def test_the_platen_takes_what_the_top_lamp_does_not_give_the_body(device, rng):
    """Balance in integer counts: x and y sum to zero; on z, body plus platen take the whole top window."""
    c, r = block_on_platen(rng)
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4)
    lamp = lamp_update(c, r, grid=grid, walls=[((0.0, 0.0, -0.25), (0.0, 0.0, 1.0))], device=device)
    d = lamp.diagnostics(c, P)
    counts, walls = d.counts, d.wall_counts
    assert counts[:, 0].sum() == 0 and counts[:, 1].sum() == 0
    assert (walls[:, :2] == 0).all()
    top_window = int(grid.counts[2].prod())
    assert counts[:, 2].sum() + walls[:, 2].sum() == -top_window
    assert walls[0, 2] < 0  # the platen is pushed down where the top lamp misses the body
    # Forces: body and platen together carry exactly -P times the window on z.
    total = d.force + d.wall_forces.sum(axis=0)
    assert total[0] == 0.0 and total[1] == 0.0
    assert total[2] == pytest.approx(-P * top_window * grid.cell_area[2], rel=1e-7)


def test_fluid_bounded_below_at_mid_height_loads_nothing_under_it(device, rng):
    """Particles wholly below a wall at mid-height carry nothing; those above are loaded from every side."""
    c, r = block_on_platen(rng)
    z_w = 0.5 * (c[:, 2].min() + c[:, 2].max())
    f = wl.lamp_forces(c, r, P, walls=[((0.0, 0.0, z_w), (0.0, 0.0, 1.0))], device=device)
    below = c[:, 2] + r < z_w
    above = c[:, 2] - r > z_w
    assert below.sum() > 20 and above.sum() > 20
    assert (f[below] == 0).all()
    assert np.abs(f[above]).sum(axis=1).astype(bool).sum() > 0.3 * above.sum()


@pytest.mark.parametrize("criterion", [0, 1])
def test_walls_match_the_float64_reference(device, rng, criterion):
    """Owners, wall owners and counts equal the float64 reference on random scenes with tilted walls."""
    c, r = polydisperse_scene(rng, n=120)
    walls = [((2.5, 2.5, 1.5), (0.2, -0.1, 1.0)), ((4.0, 1.0, 2.0), (-1.0, 0.3, 0.2))]
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3)
    lamp = lamp_update(c, r, grid=grid, criterion=criterion, walls=walls, device=device)
    planes = wl.validate.check_walls(walls)
    ref = lamp_reference(c, r, grid, criterion=criterion, walls=planes)
    d = lamp.diagnostics()
    ambiguous = sum(int(a.sum()) for a in ref.ambiguous.values())
    for name in wl.LAMPS:
        ok = ~ref.ambiguous[name]
        np.testing.assert_array_equal(d.owners[name][ok], ref.owners[name][ok])
        np.testing.assert_array_equal(d.wall_owners[name][ok], ref.wall_owners[name][ok])
    if ambiguous == 0:
        np.testing.assert_array_equal(d.counts, ref.counts)
        np.testing.assert_array_equal(d.wall_counts, ref.wall_counts)
    assert (ref.wall_counts != 0).any()  # the walls take something
    assert np.abs(d.wall_counts - ref.wall_counts).sum() <= ambiguous


def test_rotated_grid_and_moving_walls_on_the_device(device, rng):
    """A turned lamp frame and walls overwritten between updates: on each frame axis (each cut by the tilted wall),
    body and wall counts sum to the whole window of the one lamp whose rays start in the fluid."""
    c, r = polydisperse_scene(rng, n=150)
    q = np.array([0.1, 0.2, 0.3, 0.927])
    R = wl.validate.lamp_rotation(q / np.linalg.norm(q))
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3, rotation=R)
    walls = [((0.0, 0.0, 1.0), (0.0, 0.0, 1.0))]
    lamp = wl.ShiningLamp(grid, walls=walls, device=device)
    pos, rad = device_arrays(c, r, device)
    lamp.update(pos, rad)
    first = lamp.diagnostics(c, P)
    # Raise the wall by overwriting its plane on the device (what a simulator does to move a platen).
    lamp.walls.assign(np.array([[0.0, 0.0, 1.0, 2.5]], dtype=np.float32))
    lamp.update(pos, rad)
    second = lamp.diagnostics(c, P)
    assert (second.counts != first.counts).any()
    n_frame = R.T @ np.array([0.0, 0.0, 1.0])
    for d in (first, second):
        total = d.counts.sum(axis=0) + d.wall_counts.sum(axis=0)
        # The low lamp (from minus infinity) starts in the fluid where the wall's normal points against its rays.
        want = [-np.sign(n_frame[a]) * int(grid.counts[a].prod()) for a in range(3)]
        np.testing.assert_array_equal(total, want)
    below = c[:, 2] + r < 2.5
    assert (lamp.forces_numpy(P)[below] == 0).all()


@pytest.mark.parametrize(
    ("walls", "match"),
    [
        ([((0, 0, 0), (0, 0, 0))], r"walls: wall 0 has a zero normal"),
        ([((0, 0, np.nan), (0, 0, 1))], r"walls: wall 0 has a non-finite value"),
        ([((0, 0), (0, 0, 1))], r"walls: wall 0 .*\(point, normal\) pair"),
        ("floor", r"walls: expected a sequence"),
        ([((0, 0, 0), (0, 0, 1))] * 9, r"walls: at most 8 walls"),
    ],
)
def test_bad_walls_are_refused_by_name(walls, match):
    """Zero or NaN normals, wrong shapes and too many walls raise ValueError naming ``walls``."""
    c = np.zeros((1, 3))
    with pytest.raises(ValueError, match=match):
        wl.lamp_forces(c, 0.5, P, walls=walls, device="cpu")


def test_walls_in_a_captured_graph(device, rng):
    """The walls' placement records into a graph: a replay after moving the wall equals an eager update."""
    c, r = block_on_platen(rng, n=4)
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4)
    lamp = wl.ShiningLamp(grid, walls=[((0, 0, -0.25), (0, 0, 1))], device=device)
    pos, rad = device_arrays(c, r, device)
    forces = wp.zeros(len(r), dtype=wp.vec3, device=device)
    pressure = wp.array([P], dtype=wp.float32, device=device)
    lamp.apply(pos, rad, forces, pressure)
    with wp.ScopedCapture(device=device) as capture:
        forces.zero_()
        lamp.apply(pos, rad, forces, pressure)
    lamp.walls.assign(np.array([[0.0, 0.0, 1.0, 1.7]], dtype=np.float32))
    wp.capture_launch(capture.graph)
    replay = forces.numpy()
    eager = wl.ShiningLamp(grid, walls=[((0, 0, 1.7), (0, 0, 1))], device=device)
    out = wp.zeros(len(r), dtype=wp.vec3, device=device)
    eager.apply(pos, rad, out, pressure)
    np.testing.assert_array_equal(replay, out.numpy())
