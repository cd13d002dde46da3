"""The seeded scenes the tests, the benchmark and the examples share.

The SphereTest specimen generator at any reasonable size: small bodies pack at the densest porosity they
reach, and a porosity or a size that cannot be packed is refused at once with the reason."""

import time

import numpy as np
import pytest

from warp_lamp.scenes import (
    scene_lattice_box,
    scene_lone_sphere,
    scene_overlapping_polydisperse,
    scene_sphere_specimen,
)


def test_sphere_specimen_meets_its_spec():
    """SphereTest specimen: 100 mm body, 5 mm mean diameter, Rmax/Rmin = 1.66, porosity 0.36-0.40, no overlap
    above 1% of a radius, everything inside the envelope (checked here in float64, independently of Warp)."""
    s = scene_sphere_specimen()
    c, r = s.centers, s.radii
    assert abs(2 * r.mean() - 0.005) < 0.0002
    assert abs(r.max() / r.min() - 1.66) < 0.02
    porosity = 1 - np.sum(r**3) / s.radius**3
    assert 0.36 <= porosity <= 0.40
    assert np.all(np.linalg.norm(c, axis=1) + r <= s.radius * (1 + 0.01 * r / s.radius) + 1e-12)
    # All pairs, in blocks: overlap / smaller radius <= 1%.
    worst = 0.0
    for i0 in range(0, len(r), 512):
        d = np.linalg.norm(c[i0 : i0 + 512, None, :] - c[None, :, :], axis=2)
        ov = (r[i0 : i0 + 512, None] + r[None, :]) - d
        ov[np.arange(len(d)), np.arange(i0, i0 + len(d))] = -1.0
        worst = max(worst, float(np.max(ov / np.minimum(r[i0 : i0 + 512, None], r[None, :]))))
    assert worst <= 0.01


def test_lattice_box_and_lone_sphere_are_seeded():
    """Same seed, same scene; the lattice has the reference parameters; the lone sphere sits inside a cell."""
    a, b = scene_lattice_box(5, seed=1), scene_lattice_box(5, seed=1)
    np.testing.assert_array_equal(a.centers, b.centers)
    assert a.n == 125 and a.radii.min() >= 0.4 and a.radii.max() <= 0.5
    assert np.abs(a.centers - np.round(a.centers)).max() <= 0.05
    s = scene_lone_sphere(0.5, 0.25, seed=3)
    assert s.centers.shape == (1, 3) and s.radii.shape == (1,)
    assert s.n == 1 and np.all((s.centers >= 0) & (s.centers < 0.25))
    np.testing.assert_array_equal(s.center, s.centers[0])


def test_overlapping_polydisperse_ball_meets_its_spec():
    """The issue-19 ball: n spheres inside the ball, radii in [Rmin, 3 Rmin] with mean 0.5, every overlap at most
    30% of the smaller radius, many overlaps above 20%, none nested; the same seed gives the same scene."""
    s = scene_overlapping_polydisperse(300)
    c, r = s.centers, s.radii
    assert s.n == 300 and np.all(np.linalg.norm(c, axis=1) + r <= s.radius * (1 + 1e-12))
    assert r.min() >= 0.25 and r.max() <= 0.75 and abs(r.mean() - 0.5) < 0.05
    d = np.linalg.norm(c[:, None] - c[None], axis=2)
    i, j = np.triu_indices(s.n, 1)
    overlap = (r[i] + r[j] - d[i, j]) / np.minimum(r[i], r[j])
    assert overlap.max() <= 0.3 + 1e-12 and np.count_nonzero(overlap > 0.2) > 50
    assert np.all(d[i, j] > np.abs(r[i] - r[j]))
    again = scene_overlapping_polydisperse(300)
    assert np.array_equal(again.centers, c) and np.array_equal(again.radii, r)


@pytest.mark.parametrize("diameter", [0.07, 0.04])
def test_small_specimens_pack(diameter):
    """A 70 mm and a 40 mm body of 5 mm particles relax (in seconds, not after a long failure): every particle
    inside the body, overlaps under 1% of the smaller radius, and the envelope porosity between 0.39 and 0.5."""
    s = scene_sphere_specimen(diameter=diameter, cache=False)
    R = diameter / 2.0
    assert np.all(np.linalg.norm(s.centers, axis=1) + s.radii <= R + 0.0101 * s.radii)  # the wall, like a contact
    d = np.linalg.norm(s.centers[:, None] - s.centers[None], axis=2)
    overlap = (s.radii[:, None] + s.radii[None] - d) / np.minimum(s.radii[:, None], s.radii[None])
    np.fill_diagonal(overlap, -1.0)
    assert overlap.max() < 0.0101
    porosity = 1.0 - np.sum(s.radii**3) / R**3
    assert 0.39 < porosity < 0.5


def test_unreachable_porosity_and_tiny_bodies_are_refused_at_once():
    """The 70 mm body at the memo's porosity 0.39, and a body 3 particles across: ValueError naming the argument
    and why, within a second (before any relaxation)."""
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"porosity: 0.39 cannot be reached in a body 14 particle diameters across"):
        scene_sphere_specimen(diameter=0.07, porosity=0.39, cache=False)
    with pytest.raises(ValueError, match=r"diameter: .* 3 particle diameters .* under the 5 a packing needs"):
        scene_sphere_specimen(diameter=0.015, cache=False)
    assert time.perf_counter() - t0 < 1.0
