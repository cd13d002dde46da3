"""Peers for the benchmark: what a Warp user would write without this library."""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_lamp.grid import LampGrid
from warp_lamp.kernels import peers as peer_kernels

__all__ = ["BvhLamp", "overlap_hexahedron"]


class BvhLamp:
    """A Warp BVH ray caster of criterion 1: ``wp.Bvh`` over the spheres' boxes, one thread per cell ray and lamp
    keeping the nearest hit, then +1 / -1 per lit ray to its owner's count on the axis.

    Independent of the lamp: its own ray numbering per axis, owners and depths (no packed keys), scatter and owner
    maps; nothing from :mod:`warp_lamp.kernels.lamp`, ``keys``, ``grid`` or ``footprint``. It shares with the lamp
    the :class:`~warp_lamp.LampGrid` it is given (cell counts, sizes, corners: the question asked) and the float32
    arithmetic of the hit test (``bvh_cast``'s docstring), so that owners compare bitwise.

    Attributes:
        owner: Per axis, the owner of each ray (-1: unlit), int32, shape (n_u n_v, 2): ray j n_u + i, low and high
            side.
        depth: Per axis, where each ray meets its owner (the entry coordinate, or the negated exit), float32.
        counts: Cells per particle and axis, +1 per low-lamp cell and -1 per high-lamp cell, int64, shape (3 N,).
    """

    def __init__(self, grid: LampGrid, n: int, *, device=None):
        self.grid = grid
        self.device = wp.get_device(device)
        d = self.device
        self.n = n
        self.counts = wp.zeros(3 * n, dtype=wp.int64, device=d)
        self.lowers = wp.zeros(n, dtype=wp.vec3, device=d)
        self.uppers = wp.zeros(n, dtype=wp.vec3, device=d)
        self._rays = []
        for a in range(3):
            nu, nv = (int(x) for x in grid.counts[a])
            corner = grid.corner[a] - np.array([grid.origin[(a + 1) % 3], grid.origin[(a + 2) % 3]])
            self._rays.append((nu, nv, np.float32(corner[0]), np.float32(corner[1]), *np.float32(grid.cell[a])))
        self.owner = [wp.zeros((nu * nv, 2), dtype=wp.int32, device=d) for nu, nv, *_ in self._rays]
        self.depth = [wp.zeros((nu * nv, 2), dtype=wp.float32, device=d) for nu, nv, *_ in self._rays]
        self.bvh = None

    def build(self, positions: wp.array, radii: wp.array) -> None:
        """Boxes and a fresh BVH: a moving simulation pays this every update too.

        Args:
            positions: Particle centres in the grid's frame (``grid.to_frame``: minus its origin, turned into its
                axes) [m], vec3, shape (N,).
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
        self._start_lo = self.lowers.numpy().min(axis=0) - 1.0
        self._start_hi = self.uppers.numpy().max(axis=0) + 1.0

    def cast(self) -> None:
        """Cast every ray of the six lamps and scatter the counts (needs :meth:`build` first)."""
        d = self.device
        self.counts.zero_()
        for a, (nu, nv, cu, cv, hu, hv) in enumerate(self._rays):
            if nu * nv == 0:
                continue
            wp.launch(
                peer_kernels.bvh_cast,
                dim=(nu * nv, 2),
                inputs=[
                    self.bvh.id,
                    self._positions,
                    self._radii,
                    a,
                    nu,
                    cu,
                    cv,
                    hu,
                    hv,
                    float(self._start_lo[a]),
                    float(self._start_hi[a]),
                ],
                outputs=[self.owner[a], self.depth[a]],
                device=d,
            )
            wp.launch(peer_kernels.bvh_scatter, dim=nu * nv, inputs=[self.owner[a], a], outputs=[self.counts], device=d)

    def owners(self) -> dict:
        """Owner of each cell ``[i, j]`` per lamp name (-1 where unlit), shape (n_u, n_v)."""
        out = {}
        for a, (nu, nv, *_) in enumerate(self._rays):
            own = self.owner[a].numpy()
            for side, name in enumerate((f"-{'xyz'[a]}", f"+{'xyz'[a]}")):
                out[name] = own[:, side].reshape(nv, nu).T.astype(np.int64)
        return out


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
