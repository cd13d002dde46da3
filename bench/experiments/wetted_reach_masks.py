"""The exact test's reach masks, counted on the reference's candidate sets: per tested voxel the reached lattice
points within rho + diagonal of it (K), the near exposed spheres and those with a reached point within r + rho +
diagonal (useful), the pairs and the gated pairs' triples before and after the masks (a pair needs a point common
to both spheres' masks, a triple to all three); the heaviest tests last.

    PYTHONPATH=$PWD python bench/experiments/wetted_reach_masks.py specimen   # or: small
"""

import sys

import numpy as np

import warp_lamp as wl
from warp_lamp.reference import wetted as R
from warp_lamp.scenes import scene_lattice_box, scene_sphere_specimen

ROWS = []


def fluid(self, x, lattice):
    rho = self.rho
    rho2 = rho * rho
    near = self._near(x, self.rmax + 2 * rho + self.diag)
    v = x - self.c[near]
    d2 = R._dot(v, v)
    g = (self.r[near] + 2 * rho) * (1 + R.SLACK)
    keep = self.exposed[near] & (d2 <= g * g)
    ids = near[keep]
    c = self.c[ids]
    big = self.big[ids]
    # reached lattice points within rho+diag of x
    lo = np.floor((x - (rho + self.diag)) / self.h - 0.5).astype(int)
    hi = np.ceil((x + (rho + self.diag)) / self.h - 0.5).astype(int)
    pts = []
    for i in range(lo[0], hi[0] + 1):
        for j in range(lo[1], hi[1] + 1):
            for k in range(lo[2], hi[2] + 1):
                idx = np.array([i, j, k])
                y = (idx + 0.5) * self.h
                if np.sum((y - x) ** 2) > ((rho + self.diag) * (1 + 1e-6)) ** 2:
                    continue
                inside = np.all((idx >= 0) & (idx < self.n))
                if (inside and self.reachable[i, j, k]) or (
                    not inside and R._outside_ok(self.planes, idx, self.h, rho)
                ):
                    pts.append(y)
    pts = np.array(pts).reshape(-1, 3)
    K = len(pts)
    dist = np.sqrt(((c[:, None, :] - pts[None, :, :]) ** 2).sum(-1)) if K else np.zeros((len(ids), 0))
    mask = dist <= (big + self.diag)[:, None] * (1 + 1e-6)
    useful = mask.any(1)
    # counts before/after: faces within rho, pairs, gated pairs' triples
    npair = 0
    npair2 = 0
    ntri = 0
    ntri2 = 0
    for a in range(len(ids)):
        npair += len(ids) - a - 1
        for b in range(a + 1, len(ids)):
            ok_ab = (mask[a] & mask[b]).any()
            if ok_ab:
                npair2 += 1
            z, ok = R._circle_points(x, c[a : a + 1], big[a : a + 1], c[b : b + 1], big[b : b + 1])
            if ok[0] and R._dot(x - z[0], x - z[0]) <= rho2 * (1 + R.SLACK):
                ntri += len(ids) - b - 1
                if ok_ab:
                    ntri2 += sum((mask[a] & mask[b] & mask[k]).any() for k in range(b + 1, len(ids)))
    ROWS.append((K, len(ids), int(useful.sum()), npair, npair2, ntri, ntri2))
    return ORIG(self, x, lattice)


ORIG = R._Exact.fluid
R._Exact.fluid = fluid
sc = {"specimen": scene_sphere_specimen, "small": lambda: scene_lattice_box(12)}[sys.argv[1]]()
rho = float(sc.radii.mean())
grid = wl.LampGrid.enclosing(sc.centers, sc.radii, cells_per_diameter=4, margin=3 * rho)
R.wetted_reference(sc.centers, sc.radii, grid, probe_radius=rho)
a = np.array(ROWS)
print(len(a), "tests; K reached pts median/p90/max", np.percentile(a[:, 0], [50, 90, 100]))
print("spheres", a[:, 1].sum(), "useful", a[:, 2].sum())
print("pairs", a[:, 3].sum(), "->", a[:, 4].sum())
print("triples", a[:, 5].sum(), "->", a[:, 6].sum())
w = a[:, 5] + a[:, 3]
w2 = a[:, 6] + a[:, 4]
top = np.argsort(w)[-10:]
print("heaviest (K, ids, useful, pairs, pairs2, tri, tri2):")
print(a[top[::-1]])
print("per test pairs+triples p99/max before", np.percentile(w, [99, 100]), "after", np.percentile(w2, [99, 100]))
