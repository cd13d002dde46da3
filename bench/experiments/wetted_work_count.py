"""Count the exact test's work per tested voxel (the reference's candidate sets, which the kernels' equal after
pruning at most): faces, pairs, gated pairs, triples tried, vertex points within rho, and how many distinct
triples the whole update tries. Issue 32's prediction: the work of deciding triples per voxel against once per
update.

    PYTHONPATH=$PWD python bench/experiments/wetted_work_count.py --scene specimen --rho-diameters 0.5
"""

import numpy as np
from wetted_study import near_exposed, percentiles, study_main

from warp_lamp.reference import wetted as R

STATS = {"voxels": 0, "ids": 0, "pairs": 0, "edge_pts": 0, "gated_pairs": 0, "triples": 0, "vertex_pts": 0}
TRIPLES = set()
PER_TEST = []  # (ids, pairs, triples tried, edge points, vertex points) per tested voxel


def count(self, x):
    rho2 = self.rho * self.rho
    _near, ids = near_exposed(self, x)
    c, big = self.c[ids], self.big[ids]
    STATS["voxels"] += 1
    STATS["ids"] += len(ids)
    pa, pb = np.triu_indices(len(ids), 1)
    STATS["pairs"] += len(pa)
    z, ok = R._circle_points(x, c[pa], big[pa], c[pb], big[pb])
    e2 = R._dot(x - z, x - z)
    STATS["edge_pts"] += int((ok & (e2 <= rho2)).sum())
    gated = np.flatnonzero(ok & (e2 <= rho2 * (1.0 + R.SLACK)))
    STATS["gated_pairs"] += len(gated)
    per = len(ids) - pb[gated] - 1
    STATS["triples"] += int(per.sum())
    ta, tb = np.repeat(pa[gated], per), np.repeat(pb[gated], per)
    start = np.repeat(np.cumsum(per) - per, per)
    tk = np.arange(int(per.sum())) - start + tb + 1
    z1, z2, okv = R._vertex_points(c[ta], big[ta], c[tb], big[tb], c[tk], big[tk])
    for q in range(len(ta)):
        if okv[q]:
            TRIPLES.add((int(ids[ta[q]]), int(ids[tb[q]]), int(ids[tk[q]])))
    w1 = R._dot(x - z1, x - z1) <= rho2
    w2 = R._dot(x - z2, x - z2) <= rho2
    STATS["vertex_pts"] += int((okv & w1).sum() + (okv & w2).sum())
    PER_TEST.append(
        (len(ids), len(pa), int(per.sum()), int((ok & (e2 <= rho2)).sum()), int((okv & w1).sum() + (okv & w2).sum()))
    )


def main():
    a, sc, rho, seconds = study_main(count)
    print(f"{a.scene} rho={rho:.4g} n={sc.n} {seconds:.1f} s")
    v = max(STATS["voxels"], 1)
    for k, val in STATS.items():
        print(f"  {k:12s} {val:>12,}  per tested voxel {val / v:8.2f}")
    print(f"  distinct triples with points: {len(TRIPLES):,}")
    # The GPU runs every test at once, so its time follows the slowest tests: the tail of the work per test.
    a = np.array(PER_TEST, dtype=np.int64).reshape(-1, 5)
    for k, name in enumerate(("spheres", "pairs", "triples tried", "edge points", "vertex points")):
        q = percentiles(a[:, k])
        print(
            f"  per test {name:14s} median {q[0]:6.0f}  p90 {q[1]:6.0f}  p99 {q[2]:6.0f}  p99.9 {q[3]:6.0f}"
            f"  max {q[4]:6.0f}"
        )


if __name__ == "__main__":
    main()
