"""Cells that are not cubes (0.02 x 0.03 x 0.05 m), on every path that turns cells into forces or volumes.

Grid a looks along axis a and spans the two other axes, so its cell area is the product of *their* edges:
A_x = h_y h_z, A_y = h_z h_x, A_z = h_x h_y. With cubic cells every mix-up of axes gives the right answer; here
each one is off by a factor between 0.4 and 2.5. The expected values are computed by hand from the three edges.
"""

import numpy as np
import pytest
import warp as wp
from helpers import bvh_owners, device_arrays
from test_lamp import assert_matches_reference

import warp_lamp as wl
from warp_lamp.lamp import lamp_update
from warp_lamp.porosity import porosity

CELL = (0.02, 0.03, 0.05)
#: Cell area of grid a [m^2], by hand: the product of the two other axes' edges.
AREA = np.array([CELL[1] * CELL[2], CELL[2] * CELL[0], CELL[0] * CELL[1]])
PRESSURE = (3.0e6, 1.1e7, 7.0e6)  # distinct per axis, so that an axis mix-up in P shows too


def scene(rng, n=60):
    """Overlapping polydisperse spheres in [0, 0.6]^3 and a grid around them with float32-exact origin."""
    centers = rng.uniform(0.0, 0.6, (n, 3)).astype(np.float32).astype(np.float64)
    radii = rng.uniform(0.04, 0.1, n)
    grid = wl.LampGrid([-0.25, -0.25, -0.25], [0.85, 0.85, 0.85], CELL)
    return centers, radii, grid


def test_grid_cell_areas_are_the_products_of_the_transverse_edges():
    """LampGrid's per-grid cell sizes and areas follow the axes: grid a spans (a+1, a+2)."""
    grid = wl.LampGrid([0.0] * 3, [1.2] * 3, CELL)
    np.testing.assert_array_equal(grid.cell, [[CELL[1], CELL[2]], [CELL[2], CELL[0]], [CELL[0], CELL[1]]])
    np.testing.assert_allclose(grid.cell_area, AREA, rtol=1e-15)
    np.testing.assert_array_equal(grid.box_cell, CELL)
    np.testing.assert_array_equal(grid.box_counts, [60, 40, 24])


@pytest.mark.parametrize("criterion", [1, 0])
def test_lamp_forces_use_each_axis_own_cell_area(device, rng, criterion):
    """lamp_forces on anisotropic cells: owners match the float64 reference, and forces are count x P_a x A_a with
    the hand-computed areas (to the 26-bit rounding of P A)."""
    centers, radii, grid = scene(rng)
    lamp = lamp_update(centers, radii, grid=grid, criterion=criterion, device=device)
    assert_matches_reference(lamp, centers, radii, criterion=criterion)
    counts = lamp.counts_numpy()
    assert (counts != 0).sum(axis=0).min() > 10
    forces = wl.lamp_forces(centers, radii, PRESSURE, grid=grid, criterion=criterion, device=device)
    np.testing.assert_allclose(forces, counts * (np.array(PRESSURE) * AREA), rtol=3e-8, atol=0)
    np.testing.assert_array_equal(forces.sum(axis=0), 0.0)


def test_lone_sphere_load_is_pressure_times_its_disk_on_every_axis(device):
    """A lone sphere of radius 0.3 m on anisotropic cells, one lamp at a time: the load of lamp -a is P_a pi r^2
    along +a to within the counting error of 12 to 30 cells across the disk (2% allowed; measured 0.05-0.6% for
    criterion 1, under 0.07% for 'area'); with all six lamps on, it is zero."""
    r, centre = 0.3, [[0.013, -0.007, 0.021]]
    grid = wl.LampGrid([-0.45] * 3, [0.45] * 3, CELL)
    for criterion in (1, "area"):
        both = wl.lamp_forces(centre, [r], PRESSURE, grid=grid, criterion=criterion, device=device)
        np.testing.assert_array_equal(both, 0.0)
        for a in range(3):
            f = wl.lamp_forces(
                centre, [r], PRESSURE, grid=grid, criterion=criterion, lamps=[wl.LAMPS[2 * a]], device=device
            )
            assert f[0, a] > 0 and np.count_nonzero(f) == 1
            ratio = f[0, a] / (PRESSURE[a] * np.pi * r * r)
            assert abs(ratio - 1.0) < 0.02, (criterion, a, ratio)


@pytest.mark.parametrize("criterion", [1, 0, "area"])
def test_add_forces_and_apply_on_anisotropic_cells(device, rng, criterion):
    """ShiningLamp.apply and add_forces (host pressure, device pressure of 3 values) add float32(lamp_forces) on
    anisotropic cells, and lamp_forces is count x P_a x A_a / unit with the hand-computed areas."""
    centers, radii, grid = scene(rng, n=40)
    expected = wl.lamp_forces(centers, radii, PRESSURE, grid=grid, criterion=criterion, device=device)
    lamp = wl.ShiningLamp(grid, criterion=criterion, device=device)
    pos, rad = device_arrays(centers, radii, device)
    forces = wp.zeros(len(radii), dtype=wp.vec3, device=device)
    lamp.apply(pos, rad, forces, PRESSURE)
    counts = lamp.counts_numpy()
    np.testing.assert_allclose(expected, counts * (np.array(PRESSURE) * AREA / lamp.unit), rtol=3e-8, atol=0)
    np.testing.assert_array_equal(forces.numpy(), expected.astype(np.float32))
    forces.zero_()
    lamp.add_forces(forces, wp.array(PRESSURE, dtype=wp.float32, device=device))
    np.testing.assert_array_equal(forces.numpy(), expected.astype(np.float32))
    assert np.abs(expected).max() > 0


def test_porosity_on_anisotropic_cells(device, rng):
    """Porosity on 0.25 x 0.4 x 0.18 cells: the sum methods hold each sphere's whole volume (exact: 4/3 pi r^3;
    centroid: in the cell its centre is in, indexed by hand; polyhedron: its cube (2r)^3), and voxel at 16
    subdivisions is within 5e-3 of a cell of exact in every cell (measured 2.7e-3: spheres 4 to 15 sub-cells
    across) and within 0.5% of it in total, for non-overlapping spheres inside the box."""
    lower, upper, shape = np.zeros(3), np.array([1.0, 1.2, 0.9]), (4, 3, 5)
    h = (upper - lower) / shape
    centers, radii = [], []
    while len(radii) < 12:
        r = rng.uniform(0.04, 0.12)
        c = rng.uniform(lower + r, upper - r)
        if all(np.linalg.norm(c - d) > r + e for d, e in zip(centers, radii, strict=True)):
            centers.append(c)
            radii.append(r)
    centers, radii = np.array(centers), np.array(radii)
    cell_volume = np.prod(h)
    for method, volume in (("exact", 4 / 3 * np.pi * radii**3), ("polyhedron", (2 * radii) ** 3)):
        solid = (1.0 - porosity(centers, radii, lower, upper, shape, method=method, device=device)) * cell_volume
        np.testing.assert_allclose(solid.sum(), volume.sum(), rtol=1e-12)
    solid = (1.0 - porosity(centers, radii, lower, upper, shape, method="centroid", device=device)) * cell_volume
    want = np.zeros(shape)
    for c, r in zip(centers, radii, strict=True):
        want[int(c[0] // 0.25), int(c[1] // 0.4), int(c[2] // 0.18)] += 4 / 3 * np.pi * r**3
    np.testing.assert_allclose(solid, want, rtol=1e-12, atol=1e-15)
    exact = porosity(centers, radii, lower, upper, shape, method="exact", device=device)
    voxel = porosity(centers, radii, lower, upper, shape, method="voxel", subdivisions=16, device=device)
    assert np.abs(voxel - exact).max() < 5e-3, np.abs(voxel - exact).max()
    assert abs(np.sum(1.0 - voxel) / np.sum(1.0 - exact) - 1.0) < 5e-3


def test_frame_averaging_refuses_what_it_cannot_turn(device):
    """Frame averaging turns the grid, which needs cubic cells, and turns the lamp axes, which needs one pressure:
    anisotropic cells and a per-axis pressure (host or device) are refused with errors that name the argument, from
    2 frames on, by lamp_forces and by ShiningLamp."""
    centre, r = [[0.0, 0.0, 0.0]], [0.3]
    grid = wl.LampGrid([-0.45] * 3, [0.45] * 3, CELL)
    with pytest.raises(ValueError, match=r"frames: turning a grid needs the box form with cubic cells"):
        wl.ShiningLamp(grid, frames=2, device=device)
    with pytest.raises(ValueError, match=r"frames: turning a grid needs the box form with cubic cells"):
        wl.lamp_forces(centre, r, 1.0e6, grid=grid, frames=2, device=device)
    with pytest.raises(ValueError, match=r"frames: frame averaging needs an isotropic pressure"):
        wl.lamp_forces(centre, r, PRESSURE, frames=2, device=device)
    cubic = wl.LampGrid([-0.45] * 3, [0.45] * 3, 0.05)
    lamp = wl.ShiningLamp(cubic, frames=2, device=device)
    pos, rad = device_arrays(centre, r, device)
    forces = wp.zeros(1, dtype=wp.vec3, device=device)
    lamp.update(pos, rad)
    with pytest.raises(ValueError, match=r"frames: frame averaging needs an isotropic pressure"):
        lamp.add_forces(forces, PRESSURE)
    with pytest.raises(ValueError, match=r"frames: frame averaging needs an isotropic pressure"):
        lamp.forces_numpy(PRESSURE)
    with pytest.raises(ValueError, match=r"pressure: frame averaging needs an isotropic pressure"):
        lamp.add_forces(forces, wp.array([1.0e6, 2.0e6, 3.0e6], dtype=wp.float32, device=device))
    assert not forces.numpy().any()  # nothing written before the refusal
    pair = wl.lamp_forces([[-0.2, 0, 0], [0.2, 0, 0]], [0.2, 0.2], 1.0e6, grid=cubic, frames=2, device=device)
    assert np.abs(pair).max() > 0 and not pair.sum(axis=0).any()


def test_bvh_peer_finds_the_lamp_owners_on_memo_form_grids(device, rng):
    """The BVH caster (one ray per cell) and the lamp agree cell by cell on the memo's 18-number form, where each
    grid has its own corner, extent and cell counts (rectangular cells that differ from grid to grid)."""
    centers, radii, _ = scene(rng, n=50)
    grid = wl.LampGrid.from_grids(
        corners=[[-0.21, -0.17], [-0.23, -0.19], [-0.15, -0.24]],
        lengths=[[1.02, 0.99], [0.97, 1.04], [1.05, 0.95]],
        counts=[[37, 23], [41, 19], [29, 44]],
    )
    lamp = lamp_update(centers, radii, grid=grid, criterion=1, device=device)
    owners, _ = bvh_owners(grid, centers, radii, device)
    d = lamp.diagnostics()
    assert all((d.owners[name] >= 0).sum() > 50 for name in wl.LAMPS)
    for name in wl.LAMPS:
        np.testing.assert_array_equal(owners[name], d.owners[name], err_msg=name)
