"""The benchmark's error and load measures, against values computed by hand on tiny scenes.

The benchmark's error and load measures (``warp_lamp.measures``) against values worked out by hand on tiny
scenes, and the README's accuracy figures that they produce."""

import numpy as np
import pytest

from warp_lamp.bench import specimen_stress
from warp_lamp.measures import (
    ball_outer_normals,
    block_face_interior,
    direction_error,
    envelope_stress,
    lone_sphere_error,
    slot_load_ratios,
    stress_summary,
    visible_area_error,
)
from warp_lamp.scenes import scene_lattice_box, scene_slot_block, scene_sphere_specimen


def rotation_z(deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_direction_error_hand_values():
    """Angles 0, 45 and 90 degrees and one unloaded particle: mean 45, p90 81 (linear interpolation between 45 and
    90), the |F|-weighted mean (0 + 45 sqrt 2 + 180) / (4 + sqrt 2); normals need not be unit vectors."""
    f = [[2.0, 0, 0], [1.0, 1.0, 0], [0, 0, 0], [0, 2.0, 0], [5.0, 0, 0]]
    n = [[3.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0], [0, 0, -0.5], [-1.0, 0, 0]]
    select = [True, True, True, True, False]
    out = direction_error(f, n, select)
    assert (out["particles"], out["loaded"], out["unloaded"]) == (4, 3, 1)
    assert out["mean_deg"] == pytest.approx(45.0, abs=1e-12)
    assert out["p90_deg"] == pytest.approx(81.0, abs=1e-12)
    weighted = (0.0 + 45.0 * np.sqrt(2.0) + 90.0 * 2.0) / (2.0 + np.sqrt(2.0) + 2.0)
    assert out["weighted_mean_deg"] == pytest.approx(weighted, abs=1e-12)
    # The unselected particle points against its normal (180 degrees): selecting it moves the mean.
    assert direction_error(f, n)["mean_deg"] == pytest.approx((0 + 45 + 90 + 180) / 4, abs=1e-12)


def test_direction_error_without_loaded_particles_and_bad_input():
    """No loaded particle selected gives None angles (JSON-ready, not NaN); bad shapes and a zero normal under a
    loaded particle are refused, naming the argument and the index."""
    out = direction_error(np.zeros((3, 3)), np.ones((3, 3)))
    assert out["mean_deg"] is None and out["p90_deg"] is None and out["unloaded"] == 3
    with pytest.raises(ValueError, match=r"forces: expected shape \(N, 3\)"):
        direction_error(np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match=r"normals: expected shape \(2, 3\)"):
        direction_error(np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"select: expected shape \(2,\)"):
        direction_error(np.zeros((2, 3)), np.zeros((2, 3)), [True])
    with pytest.raises(ValueError, match=r"normals: must be nonzero .* index 1"):
        direction_error([[1.0, 0, 0], [1.0, 0, 0]], [[1.0, 0, 0], [0, 0, 0]])


def test_block_face_interior_on_a_5_cube():
    """On a 5 x 5 x 5 lattice, edge 2 leaves the six face centres, each with its inward normal (turned with the
    body); edge 1 leaves 3 x 3 per face; edges and corners are never taken."""
    idx = np.stack(np.unravel_index(np.arange(125), (5, 5, 5)), axis=1)
    select, normals = block_face_interior(idx, 5, edge=2)
    assert select.sum() == 6
    expected = {(0, 2, 2): [1, 0, 0], (4, 2, 2): [-1, 0, 0], (2, 0, 2): [0, 1, 0], (2, 4, 2): [0, -1, 0]}
    expected.update({(2, 2, 0): [0, 0, 1], (2, 2, 4): [0, 0, -1]})
    got = {tuple(int(x) for x in idx[k]): normals[k].tolist() for k in np.flatnonzero(select)}
    assert got == {k: [float(x) for x in v] for k, v in expected.items()}
    assert not normals[~select].any()
    select1, _ = block_face_interior(idx, 5, edge=1)
    assert select1.sum() == 6 * 9
    on_edge = (idx == 0).sum(axis=1) + (idx == 4).sum(axis=1) >= 2
    assert not (select1 & on_edge).any()
    rot = rotation_z(30.0)
    _, turned = block_face_interior(idx, 5, rotation=rot, edge=2)
    np.testing.assert_allclose(turned, normals @ rot.T, atol=1e-15)
    with pytest.raises(ValueError, match=r"edge: expected an integer >= 1"):
        block_face_interior(idx, 5, edge=0)
    with pytest.raises(ValueError, match=r"index: expected shape \(N, 3\)"):
        block_face_interior(idx[:, :2], 5)


def test_block_face_interior_matches_scene_layout():
    """The lattice index of scene_lattice_box's particle k is np.unravel_index(k, n): the face-interior particles
    of a 6^3 block (edge 2) are the 4 central sites of each face, at the block's extreme coordinates."""
    s = scene_lattice_box(6)
    idx = np.stack(np.unravel_index(np.arange(s.n), (6, 6, 6)), axis=1)
    np.testing.assert_allclose(s.centers, idx, atol=0.05 + 1e-12)
    select, normals = block_face_interior(idx, 6)
    assert select.sum() == 24
    # Each inward normal points from the particle toward the block's centre.
    assert np.all(np.sum((s.center - s.centers[select]) * normals[select], axis=1) > 2.0)


def test_ball_outer_normals_hand_values():
    """Particles farther than R - depth from the centre are outer, with the unit inward radial direction; the
    centre itself is never outer."""
    c = np.array([[0.0, 0, 0], [1.0, 0, 0], [0, 0.5, 0], [0, 0, -0.95], [0.6, 0.8, 0]]) + 2.0
    select, normals = ball_outer_normals(c, [2.0, 2.0, 2.0], 1.0, 0.2)
    assert select.tolist() == [False, True, False, True, True]
    np.testing.assert_allclose(normals[[1, 3, 4]], [[-1, 0, 0], [0, 0, 1], [-0.6, -0.8, 0]], atol=1e-15)
    assert not normals[0].any()


def test_visible_area_error_hand_values():
    """Particle 0 sees 2 m^2 from -x and 1 m^2 from +x: exact force P (1, 0, 0); the lamp's error (0, 0.3, 0.4) P
    is 0.5 P pi rbar^2 with pi rbar^2 = 1. Particle 1 is hidden (no exact area) and carries an error of 1: it
    counts in rms_all and worst, not in the surface RMS."""
    p = 2.0
    rbar = 1.0 / np.sqrt(np.pi)
    areas = np.zeros((2, 6))
    areas[0, 0], areas[0, 1] = 2.0, 1.0
    areas[0, 2] = areas[0, 3] = 0.7  # equal from both y lamps: no exact net force on y
    f = np.array([[1.0, 0.3, 0.4], [0.6, 0.8, 0.0]]) * p
    out = visible_area_error(f, areas, p, rbar)
    assert out["rms"] == pytest.approx(0.5, abs=1e-14)
    assert out["rms_all"] == pytest.approx(np.sqrt((0.25 + 1.0) / 2), abs=1e-14)
    assert out["worst"] == pytest.approx(1.0, abs=1e-14) and out["worst_particle"] == 1
    assert out["surface"] == 1
    exact = p * (areas[:, 0::2] - areas[:, 1::2])
    assert visible_area_error(exact, areas, p, rbar)["worst"] == 0.0
    with pytest.raises(ValueError, match=r"exact_areas: expected shape \(2, 6\)"):
        visible_area_error(f, areas[:, :3], p, rbar)
    with pytest.raises(ValueError, match=r"pressure: must be finite and > 0"):
        visible_area_error(f, areas, 0.0, rbar)
    with pytest.raises(ValueError, match=r"mean_radius: must be finite and > 0"):
        visible_area_error(f, areas, p, np.nan)


def test_slot_load_ratios_hand_values():
    """A 3 x 6 x 4 block with a slot 2 wide and 2 deep (L = 3, D = 2, w = 2): forces placed by hand on each wall
    column, the floor and its corner columns give the ratios chosen; forces elsewhere (below the slot's depth,
    on the outer face, or lateral on the floor) count for nothing."""
    s = scene_slot_block((3, 6, 4), width=2, depth=2)
    cut, idx = s.cut, s.index
    assert (cut["j0"], cut["j1"], cut["k0"], cut["wall_lo"], cut["wall_hi"], cut["floor"]) == (2, 4, 2, 1, 4, 1)
    p = 3.0
    side, bottom = p * 3 * 2, p * 3 * 2
    f = np.zeros((s.n, 3))
    top = idx[:, 2] >= 2
    lo, hi = (idx[:, 1] == 1) & top, (idx[:, 1] == 4) & top
    assert lo.sum() == hi.sum() == 6
    f[lo, 1] = -0.5 * side / 6
    f[hi, 1] = 0.75 * side / 6
    floor = (idx[:, 2] == 1) & (idx[:, 1] >= 2) & (idx[:, 1] < 4)
    corners = (idx[:, 2] == 1) & np.isin(idx[:, 1], [1, 4])
    assert floor.sum() == corners.sum() == 6
    f[floor, 2] = -bottom / 6
    f[corners, 2] = -0.5 * bottom / 6
    f[corners, 1] = -100.0  # lateral, below the slot's depth
    f[(idx[:, 1] == 0) & top, 1] = -50.0  # the block's outer face
    f[floor, 1] = 7.0
    out = slot_load_ratios(s, f, p)
    assert out == pytest.approx({"wall_lo": 0.5, "wall_hi": 0.75, "floor": 1.0, "floor_plus": 1.5}, abs=1e-14)
    with pytest.raises(ValueError, match=r"scene: expected a slot block"):
        slot_load_ratios(scene_lattice_box(3), np.zeros((27, 3)), p)
    with pytest.raises(ValueError, match=r"forces: expected shape"):
        slot_load_ratios(s, f[:-1], p)


def test_envelope_stress_by_hand():
    """sigma = (1/V) sum (x_i - x_c) (x) F_i: a squeezed pair gives sigma_xx = -2 a F / V; an off-axis load fills
    [x, y] (position row, force column) and not [y, x]; the reference point is subtracted."""
    a, f, v = 0.5, 3.0, 2.0
    sigma = envelope_stress([[a, 0, 0], [-a, 0, 0]], [[-f, 0, 0], [f, 0, 0]], [0, 0, 0], v)
    want = np.zeros((3, 3))
    want[0, 0] = -2 * a * f / v
    np.testing.assert_allclose(sigma, want, rtol=1e-15, atol=0)
    sigma = envelope_stress([[a, 0, 0]], [[0, f, 0]], [0, 0, 0], v)
    want = np.zeros((3, 3))
    want[0, 1] = a * f / v
    np.testing.assert_allclose(sigma, want, rtol=1e-15, atol=0)
    sigma = envelope_stress([[2.0, 1.0, 0.0]], [[3.0, 0.0, 0.0]], [1.0, 1.0, 0.0], 1.5)
    want = np.zeros((3, 3))
    want[0, 0] = (2.0 - 1.0) * 3.0 / 1.5
    np.testing.assert_allclose(sigma, want, rtol=1e-15, atol=0)


def test_stress_summary_by_hand():
    """Mean pressure -tr(sigma)/3 over P, and the Frobenius norm of sigma + mean I over P: hydrostatic -P I gives
    (1, 0); diag(-1, -2, -3) P with shears tau gives mean 2 and deviator diag(1, 0, -1) P plus the shears,
    norm sqrt(2 + 2 (0.5^2 + 0.25^2)); tension counts negative."""
    p = 4.0e6
    out = stress_summary(-p * np.eye(3), p)
    assert out["mean_pressure_over_P"] == pytest.approx(1.0, rel=1e-15)
    assert out["deviatoric_over_P"] == pytest.approx(0.0, abs=1e-15)
    sigma = p * np.array([[-1.0, 0.5, 0.0], [0.5, -2.0, 0.25], [0.0, 0.25, -3.0]])
    out = stress_summary(sigma, p)
    assert out["mean_pressure_over_P"] == pytest.approx(2.0, rel=1e-15)
    assert out["deviatoric_over_P"] == pytest.approx(np.sqrt(2.0 + 2 * (0.5**2 + 0.25**2)), rel=1e-14)
    assert stress_summary(p * np.eye(3), p)["mean_pressure_over_P"] == pytest.approx(-1.0, rel=1e-15)


def lit_cells(offset, r, h, criterion):
    """Cells of the [-1, 1]^3 grid that each lamp pair lights for a lone sphere, counted in float64 by hand: cell
    centres within r of the projected centre (criterion 1), or cell rectangles within r (criterion 0)."""
    edges = np.arange(-1.0, 1.0 + h / 2, h)
    lo, hi = edges[:-1], edges[1:]
    out = []
    for a in range(3):
        pu, pv = offset[(a + 1) % 3], offset[(a + 2) % 3]
        if criterion == 1:
            du, dv = 0.5 * (lo + hi) - pu, 0.5 * (lo + hi) - pv
        else:
            du = np.maximum(np.maximum(lo - pu, pu - hi), 0.0)
            dv = np.maximum(np.maximum(lo - pv, pv - hi), 0.0)
        out.append(int(np.sum(du[:, None] ** 2 + dv[None, :] ** 2 <= r * r)))
    return out


@pytest.mark.parametrize("criterion", [1, 0])
@pytest.mark.parametrize("cells_per_diameter", [2, 4])
def test_lone_sphere_error_is_the_rms_of_hand_counted_cells(device, criterion, cells_per_diameter):
    """E_area: RMS over the offsets and the six lamps of (lit cells x h^2) / (pi r^2) - 1, with the lit cells
    counted here in float64 (both lamps of an axis light the same cells), at the offsets the measure documents
    (uniform in a cell, seeded)."""
    r, samples, seed = 0.5, 16, 7
    h = 2 * r / cells_per_diameter
    offsets = np.random.default_rng(seed).uniform(0.0, h, (samples, 3))
    errors = []
    for off in offsets:
        for n in lit_cells(off, r, h, criterion):
            errors += [n * h * h / (np.pi * r * r) - 1.0] * 2
    want = np.sqrt(np.mean(np.square(errors)))
    assert abs(np.mean(np.abs(errors)) - want) > 1e-3 * want  # the scene tells RMS from mean |e|
    got = lone_sphere_error(criterion, cells_per_diameter, device, samples=samples, seed=seed)
    assert got == pytest.approx(want, rel=1e-12)


def test_specimen_stress_readme_figures(device):
    """The README's SphereTest-specimen figures (criterion 1): the loads' mean pressure over the 100 mm envelope is
    0.874 P at 2, 4, 8 and 16 cells per diameter (measured 0.87397 to 0.87403), the deviatoric norm below 0.2% of P
    from 4 cells per diameter on (measured 0.07% at most), the moment below 2e-3 P pi R^3 (measured 1.7e-3 at 2),
    the force sum exactly zero."""
    scene = scene_sphere_specimen()
    for k in (2, 4, 8, 16):
        out = specimen_stress(scene, 1, k, device)
        assert round(out["mean_pressure_over_P"], 3) == 0.874, (k, out)
        if k >= 4:
            assert out["deviatoric_over_P"] < 0.002, (k, out)
        assert out["moment_over_PpiR3"] < 2e-3, (k, out)
        assert out["force_sum"] == [0.0, 0.0, 0.0]
