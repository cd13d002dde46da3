"""examples/triaxial.py: a drained triaxial test confined by the lamp, small enough for a CPU core."""

import numpy as np
import pytest
from helpers import load_example

from warp_lamp.scenes import scene_cylinder_specimen

SIGMA_3 = 100e3
PARTICLES = 300
_RUNS = {}


def small_triaxial(device, surfaces="first"):
    """300 particles (5.7 across), lamp at 4 cells per diameter (the memo's lamp, or every wetted surface with a
    probe of half a mean radius): consolidation (at most 3,000 cycles), then compression to 2% axial strain at
    I = 2e-3 (about 6,900 cycles). Run once per device and mode, shared by the tests."""
    key = (device, surfaces)
    if key not in _RUNS:
        tx = load_example("triaxial")
        test = tx.TriaxialTest(
            PARTICLES, sigma3=SIGMA_3, inertial_number=2e-3, check_every=100, surfaces=surfaces, device=device
        )
        cons = test.consolidate(3000)
        test.compress(0.02)
        _RUNS[key] = (test, cons)
    return _RUNS[key]


def test_silhouette_and_envelope_match_geometry(rng):
    """The host measures: the silhouette of disks equals a 4,000 x 4,000 raster of them within its resolution (one
    disk, two overlapping, 40 at random); the lateral envelope of a ring of particles is the cylinder they span."""
    tx = load_example("triaxial")
    u, v, r = np.array([0.0]), np.array([0.0]), np.array([1.0])
    assert abs(tx.silhouette_area(u, v, r, 0.01) / np.pi - 1) < 3e-4
    d = 1.2  # two unit disks: the union is 2 pi - the lens
    lens = 2.0 * np.arccos(d / 2.0) - 0.5 * d * np.sqrt(4.0 - d * d)
    area = tx.silhouette_area(np.array([0.0, d]), np.zeros(2), np.ones(2), 0.01)
    assert abs(area / (2.0 * np.pi - lens) - 1) < 3e-4
    u, v, r = rng.uniform(0, 5, 40), rng.uniform(0, 5, 40), rng.uniform(0.2, 0.8, 40)
    g = np.linspace(-1.0, 6.0, 4000, endpoint=False) + 3.5 / 4000
    gu, gv = np.meshgrid(g, g, indexing="ij")
    covered = np.zeros(gu.shape, dtype=bool)
    for ui, vi, ri in zip(u, v, r, strict=True):
        covered |= (gu - ui) ** 2 + (gv - vi) ** 2 <= ri * ri
    raster = covered.sum() * (7.0 / 4000) ** 2
    assert abs(tx.silhouette_area(u, v, r, 0.005) - raster) < 2e-3 * raster
    # 64 particles of radius 1 mm on each of 20 rings of radius 24 mm: the envelope is the 25 mm cylinder.
    theta = np.repeat(np.linspace(0, 2 * np.pi, 64, endpoint=False)[None, :], 20, axis=0)
    z = np.repeat((np.arange(20) * 2e-3 + 1e-3)[:, None], 64, axis=1)
    x = np.stack([0.024 * np.cos(theta), 0.024 * np.sin(theta), z], axis=-1).reshape(-1, 3)
    env = tx.lateral_envelope(x, np.full(len(x), 1e-3), 0.0, 0.04, 10, 32)
    assert abs(env["volume"] / (np.pi * 0.025**2 * 0.04) - 1) < 0.01
    np.testing.assert_allclose(env["radius"], 0.025, rtol=0, atol=1e-12)


def test_cylinder_specimen_meets_its_spec(device):
    """The cylinder specimen: the particle count asked for, at the porosity asked for, inside the 50 x 100 mm
    cylinder, no overlap above 1% of the smaller radius (all pairs, float64, independently of Warp)."""
    s = scene_cylinder_specimen(particles=PARTICLES, porosity=0.45, device=device, cache=False)
    c, r = s.centers, s.radii
    assert s.n == PARTICLES
    assert abs(r.max() / r.min() - 1.66) < 0.05
    solid = np.sum(4.0 / 3.0 * np.pi * r**3) / (np.pi * 0.025**2 * 0.1)
    assert abs(solid - 0.55) < 1e-9
    tol = 0.011 * r
    assert np.all(np.hypot(c[:, 0], c[:, 1]) + r <= 0.025 + tol)
    assert np.all(np.abs(c[:, 2]) + r <= 0.05 + tol)
    d = np.linalg.norm(c[:, None, :] - c[None, :, :], axis=2)
    overlap = (r[:, None] + r[None, :] - d) / np.minimum(r[:, None], r[None, :])
    np.fill_diagonal(overlap, -1.0)
    assert overlap.max() <= 0.01


@pytest.mark.parametrize("surfaces", ["first", "all"])
def test_triaxial_specimen_stays_confined(device, surfaces):
    """Through consolidation and compression the lamp (either mode) holds the specimen: every particle stays
    within 15% of the specimen's radius, no particle leaves the lamp's grid, and the volume changes by less than
    5%."""
    test, cons = small_triaxial(device, surfaces)
    x = test.dem.x.numpy()
    assert np.isfinite(x).all()
    samples = test.history["consolidation"] + test.history["compression"]
    radius = max(s["max_radial"] for s in samples)
    assert radius < 1.15 * 0.025, radius
    assert test.lamp.max_outside == 0
    assert max(abs(s["eps_v"]) for s in test.history["compression"]) < 0.05
    assert abs(cons["sigma_bottom"] / SIGMA_3 - 1) < 0.05 and abs(cons["sigma_top"] / SIGMA_3 - 1) < 0.05, cons


@pytest.mark.parametrize("surfaces", ["first", "all"])
def test_lamp_lateral_stress_is_within_10_percent_of_sigma_3(device, surfaces):
    """The lateral stress the lamp applies (its lit area times P over the specimen's silhouettes along x and y)
    stays within 10% of sigma_3 at every sample of both phases."""
    test, _ = small_triaxial(device, surfaces)
    lateral = np.array([s["sigma_lat"] for s in test.history["consolidation"] + test.history["compression"]])
    assert np.abs(lateral / SIGMA_3 - 1).max() < 0.10, lateral


@pytest.mark.parametrize("surfaces", ["first", "all"])
def test_deviator_stress_rises_with_axial_strain(device, surfaces):
    """q starts near zero after consolidation, is positive once the platen has moved, and rises with axial
    strain: over the last third of the compression it exceeds its mean over the first third by sigma_3 / 10."""
    test, _ = small_triaxial(device, surfaces)
    c = test.history["compression"]
    eps = np.array([s["eps_a"] for s in c])
    q = np.array([s["q"] for s in c])
    assert eps[-1] >= 0.02
    assert abs(q[0]) < 0.05 * SIGMA_3, q[0]
    assert np.all(q[eps > 0.001] > 0.0), q
    first = q[(eps > 0) & (eps < eps[-1] / 3)].mean()
    last = q[eps > 2 * eps[-1] / 3].mean()
    assert last > first + 0.1 * SIGMA_3, (first, last)


def test_captured_block_records_one_block_of_cycles(device, monkeypatch):
    """The graph a triaxial test records holds exactly one block of cycles (n_u of them, the lamp updated on the
    first), the count the cycle counter advances by per replay: recorded here by calling what capture would
    record, on any device."""
    tx = load_example("triaxial")
    test = tx.TriaxialTest(PARTICLES, sigma3=SIGMA_3, inertial_number=2e-3, check_every=100, device=device)
    calls = []
    monkeypatch.setattr(test, "step", lambda **kw: calls.append(kw["lamp_update"]))
    monkeypatch.setattr(test.dem, "capture", lambda fn, cycles: [fn() for _ in range(cycles)])
    test.capture()
    assert len(calls) == test.block
    assert [k for k, upd in enumerate(calls) if upd] == list(range(0, test.block, test.update_every))
