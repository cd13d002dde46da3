"""The SphereTest specimen generator at any reasonable size: small bodies pack at the densest porosity they
reach, and a porosity or a size that cannot be packed is refused at once with the reason."""

import time

import numpy as np
import pytest

from warp_lamp.scenes import scene_sphere_specimen


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
