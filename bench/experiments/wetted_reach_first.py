"""How much of the exact test's work a candidate's reached corners could skip: per tested voxel, the candidates in
the kernel's order (faces, then each pair's circle point with its triples' points), stopping at the first valid
one, with a cost model of the kernel's searches (spheres read): the hint, the blocker search over the gathered
list to its first blocker, then per reached corner the tangent tests and the segment search. "reach first" reads
the candidate's eight corner bits before the blocker search and skips a candidate none of whose corners is
reached (the same answer: a valid candidate needs a reached corner). The reference's candidate sets, without the
kernel's covered-cap pruning (an upper bound on the kernel's checks).

    PYTHONPATH=$PWD python bench/experiments/wetted_reach_first.py --scene specimen   # or: small, slot
"""

import numpy as np
from wetted_study import near_exposed, percentiles, study_main

from warp_lamp.reference import wetted as R

ROWS = []  # per test: (wet, checks, no-corner checks, cost before, cost reach-first)


def corners_reached(self, z):
    lo = np.clip(np.floor(z / self.h - 0.5), -2.0, self.n + 1.0).astype(np.int64)
    out = []
    for corner in range(8):
        idx = lo + np.array([corner & 1, (corner >> 1) & 1, (corner >> 2) & 1])
        inside = np.all((idx >= 0) & (idx < self.n))
        if inside and self.reachable[tuple(idx)]:
            out.append(idx)
        elif not inside and R._outside_ok(self.planes, idx, self.h, self.rho):
            out.append(idx)
    return out


def check(self, z, own, near, hint, reach_first):
    """(valid, blocker or -1, spheres read) for candidate z on spheres ``own``."""
    grp = self.group
    mine = np.zeros(len(near), dtype=bool)
    for s in own:
        if s >= 0:
            mine |= grp[near] == grp[s]
    cost = 0
    corners = None
    if reach_first:
        corners = corners_reached(self, z)
        cost += 1  # eight bit reads, about one sphere's load
        if not corners:
            return False, -1, cost
    if hint >= 0:
        cost += 1
        v = z - self.c[hint]
        if R._dot(v, v) < self.big[hint] ** 2 and not any(s >= 0 and grp[s] == grp[hint] for s in own):
            return False, hint, cost
    v = z - self.c[near]
    inside = (R._dot(v, v) < self.big[near] ** 2) & ~mine
    hit = np.flatnonzero(inside)
    if len(hit):
        return False, int(near[hit[0]]), cost + int(hit[0]) + 1
    cost += len(near)
    if corners is None:
        corners = corners_reached(self, z)
    others = near[~mine]
    for idx in corners:
        y = (idx + 0.5) * self.h
        if any(R._dot(y - z, z - self.c[s]) < 0.0 for s in own if s >= 0):
            continue
        d = z - y
        dd = R._dot(d, d)
        w = y - self.c[others]
        t = np.clip(-R._dot(w, d) / dd, 0.0, 1.0) if dd > 0.0 else np.zeros(len(others))
        p = w + d * t[:, None]
        cut = np.flatnonzero(R._dot(p, p) < self.big[others] ** 2)
        if not len(cut):
            return True, -1, cost + len(others)
        cost += int(cut[0]) + 1
    return False, -1, cost


def count(self, x):
    rho2 = self.rho * self.rho
    near, ids = near_exposed(self, x)
    c, big = self.c[ids], self.big[ids]
    cands = []
    for a, i in enumerate(ids):
        v = x - c[a]
        d2 = R._dot(v, v)
        if d2 > 0.0:
            z = c[a] + v * (big[a] / np.sqrt(d2))
            if R._dot(x - z, x - z) <= rho2:
                cands.append((z, (i, -1, -1)))
    pairs = []
    for a in range(len(ids)):
        for b in range(a + 1, len(ids)):
            pairs.append((a, b))
    for a, b in pairs:
        z, ok = R._circle_points(x, c[a : a + 1], big[a : a + 1], c[b : b + 1], big[b : b + 1])
        if not ok[0]:
            continue
        e2 = R._dot(x - z[0], x - z[0])
        if e2 <= rho2:
            cands.append((z[0], (ids[a], ids[b], -1)))
        if e2 <= rho2 * (1.0 + R.SLACK):
            for k in range(b + 1, len(ids)):
                z1, z2, okv = R._vertex_points(
                    c[a : a + 1], big[a : a + 1], c[b : b + 1], big[b : b + 1], c[k : k + 1], big[k : k + 1]
                )
                if okv[0]:
                    for zz in (z1[0], z2[0]):
                        if R._dot(x - zz, x - zz) <= rho2:
                            cands.append((zz, (ids[a], ids[b], ids[k])))
    res = []
    for reach_first in (False, True):
        hint, total, checks, nocorner, wet = -1, 0, 0, 0, False
        for z, own in cands:
            checks += 1
            ok, blocker, cost = check(self, z, own, near, hint, reach_first)
            total += cost
            if reach_first and cost == 1 and not ok and blocker < 0:
                nocorner += 1
            if blocker >= 0:
                hint = blocker
            if ok:
                wet = True
                break
        res.append((wet, checks, nocorner, total))
    assert res[0][0] == res[1][0]
    ROWS.append((int(res[0][0]), res[0][1], res[1][2], res[0][3], res[1][3]))


def main():
    a, _sc, rho, seconds = study_main(count)
    rows = np.array(ROWS, dtype=np.int64).reshape(-1, 5)
    print(f"{a.scene} rho={rho:.4g}: {len(rows)} tests, {seconds:.0f} s")
    wet = rows[:, 0] == 1
    for name, sel in (("all", slice(None)), ("wet", wet), ("dry", ~wet)):
        r = rows[sel]
        print(
            f"  {name:4s} {len(r):6d} tests: checks {r[:, 1].sum():8d}, with no reached corner {r[:, 2].sum():8d};"
            f" spheres read {r[:, 3].sum():10d} -> {r[:, 4].sum():10d}"
        )
    for k, name in ((3, "before"), (4, "reach first")):
        q = percentiles(rows[:, k])
        print(
            f"  spheres read per test, {name:11s}: median {q[0]:7.0f} p90 {q[1]:7.0f} p99 {q[2]:7.0f}"
            f" p99.9 {q[3]:7.0f} max {q[4]:7.0f}"
        )
    top = np.argsort(rows[:, 3])[-20:]
    print("  the 20 heaviest tests (wet, checks, no-corner checks, before, reach first):")
    for t_ in top[::-1]:
        print("   ", rows[t_].tolist())


if __name__ == "__main__":
    main()
