"""The exact test's reach masks, counted on the reference's candidate sets: per tested voxel the reached lattice
points within rho + diagonal of it (K), the near exposed spheres and those with a reached point within r + rho +
diagonal (useful), the pairs and the gated pairs' triples before and after the masks (a pair needs a point common
to both spheres' masks, a triple to all three); the heaviest tests last.

    PYTHONPATH=$PWD python bench/experiments/wetted_reach_masks.py --scene specimen   # or: small, slot
"""

import numpy as np
from wetted_study import near_exposed, study_main

from warp_lamp.reference import wetted as R

ROWS = []  # per test: (K, spheres, useful, pairs, pairs kept, triples, triples kept)


def reached_points(exact, x):
    """The reached lattice points (voxel centres; beyond the box, those keeping rho from every wall) within
    rho + diagonal of x."""
    rho = exact.rho
    far = (rho + exact.diag) * (1.0 + 1e-6)
    lo = np.floor((x - far) / exact.h - 0.5).astype(int)
    hi = np.ceil((x + far) / exact.h - 0.5).astype(int)
    pts = []
    for i in range(lo[0], hi[0] + 1):
        for j in range(lo[1], hi[1] + 1):
            for k in range(lo[2], hi[2] + 1):
                idx = np.array([i, j, k])
                y = (idx + 0.5) * exact.h
                if np.sum((y - x) ** 2) > far**2:
                    continue
                inside = np.all((idx >= 0) & (idx < exact.n))
                if (inside and exact.reachable[i, j, k]) or (
                    not inside and R._outside_ok(exact.planes, idx, exact.h, rho)
                ):
                    pts.append(y)
    return np.array(pts).reshape(-1, 3)


def count(exact, x):
    rho2 = exact.rho * exact.rho
    _near, ids = near_exposed(exact, x)
    c, big = exact.c[ids], exact.big[ids]
    pts = reached_points(exact, x)
    dist = np.sqrt(((c[:, None, :] - pts[None, :, :]) ** 2).sum(-1)) if len(pts) else np.zeros((len(ids), 0))
    mask = dist <= (big + exact.diag)[:, None] * (1 + 1e-6)
    pairs = pairs_kept = triples = triples_kept = 0
    for a in range(len(ids)):
        pairs += len(ids) - a - 1
        for b in range(a + 1, len(ids)):
            ab = mask[a] & mask[b]
            pairs_kept += int(ab.any())
            z, ok = R._circle_points(x, c[a : a + 1], big[a : a + 1], c[b : b + 1], big[b : b + 1])
            if ok[0] and R._dot(x - z[0], x - z[0]) <= rho2 * (1 + R.SLACK):
                triples += len(ids) - b - 1
                triples_kept += sum(int((ab & mask[k]).any()) for k in range(b + 1, len(ids)))
    ROWS.append((len(pts), len(ids), int(mask.any(axis=1).sum()), pairs, pairs_kept, triples, triples_kept))


def main():
    args, _sc, rho, seconds = study_main(count)
    a = np.array(ROWS).reshape(-1, 7)
    print(f"{args.scene} rho={rho:.4g}: {len(a)} tests, {seconds:.0f} s")
    print("  reached points near a test: median / p90 / max", np.percentile(a[:, 0], [50, 90, 100]))
    print(f"  spheres {a[:, 1].sum()}, useful {a[:, 2].sum()}")
    print(f"  pairs {a[:, 3].sum()} -> {a[:, 4].sum()}; triples {a[:, 5].sum()} -> {a[:, 6].sum()}")
    work, kept = a[:, 5] + a[:, 3], a[:, 6] + a[:, 4]
    p99 = np.percentile(work, [99, 100]), np.percentile(kept, [99, 100])
    print("  pairs + triples per test, p99 / max:", p99[0], "->", p99[1])
    print("  the heaviest tests (K, spheres, useful, pairs, kept, triples, kept):")
    print(a[np.argsort(work)[-10:][::-1]])


if __name__ == "__main__":
    main()
