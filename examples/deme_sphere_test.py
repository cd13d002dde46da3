"""The memo's SphereTest in DEM-Engine (DEME 3): a 100 mm ball of 4,628 spheres held by a 10 MPa shining lamp, on a GPU.

    pip install -e ".[deme]"            # deme[cuda12]: DEME 3.0.19 and its CUDA 12.8 wheels
    python examples/deme_sphere_test.py [--every 10] [--steps 40000] [--quick] [--json out.json]

DEME runs in this Python process on one GPU; the lamp is :class:`warp_lamp.engines.DemeLamp` on the same GPU: every
``--every`` steps (the memo's ``ct_pressrate``) it reads DEME's positions into a Warp array on the device
(``tracker.PositionsToDevice``), runs the lamp and turns each sphere's force into its acceleration, which it queues
before every step (``tracker.AddAccFromDevice``; DEME drops it after one step). The first ``Initialize()`` on a
machine compiles DEME's kernels (about three minutes).

The specimen is the one the Warp, YADE and LAMMPS examples use (:func:`warp_lamp.scenes.scene_sphere_specimen`), each
sphere a one-sphere clump of its own radius (so 4,628 templates, kept in device arrays:
``DisableJitifyClumpTemplates``). The contact law is DEME's own frictional Hertz-Mindlin model (DEME has no linear
spring law built in): E = 100 GPa (the memo's contact modulus), Poisson 0.27 (1 / 3.7, the memo's kn / ks),
friction mu = 0.5, no rolling resistance, restitution 0.2 for damping (DEME has no local damping: its contact
dashpots settle the ball), density 2620 kg/m^3, no gravity, a time step of a tenth of the smallest sphere's Rayleigh
time. DEME's domain is ``BOX`` (+-0.42 m): DEME compiles its box and templates into its kernels, and this one also
holds the share bench's 1M-sphere ball (``bench/deme_share.py``), so DEME compiles once for both. Statics do not
depend on the law's stiffness or the masses: the ball should sit at about 0.96 P, as in the other engines.

At each check it prints the stress in the 90 mm measurement sphere (PFC's formula with the porosity correction,
:func:`warp_lamp.measures.sphere_stress`, from DEME's contact forces, ``GetContactDetailedInfo``) over P, centred
on the spheres' centroid, and the unbalanced force ratio; at the end, the adapter's cost per update (read, lamp,
write) and per step (queueing the load, DEME's step).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import warp as wp

from warp_lamp.engines import DemeLamp, add_deme_spheres, load_deme
from warp_lamp.measures import sphere_stress
from warp_lamp.scenes import scene_sphere_specimen

E = 100e9  # Young's modulus [Pa]
NU = 1.0 / 3.7
MU = 0.5
COR = 0.2  # restitution: the contact dashpots' damping
DENSITY = 2620.0  # [kg/m^3]
PRESSURE = 10e6  # [Pa]
MEASURE = 0.09  # measurement sphere diameter [m]
#: DEME's domain [m]: DEME compiles its box into its kernels, so one box for this ball and the share bench's 1M-sphere
#: ball (bench/deme_share.py) lets DEME compile once for both.
BOX = ((-0.42, 0.42),) * 3


def rayleigh_step(radius: float, *, young: float = E, poisson: float = NU, density: float = DENSITY) -> float:
    """The Rayleigh time of a sphere [s], pi r sqrt(rho / G) / (0.1631 nu + 0.8766), G = E / (2 (1 + nu))."""
    shear = young / (2.0 * (1.0 + poisson))
    return np.pi * radius * np.sqrt(density / shear) / (0.1631 * poisson + 0.8766)


def build(deme, centers, radii, *, dt: float, cor: float = COR, box=BOX, template_radii=None, verbosity="WARNING"):
    """A DEME solver on one GPU with the spheres (one-sphere clumps, templates in device arrays) in ``box``
    (((xlo, xhi), (ylo, yhi), (zlo, zhi)) [m]), initialised; ``template_radii``: templates to load besides the
    spheres' own (:func:`~warp_lamp.engines.add_deme_spheres`). Returns ``(solver, tracker, init_seconds)``."""
    lo, hi = np.array([b[0] for b in box]), np.array([b[1] for b in box])
    if np.any(centers - radii[:, None] < lo) or np.any(centers + radii[:, None] > hi):
        raise ValueError(f"box: the spheres reach outside {box}")
    solver = deme.DEMSolver(1)
    solver.SetVerbosity(verbosity)
    mat = solver.LoadMaterial({"E": E, "nu": NU, "CoR": cor, "mu": MU, "Crr": 0.0})
    _, tracker = add_deme_spheres(solver, centers, radii, mat, density=DENSITY, template_radii=template_radii)
    solver.InstructBoxDomainDimension(*[(float(a), float(b)) for a, b in box])
    solver.SetGravitationalAcceleration([0.0, 0.0, 0.0])
    solver.SetInitTimeStep(dt)
    solver.DisableJitifyClumpTemplates()
    solver.DisableJitifyMassProperties()
    solver.SetErrorOutAvgContacts(200.0)
    t0 = time.perf_counter()
    solver.Initialize()
    return solver, tracker, time.perf_counter() - t0


def _vec3s(values) -> np.ndarray:
    """DEME's ``list[float3]`` as an (n, 3) float64 array (sequences of three numbers, or objects with x, y, z)."""
    values = list(values)
    try:
        return np.asarray(values, dtype=np.float64).reshape(-1, 3)
    except (TypeError, ValueError):
        return np.array([[v.x, v.y, v.z] for v in values], dtype=np.float64).reshape(-1, 3)


def contacts(solver, owner_ids, positions):
    """DEME's sphere-sphere contacts among the tracked owners: pairs as tracker indices, shape (C, 2), and the force
    each contact puts on its first sphere [N], shape (C, 3); and which owner DEME's force acts on ("A" or "B",
    found from the forces themselves: a repulsive force on A points from B to A)."""
    info = solver.GetContactDetailedInfo()
    a = np.asarray(info.GetAOwner(), dtype=np.int64)
    b = np.asarray(info.GetBOwner(), dtype=np.int64)
    f = _vec3s(info.GetForce())
    ids = np.asarray(owner_ids, dtype=np.int64)
    where = np.full(int(max(ids.max(), a.max(initial=0), b.max(initial=0))) + 1, -1, dtype=np.int64)
    where[ids] = np.arange(len(ids))
    i, j = where[a], where[b]
    keep = (i >= 0) & (j >= 0) & np.any(f != 0.0, axis=1)
    pairs, forces = np.stack([i[keep], j[keep]], axis=1), f[keep]
    side = "A"
    if len(pairs) and np.einsum("ij,ij->", forces, positions[pairs[:, 0]] - positions[pairs[:, 1]]) < 0:
        forces, side = -forces, "B"
    return pairs, forces, side


def state(solver, lamp: DemeLamp, radii):
    """Stress in the measurement sphere [Pa] (centred on the centroid), the unbalanced force ratio (mean |contact
    + lamp force| per sphere over the mean contact force), the contact count, and the side DEME's forces act on."""
    x = np.asarray(lamp.tracker.Positions(), dtype=np.float64)
    pairs, forces, side = contacts(solver, lamp.owner_ids, x)
    if len(pairs) == 0:
        return np.zeros((3, 3)), float("nan"), 0, side
    sigma = sphere_stress(x, radii, pairs, forces, x.mean(axis=0), MEASURE)
    net = np.zeros_like(x)
    np.add.at(net, pairs[:, 0], forces)
    np.subtract.at(net, pairs[:, 1], forces)
    net += lamp.forces()
    ratio = float(np.linalg.norm(net, axis=1).mean() / np.linalg.norm(forces, axis=1).mean())
    return sigma, ratio, len(pairs), side


def run(
    deme,
    scene,
    *,
    every=10,
    steps=40000,
    check=2000,
    tol=2e-3,
    cells=4.0,
    cor=COR,
    box=BOX,
    device=None,
    keep=None,
    log=print,
):
    """Settle the ball under the lamp; returns the result dict (stress, history, costs). ``box``: DEME's domain;
    ``keep``, a dict, receives the ``solver``, ``tracker`` and ``lamp`` for more work on the settled ball."""
    t_start = time.perf_counter()
    dt = 0.1 * rayleigh_step(float(scene.radii.min()))
    solver, tracker, init_s = build(deme, scene.centers, scene.radii, dt=dt, cor=cor, box=box)
    options = {"device": device} if device else {}
    lamp = DemeLamp(solver, tracker, PRESSURE, radii=scene.radii, every=every, cells_per_diameter=cells, **options)
    log(
        f"DEME {getattr(deme, '__version__', '?')}, {scene.n:,} spheres, Initialize {init_s:.1f} s, step {dt:.3g} s, "
        f"lamp on {lamp.device} ({lamp.transfer} transfer), grid {lamp.core.grid.counts[0].tolist()} cells per face, "
        f"update every {every} steps"
    )
    history, done, ratio, sigma, n_contacts, side = [], 0, float("inf"), np.zeros((3, 3)), 0, "A"
    t0 = time.perf_counter()
    while done < steps:
        n = min(check, steps - done)
        lamp.step(n)
        done += n
        sigma, ratio, n_contacts, side = state(solver, lamp, scene.radii)
        mean = float(np.trace(sigma) / 3.0)
        history.append((done, ratio, mean / PRESSURE))
        log(f"  step {done:6d}  unbalanced {ratio:.2e}  mean stress / P {mean / PRESSURE:.4f}  contacts {n_contacts}")
        if ratio < tol:
            break
    run_s = time.perf_counter() - t0
    mean = float(np.trace(sigma) / 3.0)
    if keep is not None:
        keep.update(solver=solver, tracker=tracker, lamp=lamp)
    return {
        "engine": f"DEME {getattr(deme, '__version__', '?')}",
        "device": str(lamp.device),
        "gpu": wp.get_device(lamp.device).name if lamp.device.is_cuda else "cpu",
        "n": scene.n,
        "steps": done,
        "dt_s": dt,
        "unbalanced": ratio,
        "sigma_Pa": sigma.tolist(),
        "mean_over_P": mean / PRESSURE,
        "contacts": n_contacts,
        "deme_force_on": side,
        "every": every,
        "cells_per_diameter": cells,
        "restitution": cor,
        "transfer": lamp.transfer,
        "cost_s": lamp.cost(),
        "initialize_s": init_s,
        "run_s": run_s,
        "total_s": time.perf_counter() - t_start,
        "history": history,
    }


def report(result: dict) -> str:
    """The stress row and the cost table, as Markdown."""
    s = np.asarray(result["sigma_Pa"])
    diag, off = np.diag(s) / 1e6, max(abs(s[0, 1]), abs(s[0, 2]), abs(s[1, 2])) / 1e6
    c = result["cost_s"]
    wall, cpu = c["wall"], c["cpu"]
    per_step = c["step"] + c["apply"] + wall["total"] / result["every"]
    lines = [
        "| engine | steps | unbalanced | sxx MPa | syy MPa | szz MPa | max off-diagonal MPa | mean / P |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
        f"| {result['engine']} | {result['steps']} | {result['unbalanced']:.1e} | {diag[0]:.3f} | {diag[1]:.3f} | "
        f"{diag[2]:.3f} | {off:.3f} | {result['mean_over_P']:.3f} |",
        "",
        f"Per lamp update (median of {c['calls'] - 1}), {result['n']:,} spheres on {result['gpu']}, wall / CPU:",
        "| read (DEME -> Warp) | lamp (update, forces) | write (owner accelerations) | total |",
        "| --- | --- | --- | --- |",
        f"| {wall['read'] * 1e6:.1f} / {cpu['read'] * 1e6:.1f} us | {wall['lamp'] * 1e6:.1f} / {cpu['lamp'] * 1e6:.1f} "
        f"us | {wall['write'] * 1e6:.1f} / {cpu['write'] * 1e6:.1f} us | {wall['total'] * 1e6:.1f} / "
        f"{cpu['total'] * 1e6:.1f} us |",
        "",
        f"Per step: DEME step {c['step'] * 1e6:.1f} us, queueing the load {c['apply'] * 1e6:.1f} us, the lamp's update "
        f"over {result['every']} steps {wall['total'] / result['every'] * 1e6:.1f} us: the lamp's share "
        f"{(c['apply'] + wall['total'] / result['every']) / per_step:.1%}.",
        f"Run: {result['run_s']:.1f} s for {result['steps']} steps; Initialize {result['initialize_s']:.1f} s; "
        f"{result['total_s']:.1f} s in all.",
    ]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cells", type=float, default=4.0, help="lamp cells per mean diameter")
    parser.add_argument("--every", type=int, default=10, help="lamp update every n steps (ct_pressrate)")
    parser.add_argument("--steps", type=int, default=40000, help="most steps")
    parser.add_argument("--check", type=int, default=2000, help="steps between checks")
    parser.add_argument("--tol", type=float, default=2e-3, help="stop when the unbalanced force ratio is below")
    parser.add_argument("--cor", type=float, default=COR, help="restitution (contact damping)")
    parser.add_argument("--quick", action="store_true", help="a short run: 6,000 steps, checks every 1,000")
    parser.add_argument("--json", default=None, help="write the result as JSON")
    args = parser.parse_args(argv)
    if args.quick:
        args.steps, args.check = min(args.steps, 6000), min(args.check, 1000)
    wp.config.log_level = wp.LOG_WARNING
    deme = load_deme()
    result = run(
        deme,
        scene_sphere_specimen(),
        every=args.every,
        steps=args.steps,
        check=args.check,
        tol=args.tol,
        cells=args.cells,
        cor=args.cor,
        log=lambda m: print(m, flush=True),
    )
    print()
    print(report(result))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
