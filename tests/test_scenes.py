"""The seeded scenes the tests, the benchmark and the examples share.

The SphereTest specimen generator at any reasonable size: small bodies pack at the densest porosity they
reach, and a porosity or a size that cannot be packed is refused at once with the reason."""

import time

import numpy as np
import pytest
from helpers import worst_overlap

from warp_lamp.scenes import (
    relax_packing,
    scene_box_specimen,
    scene_cylinder_specimen,
    scene_lattice_ball,
    scene_lattice_box,
    scene_lone_sphere,
    scene_overlapping_box,
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
    assert worst_overlap(s.centers, s.radii) < 0.0101
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


def test_cylinder_and_box_specimens_pack_inside_their_containers():
    """Fresh packings (no cache, which would hand back whatever an earlier version of the relaxation left) of the
    triaxial cylinder and the cutting slab: every particle inside its container (the wall allowed 1% of a radius,
    like a contact), overlaps under 1% of the smaller radius, the slab's mean diameter the one asked for and its name
    in millimetres."""
    cyl = scene_cylinder_specimen(diameter=0.03, height=0.03, particles=400, porosity=0.46, cache=False)
    c, r = cyl.centers, cyl.radii
    assert np.all(np.hypot(c[:, 0], c[:, 1]) + r <= 0.015 + 0.0101 * r)
    assert np.all(np.abs(c[:, 2]) + r <= 0.015 + 0.0101 * r)
    assert worst_overlap(c, r) < 0.0101
    assert np.ptp(c[:, 2]) > 0.03 - 4.0 * r.max()  # filled end to end, not squeezed to one face
    assert abs(1.0 - np.sum(4.0 / 3.0 * r**3) / (0.015**2 * 0.03) - 0.46) < 1e-9  # the porosity asked for

    box = scene_box_specimen((0.02, 0.02, 0.03), 0.004, cache=False)
    c, r = box.centers, box.radii
    assert np.all(
        (c - r[:, None] >= -0.0101 * r[:, None]) & (c + r[:, None] <= [0.02, 0.02, 0.03] + 0.0101 * r[:, None])
    )
    assert worst_overlap(c, r) < 0.0101
    assert abs(2.0 * r.mean() / 0.004 - 1.0) < 0.05
    assert box.name == f"box specimen 20 x 20 x 30 mm, {len(r)} particles"


def test_overlapping_box_relaxes_to_its_overlap_inside_the_box():
    """The paper's dense box, freshly packed: inside [0, size], overlaps at most ``max_overlap`` of a radius (it is
    meant to keep soft-contact overlaps, so some remain), the solid fraction as asked."""
    s = scene_overlapping_box(0.004, size=(0.03, 0.03, 0.03), solid_fraction=0.5, max_overlap=0.1, cache=False)
    c, r = s.centers, s.radii
    assert np.all((c - r[:, None] >= -0.101 * r[:, None]) & (c + r[:, None] <= 0.03 + 0.101 * r[:, None]))
    assert 0.0 < worst_overlap(c, r) <= 0.101
    assert abs(len(r) * 4.0 / 3.0 * np.pi * 0.004**3 / 0.03**3 - 0.5) < 0.01


def test_lattice_ball_defaults_are_the_memos_sphere_test():
    """The quick stand-in's defaults are the memo's SphereTest dimensions: a 100 mm body of 5 mm particles."""
    s = scene_lattice_ball()
    assert s.radius == 0.05
    assert np.all(np.linalg.norm(s.centers, axis=1) + s.radii <= 0.05)
    assert np.linalg.norm(s.centers, axis=1).max() + s.radii.max() > 0.045
    assert abs(2.0 * s.radii.mean() - 0.005) < 0.0002


def test_coincident_particles_are_pushed_apart():
    """Two particles placed at the same point (a random placement can do it; an import often does) have no
    direction between them: the relaxation picks one and separates them rather than leaving them stacked."""
    x0 = np.array([[0.5, 0.5, 0.5], [0.5, 0.5, 0.5], [0.2, 0.2, 0.2]])
    c = relax_packing(x0, np.full(3, 0.1), box=(np.zeros(3), np.ones(3)), device="cpu")
    assert np.linalg.norm(c[0] - c[1]) >= 0.2 * (1.0 - 0.0099)
