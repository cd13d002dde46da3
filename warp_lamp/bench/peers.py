"""Peers for the benchmark: what a Warp user would write without this library."""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_lamp.grid import LampGrid
from warp_lamp.kernels import lamp as lamp_kernels
from warp_lamp.kernels import peers as peer_kernels
from warp_lamp.lamp import lamp_owner_maps

__all__ = ["BvhLamp", "overlap_hexahedron"]


class BvhLamp:
    """A Warp BVH ray caster with the lamp's output: ``wp.Bvh`` over the spheres' boxes, one thread per cell
    ray per lamp keeping the nearest hit (criterion 1), then the lamp's own count scatter.

    The keys and counts have the layout of :class:`warp_lamp.ShiningLamp`, so owners compare cell by cell.
    """

    def __init__(self, grid: LampGrid, n: int, *, device=None):
        self.grid = grid
        self.device = wp.get_device(device)
        d = self.device
        self._params = grid.params(*grid.pose_arrays(self.device, in_frame=True))
        self.n = n
        self.n_cells = grid.n_cells
        self.keys = wp.zeros(2 * self.n_cells, dtype=wp.uint64, device=d)
        self.counts = wp.zeros(3 * n, dtype=wp.int64, device=d)
        self.lowers = wp.zeros(n, dtype=wp.vec3, device=d)
        self.uppers = wp.zeros(n, dtype=wp.vec3, device=d)
        self.bvh = None

    def build(self, positions: wp.array, radii: wp.array) -> None:
        """Boxes and a fresh BVH: a moving simulation pays this every update too.

        Args:
            positions: Particle centres in frame coordinates (minus ``grid.origin``) [m], vec3, shape (N,).
            radii: Particle radii [m], float32, shape (N,).
        """
        wp.launch(
            peer_kernels.bvh_sphere_bounds,
            dim=self.n,
            inputs=[positions, radii],
            outputs=[self.lowers, self.uppers],
            device=self.device,
        )
        self.bvh = wp.Bvh(self.lowers, self.uppers)
        self._positions, self._radii = positions, radii
        lo = self.lowers.numpy().min(axis=0) - 1.0
        hi = self.uppers.numpy().max(axis=0) + 1.0
        self._start_lo, self._start_hi = wp.vec3(*lo), wp.vec3(*hi)

    def cast(self) -> None:
        """Cast every ray of the six lamps and scatter the counts (needs :meth:`build` first)."""
        d = self.device
        self.counts.zero_()
        wp.launch(
            peer_kernels.bvh_cast,
            dim=2 * self.n_cells,
            inputs=[self._params, self.bvh.id, self._positions, self._radii, self._start_lo, self._start_hi],
            outputs=[self.keys],
            device=d,
        )
        wp.launch(
            lamp_kernels.lamp_scatter,
            dim=self.n_cells,
            inputs=[self._params, self.keys],
            outputs=[self.counts],
            device=d,
        )

    def owners(self) -> dict:
        """Owner of each cell ``[i, j]`` per lamp name (-1 where unlit), as in ``ShiningLamp.diagnostics``."""
        return lamp_owner_maps(self.keys.numpy(), self.grid)[0]


def overlap_hexahedron(lo, hi) -> np.ndarray:
    """The 8 corners of the box [lo, hi] in the order the `overlap` package (Strobl et al.) expects: bottom face,
    then top, counter-clockwise. For the porosity peer in the benchmark and the oracle in the tests."""
    return np.array(
        [
            [lo[0], lo[1], lo[2]],
            [hi[0], lo[1], lo[2]],
            [hi[0], hi[1], lo[2]],
            [lo[0], hi[1], lo[2]],
            [lo[0], lo[1], hi[2]],
            [hi[0], lo[1], hi[2]],
            [hi[0], hi[1], hi[2]],
            [lo[0], hi[1], hi[2]],
        ]
    )
