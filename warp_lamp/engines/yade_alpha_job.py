"""YADE's own pressure boundary, alpha-shape caps, timed inside YADE: the job :mod:`warp_lamp.bench.engines` runs.

    yade -j1 -n -x warp_lamp/engines/yade_alpha_job.py IN.npz OUT.npz

Needs only YADE and NumPy (YADE's interpreter need not see warp). ``IN.npz`` holds ``centers`` (N, 3), ``radii``
(N,), ``pressure`` (P [Pa]), ``alpha`` and ``shrinked`` (K,) (the alpha-shape settings to try, each > 0) and
``repeats``. For each setting the job calls ``TesselationWrapper.applyAlphaForces(-P I, alpha, shrinkedAlpha,
fixedAlpha=True, reset=True)`` ``repeats`` times (``reset`` rebuilds the triangulation, as a moving body needs on
every call), runs one step with only a ``ForceResetter`` (``O.forces.permF`` reads zero until a step has run), and
reads the permanent forces back. ``OUT.npz`` gets ``forces`` (K, N, 3), ``seconds`` (K, repeats; wall clock) and
``cpu_seconds`` (K, repeats; this thread's CPU time, which other jobs on a shared machine do not inflate).

alpha = 0 (YADE's default, "the smallest alpha that keeps every sphere") crashes in CGAL on 2023.02a; the job
refuses it rather than take YADE down.
"""

import sys
import time

import numpy as np


def main(argv):
    from yade import O
    from yade.minieigenHP import Matrix3
    from yade.utils import sphere
    from yade.wrapper import ForceResetter, TesselationWrapper

    src, dst = argv[:2]
    data = np.load(src)
    centers, radii = data["centers"], data["radii"]
    pressure = float(data["pressure"])
    alphas, shrinked = np.atleast_1d(data["alpha"]), np.atleast_1d(data["shrinked"])
    repeats = int(data["repeats"])
    if np.any(alphas <= 0) or np.any(shrinked <= 0):
        raise SystemExit("alpha, shrinked: each must be > 0 (alpha = 0 crashes YADE 2023.02a in CGAL)")
    ids = O.bodies.append([sphere(tuple(c), float(r), fixed=True) for c, r in zip(centers, radii, strict=True)])
    O.engines = [ForceResetter()]
    O.dt = 1.0
    stress = -pressure * Matrix3.Identity
    forces = np.zeros((len(alphas), len(ids), 3))
    seconds = np.zeros((len(alphas), repeats))
    cpu_seconds = np.zeros((len(alphas), repeats))
    for k, (a, s) in enumerate(zip(alphas.tolist(), shrinked.tolist(), strict=True)):
        tw = TesselationWrapper()
        for rep in range(repeats):
            t0, c0 = time.perf_counter(), time.thread_time()
            tw.applyAlphaForces(stress, alpha=a, shrinkedAlpha=s, fixedAlpha=True, reset=True)
            seconds[k, rep] = time.perf_counter() - t0
            cpu_seconds[k, rep] = time.thread_time() - c0
        O.step()
        forces[k] = [tuple(O.forces.permF(i)) for i in ids]
        for i in ids:
            O.forces.setPermF(i, (0.0, 0.0, 0.0))
    np.savez(dst, forces=forces, seconds=seconds, cpu_seconds=cpu_seconds)


if __name__ == "__main__":
    main(sys.argv[1:])
