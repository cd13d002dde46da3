"""The BVH ray caster, an independent algorithm, finds the lamp's owners."""

import numpy as np
import pytest
from helpers import bvh_owners, polydisperse_scene

import warp_lamp as wl
from warp_lamp.lamp import lamp_update
from warp_lamp.scenes import scene_lattice_box


@pytest.mark.parametrize("scene", ["random", "lattice", "far"])
def test_bvh_owners_equal_lamp_owners(device, rng, scene):
    """Criterion 1: every cell of every lamp has the same owner from the BVH caster and the lamp, except exact
    depth ties, which the BVH caster resolves the same way here (lowest index)."""
    if scene == "lattice":
        s = scene_lattice_box(8, seed=3)
        centers, radii = s.centers, s.radii
    else:
        centers, radii = polydisperse_scene(rng, n=400, extent=6.0, rmin=0.1, rmax=0.7)
        if scene == "far":
            centers = centers + 5.0e3
    lamp = lamp_update(centers, radii, cells_per_diameter=4, criterion=1, device=device)
    owners, peer = bvh_owners(lamp.grid, centers, radii, device)
    d = lamp.diagnostics()
    for name in wl.LAMPS:
        np.testing.assert_array_equal(owners[name], d.owners[name], err_msg=name)
    np.testing.assert_array_equal(peer.counts.numpy().reshape(-1, 3), d.counts)
