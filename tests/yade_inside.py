"""Run inside YADE by tests/test_engines.py: checks of YadeLamp and yade_contacts, written to a JSON file.

<python that sees warp> /usr/bin/yade -j1 -n -x tests/yade_inside.py OUT.json
"""

import json
import sys

import numpy as np
from yade import O
from yade.utils import box, sphere
from yade.wrapper import (
    Bo1_Box_Aabb,
    Bo1_Sphere_Aabb,
    ForceResetter,
    FrictMat,
    Ig2_Sphere_Sphere_ScGeom,
    InsertionSortCollider,
    InteractionLoop,
    Ip2_FrictMat_FrictMat_FrictPhys,
    Law2_ScGeom_FrictPhys_CundallStrack,
    NewtonIntegrator,
)

import warp_lamp as wl
from warp_lamp.engines import YadeLamp, yade_contacts
from warp_lamp.scenes import scene_lattice_ball


def main(out_path):
    out = {}
    scene = scene_lattice_ball(0.04, 0.005)
    O.materials.append(FrictMat(young=2e8, poisson=0.27, frictionAngle=0.46, density=2620.0))
    # A box first and a body erased, so that sphere ids are not 0..N-1 and coordsAndDisplacements lists a non-sphere.
    O.bodies.append(box((0, 0, -1), (0.1, 0.1, 0.01), fixed=True))
    gone = O.bodies.append(sphere((0, 0, 1), 0.001))
    ids = O.bodies.append([sphere(tuple(c), float(r)) for c, r in zip(scene.centers, scene.radii, strict=True)])
    O.bodies.erase(gone)
    O.engines = [
        ForceResetter(),
        InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Box_Aabb()]),
        InteractionLoop(
            [Ig2_Sphere_Sphere_ScGeom()], [Ip2_FrictMat_FrictMat_FrictPhys()], [Law2_ScGeom_FrictPhys_CundallStrack()]
        ),
        NewtonIntegrator(damping=0.7),
    ]
    O.dt = 1e-6
    lamp = YadeLamp(1e5)
    out["ids_found"] = sorted(lamp.ids.tolist()) == sorted(ids)
    out["n"] = len(ids)
    x = np.array([tuple(O.bodies[i].state.pos) for i in lamp.ids.tolist()])
    out["positions_equal"] = bool(np.array_equal(lamp.positions(), x))
    lamp()
    expected = wl.lamp_forces(x, lamp.radii, 1e5, grid=lamp.core.grid, device="cpu")
    # permF reads zero until a step has run (a trap this checks); f() shows the force at once.
    out["permF_before_step_zero"] = bool(np.all(np.array(tuple(O.forces.permF(lamp._ids_list[0]))) == 0))
    f_now = np.array([tuple(O.forces.f(i)) for i in lamp._ids_list])
    out["forces_equal"] = bool(np.array_equal(f_now, expected))
    out["first_written"] = lamp.written
    lamp()
    out["second_written"] = lamp.written
    lamp.rewrite_all()
    lamp()
    out["rewritten"] = lamp.written
    O.run(20, True)
    perm = np.array([tuple(O.forces.permF(i)) for i in lamp._ids_list])
    out["perm_kept"] = bool(np.array_equal(perm, expected))
    lamp()
    out["moved_written"] = lamp.written
    moved = np.array([tuple(O.bodies[i].state.pos) for i in lamp._ids_list])
    after = wl.lamp_forces(moved, lamp.radii, 1e5, grid=lamp.core.grid, device="cpu")
    O.step()
    # The contacts' forces and the lamp's add up to each body's force (the sign of yade_contacts).
    pairs, forces = yade_contacts(lamp.ids)
    net = np.zeros((len(lamp.ids), 3))
    np.add.at(net, pairs[:, 0], forces)
    np.subtract.at(net, pairs[:, 1], forces)
    net += after
    total = np.array([tuple(O.forces.f(i)) for i in lamp._ids_list])
    out["contacts"] = len(pairs)
    out["net_error"] = float(np.abs(net - total).max() / np.abs(total).max())
    lamp.clear()
    O.step()
    out["cleared"] = bool(np.all(np.array([tuple(O.forces.permF(i)) for i in lamp._ids_list]) == 0))
    cost = lamp.cost()
    out["cost_keys"] = sorted(cost), sorted(cost["wall"]), sorted(cost["cpu"])
    out["calls"] = lamp.calls
    with open(out_path, "w") as f:
        json.dump(out, f)


main(sys.argv[1])
