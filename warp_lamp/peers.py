"""Peers for the benchmark: what a Warp user would write without this library."""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_lamp.grid import LampGrid
from warp_lamp.kernels import lamp as KL
from warp_lamp.kernels import peers as KP

__all__ = ["BvhLamp"]


class BvhLamp:
    """A Warp BVH ray caster with the lamp's output: ``wp.Bvh`` over the spheres' boxes, one thread per cell
    ray per lamp keeping the nearest hit (criterion 1), then the lamp's own count scatter.

    The keys and counts have the layout of :class:`warp_lamp.ShiningLamp`, so owners compare cell by cell.
    """

    def __init__(self, grid: LampGrid, n: int, *, device=None):
        self.grid = grid
        self.device = wp.get_device(device)
        d = self.device
        f = grid.frame()
        self._params = [
            wp.vec3(*f["corner_u"]),
            wp.vec3(*f["corner_v"]),
            wp.vec3(*f["h_u"]),
            wp.vec3(*f["h_v"]),
            wp.vec3i(*(int(x) for x in f["n_u"])),
            wp.vec3i(*(int(x) for x in f["offset"])),
        ]
        self._offset = self._params[-1]
        self.n = n
        self.n_cells = grid.n_cells
        self.keys = wp.zeros(2 * self.n_cells, dtype=wp.uint64, device=d)
        self.counts = wp.zeros(3 * n, dtype=wp.int32, device=d)
        self.lowers = wp.zeros(n, dtype=wp.vec3, device=d)
        self.uppers = wp.zeros(n, dtype=wp.vec3, device=d)
        self.bvh = None

    def build(self, positions: wp.array, radii: wp.array, origin=(0.0, 0.0, 0.0)) -> None:
        """Boxes and a fresh BVH: a moving simulation pays this every update too."""
        self._origin = wp.vec3(*origin)
        wp.launch(
            KP.bvh_sphere_bounds,
            dim=self.n,
            inputs=[positions, radii, self._origin],
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
            KP.bvh_cast,
            dim=2 * self.n_cells,
            inputs=[
                self.bvh.id,
                self._positions,
                self._radii,
                self._origin,
                *self._params,
                self._start_lo,
                self._start_hi,
            ],
            outputs=[self.keys],
            device=d,
        )
        wp.launch(
            KL.lamp_scatter,
            dim=self.n_cells,
            inputs=[self.keys, self._offset],
            outputs=[self.counts],
            device=d,
        )

    def owners(self) -> dict:
        """Owner of each cell ``[i, j]`` per lamp name (-1 where unlit), as in ``ShiningLamp.diagnostics``."""
        from warp_lamp.lamp import LAMPS

        keys = self.keys.numpy()
        out = {}
        for a in range(3):
            nu, nv = (int(x) for x in self.grid.counts[a])
            o = int(self.grid.offsets[a])
            for side in range(2):
                k = keys[2 * o + side : 2 * (o + nu * nv) : 2]
                own = np.where(k != np.uint64(0xFFFFFFFFFFFFFFFF), (k & np.uint64(0xFFFFFFFF)).astype(np.int64), -1)
                out[LAMPS[2 * a + side]] = own.reshape(nv, nu).T
        return out
