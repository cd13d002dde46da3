"""Walls that bound the fluid: the fluid between a wall and the body pushes both, sealed where the wall crosses the
body or the body rests on it (memo's mode); the probe kept off the walls (wetted mode)."""

import numpy as np
import pytest
import warp as wp
from helpers import device_arrays, polydisperse_scene

import warp_lamp as wl
from warp_lamp.lamp import lamp_update
from warp_lamp.reference import lamp_reference
from warp_lamp.reference.wetted import frame_walls
from warp_lamp.scenes import scene_box_specimen, scene_lattice_box

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
    platen = [((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))]  # the body rests on it
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
    lamp = lamp_update(c, r, grid=grid, walls=[((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))], device=device)
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


# --- the wetted mode (surfaces="all") -------------------------------------------------------------------------


def footprint_area(centers, radii, pixels=2000):
    """The body's footprint on a platen normal to z [m^2]: the area of the union of the particles' disks projected
    along z, from a raster of ``pixels`` cells along the longer side (pixel centres inside a disk)."""
    lo = (centers[:, :2] - radii[:, None]).min(axis=0)
    hi = (centers[:, :2] + radii[:, None]).max(axis=0)
    step = float((hi - lo).max()) / pixels
    xs = lo[0] + (np.arange(int(np.ceil((hi[0] - lo[0]) / step))) + 0.5) * step
    ys = lo[1] + (np.arange(int(np.ceil((hi[1] - lo[1]) / step))) + 0.5) * step
    cover = np.zeros((len(xs), len(ys)), dtype=bool)
    for (cx, cy), r in zip(centers[:, :2], radii, strict=True):
        i0, i1 = np.searchsorted(xs, [cx - r, cx + r])
        j0, j1 = np.searchsorted(ys, [cy - r, cy + r])
        dx, dy = xs[i0:i1, None] - cx, ys[None, j0:j1] - cy
        cover[i0:i1, j0:j1] |= dx * dx + dy * dy < r * r
    return float(cover.sum()) * step * step


def test_wetted_box_on_a_platen(device):
    """The issue's random 50 mm box resting on a platen at 2 MPa, wetted mode with rho = the mean radius: the body's
    Fx and Fy are exactly 0, its Fz is within 3% of -P times its footprint, and on z the body and the platen together
    take exactly -P times the whole window (every ray's top end faces the fluid, its bottom end is in the platen)."""
    scene = scene_box_specimen((0.05, 0.05, 0.05), 0.005)
    c, r = scene.centers, scene.radii
    rho = float(r.mean())
    platen = [((0.0, 0.0, float((c[:, 2] - r).min())), (0.0, 0.0, 1.0))]
    lamp = lamp_update(c, r, surfaces="all", probe_radius=rho, walls=platen, device=device)
    d = lamp.diagnostics(c, P)
    assert d.force[0] == 0.0 and d.force[1] == 0.0
    ratio = d.force[2] / (-P * footprint_area(c, r))
    assert abs(ratio - 1.0) < 0.03, ratio
    window = int(lamp.grid.counts[2].prod())
    np.testing.assert_array_equal(d.counts.sum(axis=0) + d.wall_counts.sum(axis=0), [0, 0, -window])
    assert (d.wall_counts[:, :2] == 0).all() and d.unattributed == 0
    total = d.force + d.wall_forces.sum(axis=0)
    assert total[2] == pytest.approx(-P * window * lamp.grid.cell_area[2], rel=1e-7)
    # Without the platen (the README's old recipe: the -z lamp off) the side faces' downward pushes overload z.
    no_wall = wl.lamp_forces(c, r, P, surfaces="all", probe_radius=rho, lamps=["-x", "+x", "-y", "+y", "+z"])
    assert no_wall[:, 2].sum() / (-P * footprint_area(c, r)) > 1.15


def test_wetted_fluid_bounded_below_at_mid_height(device, rng):
    """A fluid bounded below at mid-height (a jittered block and the 50 mm random box): particles wholly below the
    wall carry nothing, also where a fillet's crossing lies nearer to them than to any particle above (a sphere
    wholly inside a wall is part of it); most of those wholly above are loaded; x and y still balance exactly."""
    box = scene_box_specimen((0.05, 0.05, 0.05), 0.005)
    for c, r in (block_on_platen(rng), (box.centers, box.radii)):
        z_w = 0.5 * (c[:, 2].min() + c[:, 2].max())
        wall = [((0.0, 0.0, z_w), (0.0, 0.0, 1.0))]
        f = wl.lamp_forces(c, r, P, surfaces="all", probe_radius=float(r.mean()), walls=wall, device=device)
        below = c[:, 2] + r < z_w
        above = c[:, 2] - r > z_w
        assert below.sum() > 20 and above.sum() > 20
        assert (f[below] == 0).all()
        assert np.abs(f[above]).sum(axis=1).astype(bool).sum() > 0.3 * above.sum()
        assert f[:, 0].sum() == 0.0 and f[:, 1].sum() == 0.0 and f[:, 2].sum() < 0.0


def test_wetted_walls_leave_the_axis_they_do_not_cut_balanced(device, rng):
    """A platen (normal z) and a side wall (normal x) in the wetted mode: on y, which neither cuts, the particles'
    counts sum to exactly zero and the walls take nothing; on x and z, particles and walls together take exactly the
    rays whose far end faces the fluid (their near end is in a wall)."""
    c, r = block_on_platen(rng)
    rho = float(r.mean())
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4, probe_radius=rho)
    walls = [((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)), (((c[:, 0] - r).min() - 0.2, 0.0, 0.0), (1.0, 0.0, 0.0))]
    lamp = lamp_update(c, r, grid=grid, surfaces="all", probe_radius=rho, walls=walls, device=device)
    d = lamp.diagnostics()
    counts, by_wall = d.counts.sum(axis=0), d.wall_counts
    assert counts[1] == 0 and (by_wall[:, 1] == 0).all() and d.unattributed == 0
    assert (by_wall[0] != 0).tolist() == [False, False, True] and (by_wall[1] != 0).tolist() == [True, False, False]
    # The far ends: x rows end in the fluid where they pass above the platen, z rows where they pass the side wall.
    planes = frame_walls(wl.validate.check_walls(walls), grid)
    h = grid.box_cell
    n = grid.box_counts
    zs = (np.arange(n[2]) + 0.5) * h[2]
    xs = (np.arange(n[0]) + 0.5) * h[0]
    fluid_x_rows = int(n[1]) * int((zs - planes[0, 3] >= 0.0).sum())
    fluid_z_rows = int(n[1]) * int((xs - planes[1, 3] >= 0.0).sum())
    assert counts[0] + by_wall[:, 0].sum() == -fluid_x_rows
    assert counts[2] + by_wall[:, 2].sum() == -fluid_z_rows


def test_wetted_walls_on_the_device_in_a_captured_graph(device, rng):
    """ShiningLamp(surfaces='all') on world positions places the walls on the device: its forces equal those of
    host positions placed in float64 (an axis-aligned platen, exact in float32), and a graph replay after moving the
    platen equals an eager lamp built with it there."""
    c, r = block_on_platen(rng, n=4)
    rho = float(r.mean())
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4, probe_radius=rho)
    platen = [((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))]  # the body rests on it
    host = wl.lamp_forces(c, r, P, grid=grid, surfaces="all", probe_radius=rho, walls=platen, device=device)
    lamp = wl.ShiningLamp(grid, surfaces="all", probe_radius=rho, walls=platen, device=device)
    pos, rad = device_arrays(c, r, device)
    lamp.update(pos, rad)
    np.testing.assert_array_equal(lamp.forces_numpy(P), host)
    forces = wp.zeros(len(r), dtype=wp.vec3, device=device)
    pressure = wp.array([P], dtype=wp.float32, device=device)
    with wp.ScopedCapture(device=device) as capture:
        forces.zero_()
        lamp.apply(pos, rad, forces, pressure)
    lamp.walls.assign(np.array([[0.0, 0.0, 1.0, 1.75]], dtype=np.float32))
    wp.capture_launch(capture.graph)
    replay = forces.numpy()
    walls_replay = lamp.wall_forces_numpy(P)
    eager = wl.ShiningLamp(grid, surfaces="all", probe_radius=rho, walls=[((0, 0, 1.75), (0, 0, 1))], device=device)
    out = wp.zeros(len(r), dtype=wp.vec3, device=device)
    eager.apply(pos, rad, out, pressure)
    np.testing.assert_array_equal(replay, out.numpy())
    np.testing.assert_array_equal(walls_replay, eager.wall_forces_numpy(P))
    assert (replay[c[:, 2] + r < 1.75] == 0).all() and np.abs(replay).sum() > 0


def test_walls_with_the_area_criterion_are_refused_with_the_reason():
    """The area criterion with walls is refused naming ``walls`` and why (its per-cell payout balances both
    lamps); the wetted mode takes them."""
    with pytest.raises(ValueError, match=r"walls: .*not with criterion='area': its per-cell payout balances"):
        wl.ShiningLamp(wl.LampGrid([0, 0, 0], [1, 1, 1], 0.25), criterion="area", walls=[((0, 0, 0), (0, 0, 1))])
    wl.ShiningLamp(
        wl.LampGrid([0, 0, 0], [1, 1, 1], 0.25), surfaces="all", probe_radius=0.1, walls=[((0, 0, 0), (0, 0, 1))]
    )


def test_walls_with_frame_averaging_are_refused():
    """Frame averaging turns every lamp axis into one that cuts the wall: nothing would balance and the walls'
    reactions would need averaging in world coordinates, so `frames > 1` with walls is refused by name (it used to
    run, with unbalanced sideways forces and no wall force reported)."""
    c = np.array([[0.0, 0.0, 0.5], [1.0, 0.0, 0.5]])
    r = np.array([0.5, 0.5])
    grid = wl.LampGrid.enclosing(c, r)
    with pytest.raises(ValueError, match="walls: not with frame averaging"):
        wl.ShiningLamp(grid, frames=4, walls=[((0, 0, 0), (0, 0, 1))], device="cpu")
    with pytest.raises(ValueError, match="walls: not with frame averaging"):
        wl.lamp_forces(c, r, 1e6, frames=4, walls=[((0, 0, 0), (0, 0, 1))], device="cpu")


# --- one rule in the memo's mode: every case against a value from the geometry ------------------------------------

R = 1.0
ONE = (np.zeros((1, 3)), np.array([R]))


def one_sphere(walls, device, *, cells_per_diameter=32):
    """The force on one sphere of radius R at the origin and the lamp's diagnostics (P = 1)."""
    c, r = ONE
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=cells_per_diameter)
    lamp = lamp_update(c, r, grid=grid, walls=walls, device=device)
    return lamp.forces_numpy(1.0)[0], lamp.diagnostics(c, 1.0), grid


def assert_walls_balance(d, grid, cut_sign, pressure=1.0):
    """Body plus walls per axis: 0 on an axis no wall cuts, -sign(n_a) P times the window where one wall cuts it
    (``cut_sign[a]``: +1 fluid above the wall along a, -1 below, 0 uncut), in counts and in forces."""
    total = d.counts.sum(axis=0) + d.wall_counts.sum(axis=0)
    window = grid.counts.prod(axis=1)
    np.testing.assert_array_equal(total, -np.asarray(cut_sign) * window)
    forces = d.force + d.wall_forces.sum(axis=0)
    want = -pressure * np.asarray(cut_sign) * window * grid.cell_area
    np.testing.assert_allclose(forces, want, rtol=1e-7, atol=0)  # P A rounded to 26 bits


def test_a_sphere_clear_of_a_wall_is_wet_all_round(device):
    """A sphere one radius above a floor: the fluid fills the gap, so it carries exactly 0 and the floor P x window."""
    f, d, grid = one_sphere([((0.0, 0.0, -2.0 * R), (0.0, 0.0, 1.0))], device)
    np.testing.assert_array_equal(f, 0.0)
    assert_walls_balance(d, grid, [0, 0, 1])
    assert d.wall_forces[0, 2] == pytest.approx(-grid.cell_area[2] * grid.counts[2].prod(), rel=1e-7)


def test_a_distant_wall_changes_no_force(device, rng):
    """300 random spheres with a floor 1,000 km below: bitwise the forces without it."""
    c, r = rng.uniform(0.0, 10.0, (300, 3)), rng.uniform(0.3, 0.8, 300)
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4)
    free = wl.lamp_forces(c, r, P, grid=grid, device=device)
    lamp = lamp_update(c, r, grid=grid, walls=[((0.0, 0.0, -1e6), (0.0, 0.0, 1.0))], device=device)
    np.testing.assert_array_equal(lamp.forces_numpy(P), free)
    assert_walls_balance(lamp.diagnostics(c, P), grid, [0, 0, 1], P)


def test_a_closed_vessel_leaves_the_body_as_without_walls(device):
    """Six walls 0.15 outside a ball of spheres: the body's forces are bitwise those without walls, and each wall is
    pushed outward by P times its axis's window."""
    ball = wl.scenes.scene_lattice_ball(diameter=2.0, particle_diameter=0.5)
    c, r = ball.centers, ball.radii
    lo, hi = (c - r[:, None]).min(axis=0) - 0.15, (c + r[:, None]).max(axis=0) + 0.15
    walls = []
    for a in range(3):
        e = np.eye(3)[a]
        walls += [(lo[a] * e, e), (hi[a] * e, -e)]
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4)
    free = wl.lamp_forces(c, r, P, grid=grid, device=device)
    lamp = lamp_update(c, r, grid=grid, walls=walls, device=device)
    np.testing.assert_array_equal(lamp.forces_numpy(P), free)
    d = lamp.diagnostics(c, P)
    for a in range(3):
        # The window facing the fluid: the cell-centre rays inside the vessel's cross-section.
        u, v = (a + 1) % 3, (a + 2) % 3
        (cu, cv), (hu, hv), (nu, nv) = grid.corner[a], grid.cell[a], grid.counts[a]
        pu, pv = cu + (np.arange(nu) + 0.5) * hu, cv + (np.arange(nv) + 0.5) * hv
        inside = ((pu > lo[u]) & (pu < hi[u])).sum() * ((pv > lo[v]) & (pv < hi[v])).sum()
        window = P * grid.cell_area[a] * inside
        assert 0 < inside < nu * nv
        np.testing.assert_allclose(
            d.wall_forces[2 * a], -window * np.eye(3)[a], rtol=1e-7, atol=0
        )  # P A rounded to 26 bits
        np.testing.assert_allclose(
            d.wall_forces[2 * a + 1], window * np.eye(3)[a], rtol=1e-7, atol=0
        )  # P A rounded to 26 bits


@pytest.mark.parametrize("level", [-0.5, 0.5])
def test_a_fluid_level_through_a_sphere_loads_its_wet_cap(device, level):
    """Fluid above z = h through a sphere: Fz = -P pi (R^2 - h^2), the section at the level (the wet cap's
    projection); x and y balance; body plus level take P times the window on z."""
    f, d, grid = one_sphere([((0.0, 0.0, level * R), (0.0, 0.0, 1.0))], device)
    assert f[0] == 0.0 and f[1] == 0.0
    assert f[2] == pytest.approx(-np.pi * (R * R - (level * R) ** 2), rel=0.015)
    assert_walls_balance(d, grid, [0, 0, 1])


def test_a_tilted_wall_through_the_centre_loads_the_half_sphere(device):
    """A wall through the centre with normal n = (1, 1, 1)/sqrt(3): the wet hemisphere carries -P pi R^2 n (the cut
    disk's area along n), on every axis the wall cuts; body plus wall take P times each window."""
    n = np.ones(3) / np.sqrt(3.0)
    f, d, grid = one_sphere([((0.0, 0.0, 0.0), tuple(n))], device)
    np.testing.assert_allclose(f, -np.pi * R * R * n, rtol=0.015)
    assert_walls_balance(d, grid, [1, 1, 1])


def test_huge_and_tiny_normals_are_the_same_wall(device):
    """Normals (1e200, 0, 1e200) and (1e-200, 0, 1e-200) are the direction (1, 0, 1): the same plane and forces."""
    want = wl.validate.check_walls([((0, 0, 0), (1.0, 0.0, 1.0))])
    np.testing.assert_allclose(want[0, :3], [2**-0.5, 0.0, 2**-0.5], rtol=1e-15)
    f, _, _ = one_sphere([((0, 0, 0), (1.0, 0.0, 1.0))], device, cells_per_diameter=8)
    for scale in (1e200, 1e-200):
        planes = wl.validate.check_walls([((0, 0, 0), (scale, 0.0, scale))])
        np.testing.assert_array_equal(planes, want)
        g, d, grid = one_sphere([((0, 0, 0), (scale, 0.0, scale))], device, cells_per_diameter=8)
        np.testing.assert_array_equal(g, f)
        assert_walls_balance(d, grid, [1, 0, 1])


def test_every_particle_behind_the_walls_warns(device):
    """A platen with its normal pointing out of the fluid leaves every particle behind it: a warning naming it."""
    c, r = ONE
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=8)
    with pytest.warns(UserWarning, match=r"every particle lies behind wall\(s\) \[0\]"):
        lamp = lamp_update(c, r, grid=grid, walls=[((0.0, 0.0, -R), (0.0, 0.0, -1.0))], device=device)
    np.testing.assert_array_equal(lamp.forces_numpy(P), 0.0)
    assert_walls_balance(lamp.diagnostics(c, 1.0), grid, [0, 0, -1])  # the fluid below pushes the wall up


@pytest.mark.parametrize("lift", [0.0, -0.05, 0.5, 1.0, 2.0])
def test_a_body_rests_on_a_platen_or_the_fluid_gets_under_it(device, rng, lift):
    """A block on a platen (lift 0, or a DEM overlap of 0.05 r): sealed, the body takes -P times every ray the top
    lamp lights on it; lifted by 0.5, 1 or 2 radii: the fluid fills the gap, the body's z counts sum to exactly 0,
    and the platen takes the whole window."""
    c, r = block_on_platen(rng, n=4)
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=4, margin=3.0)
    rho = r[np.argmin(c[:, 2] - r)]
    lamp = lamp_update(c, r, grid=grid, walls=[((0.0, 0.0, -lift * rho), (0.0, 0.0, 1.0))], device=device)
    d = lamp.diagnostics(c, P)
    body_rays = int((d.owners["+z"] >= 0).sum())
    window = int(grid.counts[2].prod())
    if lift <= 0.0:
        assert d.counts[:, 2].sum() == -body_rays and d.wall_counts[0, 2] == -(window - body_rays)
    else:
        assert d.counts[:, 2].sum() == 0 and d.wall_counts[0, 2] == -window
    assert_walls_balance(d, grid, [0, 0, 1], P)


def test_a_platen_moved_through_the_engine_lamp_is_honoured(device, rng):
    """lamp.walls overwritten between EngineLamp calls (positions in the frame, float64 on the host): each call
    equals lamp_forces with the moved platen: lifted (the body unloaded on z), resting or cutting the bottom layer."""
    from warp_lamp.engines.core import EngineLamp

    c, r = block_on_platen(rng, n=4)
    engine = EngineLamp(c, r, P, device=device, walls=[((0.0, 0.0, -1.0), (0.0, 0.0, 1.0))])
    for z in (-1.0, -0.5, 0.0, 0.4):
        engine.lamp.walls.assign(np.array([[0.0, 0.0, 1.0, z]], dtype=np.float32))
        f = engine.forces(c)
        want = wl.lamp_forces(c, r, P, grid=engine.grid, walls=[((0.0, 0.0, z), (0.0, 0.0, 1.0))], device=device)
        np.testing.assert_array_equal(f, want)
        assert (f[:, 2].sum() < 0) == (z >= 0.0)  # lifted: wet underneath; resting or cut: sealed


def test_engine_lamp_with_follow_places_the_walls_where_the_body_is(device, rng):
    """EngineLamp with follow=True passes positions relative to a reference point: its walls move with them, so a
    platen under a body far from the origin seals it as the in-frame path does (the walls were left in world
    coordinates, putting the platen the reference's height away)."""
    from warp_lamp.engines.core import EngineLamp

    c, r = block_on_platen(rng, n=4)
    c += np.array([40.0, -25.0, 60.0])  # the platen at z = 60
    platen = [((0.0, 0.0, 60.0), (0.0, 0.0, 1.0))]
    fz = {}
    for follow in (False, True):
        engine = EngineLamp(c, r, P, device=device, follow=follow, walls=platen)
        fz[follow] = engine.forces(c)[:, 2].sum()
    # A 4 x 4 block of unit spacing resting on the platen takes -P times its silhouette: the 16 unit squares less
    # the gaps between the disks (0.77 of them at radius 0.5 with jitter)
    assert -0.85 * P * 16 < fz[False] < -0.6 * P * 16
    assert abs(fz[True] - fz[False]) <= 0.01 * abs(fz[False])


@pytest.mark.parametrize("lamps", ["all", ["-x", "+z"]])
def test_a_resting_body_and_lamp_subsets_match_the_float64_reference(device, rng, lamps):
    """A block resting on a platen with a tilted side wall, all lamps or a subset: owners, wall owners and counts
    equal the float64 reference (which decides the rest from its own float64 gaps)."""
    c, r = block_on_platen(rng, n=4)
    walls = [((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)), ((3.2, 0.0, 0.0), (-1.0, 0.2, 0.3))]
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3)
    lamp = lamp_update(c, r, grid=grid, lamps=lamps, walls=walls, device=device)
    ref = lamp_reference(c, r, grid, lamps=lamps, walls=wl.validate.check_walls(walls))
    d = lamp.diagnostics()
    assert ref.wall_counts[0, 2] != 0
    ambiguous = sum(int(a.sum()) for a in ref.ambiguous.values())
    for name in wl.LAMPS:
        ok = ~ref.ambiguous[name]
        np.testing.assert_array_equal(d.owners[name][ok], ref.owners[name][ok])
        np.testing.assert_array_equal(d.wall_owners[name][ok], ref.wall_owners[name][ok])
    assert np.abs(d.counts - ref.counts).sum() <= ambiguous
    assert np.abs(d.wall_counts - ref.wall_counts).sum() <= 2 * ambiguous


def test_the_wetted_probe_leaves_a_dry_fillet_under_a_level_below_the_equator(device):
    """Wetted mode, fluid level z = h through one sphere, probe rho = 0.06 R: below the equator the probe cannot
    wet the wedge at the wall, and Fz is the section's -(R^2 - h^2) plus the lost upward push on the dry strip,
    -2 a L |h| (a the contact radius, L = rho cot(alpha / 2), cos alpha = -h / R), to first order; above the
    equator the fillet's crossings load the sphere and Fz is the section's."""
    c, r = ONE
    rho = 0.06 * R
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=32, probe_radius=rho)
    for h in (-0.5 * R, 0.5 * R):
        walls = [((0, 0, h), (0, 0, 1))]
        lamp = lamp_update(c, r, grid=grid, surfaces="all", probe_radius=rho, walls=walls, device=device)
        fz = lamp.forces_numpy(1.0)[0, 2] / np.pi
        a, alpha = np.sqrt(R * R - h * h), np.arccos(-h / R)
        section = -(R * R - h * h)
        fillet = -2.0 * a * (rho / np.tan(alpha / 2.0)) * abs(h) if h < 0 else 0.0
        assert fillet == 0.0 or fillet < -0.08  # the fillet's term is far outside the tolerance below
        assert fz == pytest.approx(section + fillet, abs=0.015), h


def test_a_platen_far_from_the_origin_keeps_the_float64_positions_precision(device, rng):
    """A block resting on a platen 3,000 km up (float32 would move the plane by 0.24 radii, past the rest band):
    on the float64 path the body rests as at the origin and takes the same z counts."""
    c, r = block_on_platen(rng, n=4)
    shift = np.array([0.0, 0.0, 3.0e6 + 0.37])
    assert abs(float(np.float32(shift[2])) - shift[2]) > 0.2 * r.min()
    counts = []
    for offset in (np.zeros(3), shift):
        grid = wl.LampGrid.enclosing(c + offset, r, cells_per_diameter=4)
        lamp = lamp_update(c + offset, r, grid=grid, walls=[(offset, (0.0, 0.0, 1.0))], device=device)
        d = lamp.diagnostics()
        assert d.counts[:, 2].sum() == -int((d.owners["+z"] >= 0).sum())  # rests: sealed underneath
        counts.append(d.counts)
    np.testing.assert_array_equal(counts[1], counts[0])
