"""The memo's SphereTest in YADE: a 100 mm ball of 4,628 spheres held by a 10 MPa shining lamp.

Runs inside YADE (Debian's ``yade`` package, 2023.02a), whose interpreter must see warp-lang and warp_lamp::

    apt-get install yade
    /usr/bin/python3 -m venv --system-site-packages ~/yade-env && ~/yade-env/bin/pip install -e .   # in this checkout
    ~/yade-env/bin/python /usr/bin/yade -j1 -n -x examples/yade_sphere_test.py [--every 10] [--steps 6000]

The lamp is :class:`warp_lamp.engines.YadeLamp`, called by a ``PyRunner`` every ``--every`` iterations (the memo's
``ct_pressrate``); it sets each sphere's permanent force with ``O.forces.setPermF``. The contact law is YADE's
linear ``FrictPhys`` with Cundall-Strack friction, the memo's Table 1 as ``examples/sphere_test.py`` has it: a
contact of balls R1, R2 has kn = 4 E_c R1 R2 / (R1 + R2), E_c = 100 GPa (YADE's ``FrictMat.young`` = 2 E_c, as YADE
takes kn = 2 E R1 R2 / (R1 + R2)), ks = kn / 3.7 (``poisson`` = 1 / 3.7), mu = 0.5; density 2620 kg/m^3; YADE's
non-viscous damping 0.7 (PFC's local damping). Masses are scaled as in the Warp example (``examples/sphere_test.py``):
m = 4 (4 E_c R) at a unit time step, rotational inertia 0.8 m R^2, so that every sphere has the same critical
step; statics do not depend on mass. (YADE 2023.02a's own ``GlobalStiffnessTimeStepper(densityScaling=True)`` set
the unit step but left the masses alone here, and the ball flew apart.)

At the end it prints the stress in the 90 mm measurement sphere (PFC's formula with the porosity correction,
:func:`warp_lamp.measures.sphere_stress`) over P, and the adapter's cost per call (read, lamp, write) against the
lamp's own.
"""

import argparse
import json
import sys
import time
from math import atan

import numpy as np

from warp_lamp.engines import YadeLamp, yade_contacts
from warp_lamp.measures import sphere_stress
from warp_lamp.scenes import scene_sphere_specimen

try:
    from yade import O
    from yade.utils import sphere, unbalancedForce
    from yade.wrapper import (
        Bo1_Sphere_Aabb,
        ForceResetter,
        FrictMat,
        Ig2_Sphere_Sphere_ScGeom,
        InsertionSortCollider,
        InteractionLoop,
        Ip2_FrictMat_FrictMat_FrictPhys,
        Law2_ScGeom_FrictPhys_CundallStrack,
        NewtonIntegrator,
        PyRunner,
    )
except ImportError:
    sys.exit("run this inside YADE: ~/yade-env/bin/python /usr/bin/yade -j1 -n -x examples/yade_sphere_test.py")

# YADE's launcher runs this script in its own globals: a global named ``opts`` would break YADE's exit, and the
# PyRunner's command "lamp()" finds the adapter there (warp_lamp.engines.yade lists the traps).
E_C = 100e9  # contact modulus [Pa]: a ball's normal stiffness is 4 E_c R
KN_KS = 3.7
MU = 0.5
DAMPING = 0.7
DENSITY = 2620.0  # [kg/m^3]
PRESSURE = 10e6  # [Pa]
MASS_SCALE = 4.0  # mass / ball stiffness at dt = 1, as examples/sphere_test.py


def build(scene):
    """The specimen's spheres, the memo's contact law, and the engines with a slot for the lamp's PyRunner."""
    mat = O.materials.append(
        FrictMat(young=2.0 * E_C, poisson=1.0 / KN_KS, frictionAngle=atan(MU), density=DENSITY, label="balls")
    )
    ids = O.bodies.append(
        [sphere(tuple(c), float(r), material=mat) for c, r in zip(scene.centers, scene.radii, strict=True)]
    )
    for i, r in zip(ids, scene.radii, strict=True):
        m = MASS_SCALE * 4.0 * E_C * float(r)
        state = O.bodies[i].state
        state.mass = m
        state.inertia = (0.8 * m * r * r,) * 3
    return ids


def engines(every: int):
    return [
        ForceResetter(),
        InsertionSortCollider([Bo1_Sphere_Aabb()]),
        InteractionLoop(
            [Ig2_Sphere_Sphere_ScGeom()], [Ip2_FrictMat_FrictMat_FrictPhys()], [Law2_ScGeom_FrictPhys_CundallStrack()]
        ),
        PyRunner(command="lamp()", iterPeriod=every, label="lamp_runner"),
        NewtonIntegrator(damping=DAMPING),
    ]


def measure(scene, ids, diameter=0.09):
    """Stress [Pa] in the measurement sphere (compression positive) from YADE's contacts."""
    pairs, forces = yade_contacts(ids)
    x = np.array([tuple(O.bodies[i].state.pos) for i in ids])
    r = np.array([O.bodies[i].shape.radius for i in ids])
    return sphere_stress(x, r, pairs, forces, scene.center, diameter)


def main(argv):
    parser = argparse.ArgumentParser(description="The memo's SphereTest in YADE, confined by the shining lamp.")
    parser.add_argument("--cells", type=float, default=4.0, help="lamp cells per mean diameter")
    parser.add_argument("--every", type=int, default=10, help="lamp update every n iterations (ct_pressrate)")
    parser.add_argument("--steps", type=int, default=6000, help="most iterations")
    parser.add_argument("--tol", type=float, default=1e-4, help="stop when YADE's unbalanced force ratio is below")
    parser.add_argument("--check", type=int, default=500, help="iterations between checks")
    parser.add_argument("--json", default=None, help="write the result as JSON")
    args = parser.parse_args(argv)
    t_start = time.perf_counter()
    scene = scene_sphere_specimen()
    ids = build(scene)
    O.engines = engines(args.every)
    O.dt = 1.0  # the scaled masses' unit time step
    global lamp
    lamp = YadeLamp(PRESSURE, ids=ids, cells_per_diameter=args.cells)
    lamp()  # forces from the start (the PyRunner's first call comes at iteration `every`)
    print(
        f"{len(ids):,} spheres, lamp grid {lamp.core.grid.counts[0].tolist()} cells per face, update every "
        f"{args.every} iterations",
        flush=True,
    )
    t0 = time.perf_counter()
    history = []
    unbalanced = float("inf")
    while O.iter < args.steps:
        O.run(args.check, True)
        unbalanced = unbalancedForce()
        sigma = measure(scene, ids)
        mean = float(np.trace(sigma) / 3.0)
        history.append((O.iter, unbalanced, mean / PRESSURE))
        print(
            f"  iteration {O.iter:6d}  unbalanced {unbalanced:.2e}  mean stress / P {mean / PRESSURE:.4f}", flush=True
        )
        if unbalanced < args.tol:
            break
    run_s = time.perf_counter() - t0
    sigma = measure(scene, ids)
    cost = lamp.cost()
    total_s = time.perf_counter() - t_start
    diag = np.diag(sigma) / 1e6
    off = max(abs(sigma[0, 1]), abs(sigma[0, 2]), abs(sigma[1, 2])) / 1e6
    mean = float(np.trace(sigma) / 3.0)
    print()
    print("| engine | iterations | unbalanced | sxx MPa | syy MPa | szz MPa | max off-diagonal MPa | mean / P |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    print(
        f"| YADE 2023.02a | {O.iter} | {unbalanced:.1e} | {diag[0]:.3f} | {diag[1]:.3f} | {diag[2]:.3f} | "
        f"{off:.3f} | {mean / PRESSURE:.3f} |"
    )
    print()
    wall, cpu = cost["wall"], cost["cpu"]
    print(
        f"Per lamp call (median of {cost['calls'] - 1}, first left out), {len(ids):,} spheres, one CPU thread, "
        "wall / CPU:"
    )
    print("| read (coordsAndDisplacements) | lamp (EngineLamp) | write (setPermF, changed rows) | total |")
    print("| --- | --- | --- | --- |")
    print(
        " | ".join(
            ["", *(f"{wall[k] * 1e3:.2f} / {cpu[k] * 1e3:.2f} ms" for k in ("read", "lamp", "write", "total")), ""]
        ).strip()
    )
    lamp_s = sum(lamp.timings.wall["lamp"])
    adapter_s = sum(map(sum, lamp.timings.wall.values()))
    print(
        f"\nRun: {run_s:.1f} s for {O.iter} iterations ({run_s / max(O.iter, 1) * 1e3:.2f} ms each, lamp calls "
        f"{lamp_s:.1f} s, all adapter calls {adapter_s:.1f} s); {total_s:.1f} s in all."
    )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(
                {
                    "engine": "YADE 2023.02a",
                    "n": len(ids),
                    "iterations": O.iter,
                    "unbalanced": unbalanced,
                    "sigma_Pa": sigma.tolist(),
                    "mean_over_P": mean / PRESSURE,
                    "every": args.every,
                    "cells_per_diameter": args.cells,
                    "cost_s": cost,
                    "run_s": run_s,
                    "total_s": total_s,
                    "history": history,
                },
                f,
                indent=1,
            )


main(sys.argv[1:])
