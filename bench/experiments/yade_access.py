"""Issue 24: how fast YADE lets a script read positions and set forces, on the SphereTest specimen (4,628 spheres).

Runs inside YADE, with an interpreter that sees warp_lamp (for the specimen and the lamp's own time)::

    PYTHONPATH=$PWD ~/yade-env/bin/python /usr/bin/yade -j1 -n -x bench/experiments/yade_access.py [OUT.json]

Reads: a Python loop over ``O.bodies`` in four spellings, and ``yade._utils.coordsAndDisplacements`` (a C++ loop,
one list per axis). Writes: ``O.forces.setPermF`` in four spellings, all rows, plus the first call in a scene (the
force container grows) and the adapter's changed-rows write after a small move. Each figure is a median of 7 after
a warm-up; every read is checked against the others and every write read back. Then the lamp's own call
(``EngineLamp.forces``) on the same positions, for the split.
"""

import itertools
import json
import sys
import time

import numpy as np
from yade import O
from yade._utils import coordsAndDisplacements
from yade.minieigenHP import Vector3
from yade.utils import sphere
from yade.wrapper import ForceResetter, NewtonIntegrator

from warp_lamp.engines import EngineLamp, YadeLamp
from warp_lamp.scenes import scene_sphere_specimen


def median_ms(fn, repeats=7):
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times) * 1e3)


def main(argv):
    s = scene_sphere_specimen()
    ids = O.bodies.append([sphere(tuple(c), float(r)) for c, r in zip(s.centers, s.radii, strict=True)])
    n = len(ids)
    O.engines = [ForceResetter(), NewtonIntegrator(damping=0.7)]
    O.dt = 1e-12
    f = np.random.default_rng(0).normal(size=(n, 3))
    t0 = time.perf_counter()
    for i, v in zip(ids, f.tolist(), strict=True):
        O.forces.setPermF(i, v)
    first_write = (time.perf_counter() - t0) * 1e3
    O.step()
    bodies = O.bodies
    states = [b.state for b in bodies]
    reads = {
        "np.array([b.state.pos for b in O.bodies])": lambda: np.array([b.state.pos for b in bodies]),
        "np.array([tuple(b.state.pos) for b in O.bodies])": lambda: np.array([tuple(b.state.pos) for b in bodies]),
        "np.fromiter(chain(b.state.pos for b in O.bodies))": lambda: np.fromiter(
            itertools.chain.from_iterable(b.state.pos for b in bodies), float, 3 * n
        ).reshape(n, 3),
        "states kept, np.array([tuple(st.pos) for st in states])": lambda: np.array([tuple(st.pos) for st in states]),
        "coordsAndDisplacements(axis), 3 calls": lambda: np.array([coordsAndDisplacements(a)[0] for a in range(3)]).T,
    }
    ref = np.array([tuple(b.state.pos) for b in bodies])
    out = {"n": n, "read_ms": {}, "write_ms": {}, "first_setPermF_call_ms": first_write}
    for name, fn in reads.items():
        assert np.array_equal(np.asarray(fn(), dtype=float), ref), name
        out["read_ms"][name] = median_ms(fn)
    set_force = O.forces.setPermF
    fl = f.tolist()
    writes = {
        "setPermF(i, Vector3(*f[i])), NumPy rows": lambda: [set_force(i, Vector3(*f[k])) for k, i in enumerate(ids)],
        "setPermF(i, Vector3(*row)), rows of f.tolist()": lambda: [
            set_force(i, Vector3(*v)) for i, v in zip(ids, fl, strict=True)
        ],
        "setPermF(i, row), rows of f.tolist()": lambda: [set_force(i, v) for i, v in zip(ids, fl, strict=True)],
        "map(setPermF, ids, f.tolist())": lambda: list(map(set_force, ids, fl)),
    }
    for name, fn in writes.items():
        O.forces.reset()
        out["write_ms"][name] = median_ms(fn)
        O.step()
        back = np.array([tuple(O.forces.permF(i)) for i in ids])
        assert np.array_equal(back, f), name
    # The adapter: a first call, then one after a move of 1e-6 m (a few hundred rows change).
    lamp = YadeLamp(10e6, ids=ids)
    lamp()
    rng = np.random.default_rng(1)
    moves = []
    for _ in range(7):
        for i in ids:
            b = O.bodies[i]
            b.state.pos = b.state.pos + Vector3(*rng.normal(0.0, 2e-7, 3))
        lamp()
        moves.append(lamp.written)
    cost = lamp.cost()
    out["adapter_ms"] = {clock: {k: v * 1e3 for k, v in cost[clock].items()} for clock in ("wall", "cpu")}
    out["adapter_rows_written"] = moves
    out["adapter_positions_ms"] = median_ms(lamp.positions)
    x = lamp.positions()
    core = EngineLamp(x, lamp.radii, 10e6)
    core.forces(x)
    out["lamp_own_ms"] = median_ms(lambda: core.forces(x))
    print(json.dumps(out, indent=1))
    if argv:
        with open(argv[0], "w") as fh:
            json.dump(out, fh, indent=1)


main(sys.argv[1:])
