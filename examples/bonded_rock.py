"""A bonded-particle rock in the examples' Warp DEM, and its calibration: unconfined compression, Brazilian and
direct tension tests.

    python examples/bonded_rock.py --device cpu --json calibration.json   # the study's specimens, three seeds
    python examples/bonded_rock.py --tiny --device cpu                    # the CPU test's small specimens

The rock is the memo's Table 1 (PFC3D microproperties of Carthage limestone), in the spirit of PFC's parallel-bond
model (Potyondy and Cundall 2004): polydisperse balls (Rmax/Rmin = 1.66, 2620 kg/m^3) with linear contacts
(E_c = 100 GPa, kn/ks = 3.7, mu = 0.5) and, in parallel, bonds (lambda = 1, E_b = 100 GPa, kn/ks = 3.7) whose
tensile and shear strengths are drawn per bond from a normal distribution of mean 107 MPa and standard deviation
20 MPa (truncated at 10% of the mean). ``examples/dem.py`` holds the bond law (:func:`dem.dem_bonds`): normal and
shear stiffness per area, bending and twisting, broken for good in tension or in shear; BOND_FRICTION_DEG > 0
makes the shear strength rise with the bond's compression (PFC5's linear parallel bond; the memo's has none).

Specimens come from :func:`warp_lamp.scenes.scene_box_specimen` (or the cylinder specimen for the Brazilian disk):
a random packing relaxed to 1% overlap; every radius is then shrunk by SHRINK (0.5%), which leaves no pair
overlapping, so the bonds are installed at zero force with no locked-in contact force (an overlap of 1% of a
radius is a contact stress of a few hundred MPa at E_c = 100 GPa, more than a bond holds). Bonds join every pair
whose surfaces are closer than BOND_GAP of the smaller radius, and every particle gets at least MIN_BONDS (to its
nearest neighbours): a bond coordination number of about 6.3.

Time step: DT_FACTOR sqrt(m / k) of the smallest ball, k its contact (2 E_c R) and bond (E_b pi R / 2) stiffness
against an equal ball; real density, PFC local damping 0.7.

Calibration (platens frictionless and rigid, moving toward each other at a constant speed; grips held):

* Unconfined compression of a prism W x W x 2W: UCS = the peak of the mean platen force over W^2; Young's modulus
  from the secant between 20% and 50% of the peak.
* Brazilian test of a disk of diameter D and thickness D/2 (axis along y), flattened over FLAT_DEG at the two
  platens normal to z: sigma_t = 2 F_peak / (pi D t). At 14 particles across the disk crushes at the flats before
  it splits, so this is a lower bound that varies twofold between specimens.
* Direct tension of a prism W x W x 2W, a diameter's layer at each end held and the top one pulled: the tensile
  strength is the peak grip force over W^2.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import warp as wp

from warp_lamp.scenes import Scene, scene_box_specimen, scene_cylinder_specimen


def _sibling(name: str):
    """Import a sibling example by path: examples/ is no package, and the tests load examples by file."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name(f"{name}.py"))
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


dem = _sibling("dem")

# The memo's Table 1: PFC3D microproperties of Carthage limestone.
DENSITY = 2620.0  # [kg/m^3]
RATIO = 1.66  # Rmax / Rmin
E_C = 100e9  # contact modulus [Pa]
KN_KS = 3.7
MU = 0.5
BOND_LAMBDA = 1.0  # bond radius over the smaller ball radius
BOND_E = 100e9  # bond modulus [Pa]
BOND_KN_KS = 3.7
BOND_STRENGTH = 107e6  # mean tensile and shear strength of a bond [Pa]
BOND_STRENGTH_SD = 20e6  # their standard deviation [Pa]
#: Friction angle of the bonds' shear strength [degrees] (PFC5's linear parallel bond; 0 is PFC4's, the memo's).
BOND_FRICTION_DEG = 0.0
DAMPING = 0.7  # PFC local damping
#: Every radius shrinks by this fraction after packing: a relaxed packing keeps overlaps up to 1% of the smaller
#: radius, and two radii shrunk by 0.5% open every such pair.
SHRINK = 0.005
#: Bonds join pairs whose surfaces are closer than this fraction of the smaller radius.
BOND_GAP = 0.1
#: Bonds every particle gets at least (to its nearest neighbours): a particle with fewer, pushed by the lamp, would
#: cross its gap unopposed and strike the rock.
MIN_BONDS = 3
#: Time step over sqrt(m / k) of the smallest ball, k its contact and bond stiffness against an equal ball.
DT_FACTOR = 0.25
#: Loading angle of the Brazilian disk's flats [degrees]: flat platens on a round disk of 14 particles across crush
#: the one or two particles they first touch and give a peak that varies twofold from specimen to specimen; flats
#: spread the load (Wang et al. 2004's flattened disk, whose correction to the plain formula 2F / (pi D t) is a few
#: percent at 20 degrees; the plain formula is used).
FLAT_DEG = 20.0
#: Mean particle diameter of the study [m] (the CPU test uses the same).
PARTICLE_DIAMETER = 0.5e-3


def bond_pairs(centers, radii, gap: float) -> np.ndarray:
    """Pairs (i < j) whose surfaces are closer than ``gap`` times the smaller radius (overlapping pairs included),
    in lexicographic order; a cell list on the host. Shape (B, 2), int64."""
    c = np.asarray(centers, dtype=np.float64)
    r = np.asarray(radii, dtype=np.float64)
    n = len(r)
    if n < 2:
        return np.zeros((0, 2), dtype=np.int64)
    edge = 2.0 * r.max() * (1.0 + gap)
    cell = np.floor((c - c.min(axis=0)) / edge).astype(np.int64)
    dims = cell.max(axis=0) + 3
    key = ((cell[:, 0] + 1) * dims[1] + cell[:, 1] + 1) * dims[2] + cell[:, 2] + 1
    order = np.argsort(key, kind="stable")
    sorted_keys = key[order]
    found = []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                other = key + (dx * dims[1] + dy) * dims[2] + dz
                lo = np.searchsorted(sorted_keys, other, side="left")
                hi = np.searchsorted(sorted_keys, other, side="right")
                count = hi - lo
                i = np.repeat(np.arange(n), count)
                start = np.repeat(lo - (np.cumsum(count) - count), count)
                j = order[start + np.arange(len(i))]
                keep = i < j
                found.append(np.stack([i[keep], j[keep]], axis=1))
    p = np.concatenate(found)
    dist = np.linalg.norm(c[p[:, 1]] - c[p[:, 0]], axis=1)
    close = dist - r[p[:, 0]] - r[p[:, 1]] <= gap * np.minimum(r[p[:, 0]], r[p[:, 1]])
    p = p[close]
    return p[np.lexsort((p[:, 1], p[:, 0]))]


def ensure_bonds(pairs, centers, radii, minimum: int, reach: float = 1.0) -> np.ndarray:
    """``pairs`` with bonds added so that every particle has at least ``minimum`` (PFC's floater elimination): a
    particle short of them is bonded to its nearest unbonded neighbours by surface gap, closer than ``reach`` times
    the smaller radius, in index order. Sorted like :func:`bond_pairs`."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    n = len(radii)
    degree = np.bincount(pairs.ravel(), minlength=n)
    if degree.min() >= minimum:
        return pairs
    c = np.asarray(centers, dtype=np.float64)
    r = np.asarray(radii, dtype=np.float64)
    cand = bond_pairs(c, r, reach)
    gap = (np.linalg.norm(c[cand[:, 1]] - c[cand[:, 0]], axis=1) - r[cand[:, 0]] - r[cand[:, 1]]) / np.minimum(
        r[cand[:, 0]], r[cand[:, 1]]
    )
    have = {(int(i), int(j)) for i, j in pairs}
    added = []
    for i in np.flatnonzero(degree < minimum):
        if degree[i] >= minimum:
            continue
        mine = np.flatnonzero((cand[:, 0] == i) | (cand[:, 1] == i))
        for k in mine[np.argsort(gap[mine], kind="stable")]:
            pair = (int(cand[k, 0]), int(cand[k, 1]))
            if pair in have:
                continue
            have.add(pair)
            added.append(pair)
            degree[list(pair)] += 1
            if degree[i] >= minimum:
                break
    if not added:
        return pairs
    p = np.concatenate([pairs, np.array(added, dtype=np.int64)])
    return p[np.lexsort((p[:, 1], p[:, 0]))]


@dataclass
class RockParams:
    """The bonded rock's microproperties (defaults: the memo's Table 1)."""

    density: float = DENSITY
    e_c: float = E_C
    kn_ks: float = KN_KS
    mu: float = MU
    bond_lambda: float = BOND_LAMBDA
    bond_e: float = BOND_E
    bond_kn_ks: float = BOND_KN_KS
    strength: float = BOND_STRENGTH
    strength_sd: float = BOND_STRENGTH_SD
    bond_friction_deg: float = BOND_FRICTION_DEG
    damping: float = DAMPING
    gap: float = BOND_GAP

    def as_dict(self) -> dict:
        return dict(self.__dict__)


class BondedRock:
    """A bonded specimen: the DEM (:class:`dem.Dem`) and its bonds (:class:`dem.Bonds`), from a packed scene."""

    def __init__(
        self,
        scene: Scene,
        *,
        params: RockParams | None = None,
        seed: int = 0,
        frame_center=None,
        stats: bool = True,
        device=None,
    ):
        """Args:
        scene: The packing (centres [m], radii [m]); radii are shrunk by SHRINK here.
        params: Microproperties; the memo's by default.
        seed: Seed of the bond strengths.
        frame_center: Centre of the DEM's float32 frame [m]; the scene's centre by default.
        stats: Keep the DEM's unbalanced-force statistics (two float64 atomics per contact).
        device: Warp device.
        """
        self.params = p = params or RockParams()
        self.device = wp.get_device(device)
        self.scene = scene
        self.centers = np.asarray(scene.centers, dtype=np.float64)
        self.radii = np.asarray(scene.radii, dtype=np.float64) * (1.0 - SHRINK)
        r = self.radii
        self.n = len(r)
        self.d_mean = 2.0 * float(r.mean())
        self.mass = p.density * 4.0 / 3.0 * np.pi * r**3
        rmin = float(r.min())
        k = 2.0 * p.e_c * rmin + p.bond_e / (2.0 * rmin) * np.pi * (p.bond_lambda * rmin) ** 2
        self.dt = DT_FACTOR * float(np.sqrt(p.density * 4.0 / 3.0 * np.pi * rmin**3 / k))
        mat = dem.material(p.e_c, kn_ks=p.kn_ks, mu=p.mu, damping=p.damping)
        center = scene.center if frame_center is None else frame_center
        self.dem = dem.Dem(
            self.centers,
            r,
            self.mass,
            0.4 * self.mass * r**2,
            mat,
            self.dt,
            frame_center=center,
            stats=stats,
            device=device,
        )
        self.pairs = ensure_bonds(bond_pairs(self.centers, r, p.gap), self.centers, r, MIN_BONDS)
        b = len(self.pairs)
        rng = np.random.default_rng(seed)
        floor = 0.1 * p.strength
        self.tensile = np.maximum(rng.normal(p.strength, p.strength_sd, b), floor)
        self.shear = np.maximum(rng.normal(p.strength, p.strength_sd, b), floor)
        bond_radius = p.bond_lambda * np.minimum(r[self.pairs[:, 0]], r[self.pairs[:, 1]])
        self.bonds = dem.Bonds.create(
            self.pairs,
            bond_radius,
            self.tensile,
            self.shear,
            self.n,
            e_c=p.bond_e,
            kn_ks=p.bond_kn_ks,
            friction_deg=p.bond_friction_deg,
            device=device,
        )

    @property
    def coordination(self) -> float:
        """Bonds per particle (each bond counted at both ends)."""
        return 2.0 * len(self.pairs) / self.n

    def step(self, external: wp.array, *, planes=None, tool=None, fixed=None) -> None:
        """One cycle: contacts, bonds, then optional plane and tool contacts, integration with ``external`` forces,
        fixed particles held (``fixed`` = (ids, held positions)), the tool advanced."""
        sim = self.dem
        sim.begin()
        sim.contacts()
        sim.bonds(self.bonds)
        if planes is not None:
            sim.planes(planes)
        if tool is not None:
            sim.tool(tool, external)
        sim.integrate(external)
        if fixed is not None:
            sim.hold(*fixed)
        if tool is not None:
            sim.advance_tool(tool)

    def fragments(self) -> np.ndarray:
        """Component label of each particle (the smallest index of its connected component of intact bonds),
        computed on the device; a host copy."""
        self.bonds.components()
        return self.bonds.label.numpy().copy()


# --- calibration ----------------------------------------------------------------------------------------------


def _platen_test(
    rock: BondedRock,
    axis_lo: float,
    axis_hi: float,
    area_norm,
    *,
    strain_rate: float,
    stop: float,
    max_strain: float,
    check_every: int,
) -> dict:
    """Two frictionless platens normal to z close in at ``strain_rate`` of the gap per cycle (each moves half)
    until the platen force falls below ``stop`` of its peak at 1.5 times the peak's strain or later (or
    ``max_strain``); samples the mean platen force."""
    d = rock.device
    mat = dem.material(rock.params.e_c, kn_ks=rock.params.kn_ks, mu=0.0, damping=rock.params.damping)
    planes = dem.Planes.create([[0, 0, 1], [0, 0, -1]], [axis_lo, -axis_hi], rock.n, d, mat=mat)
    gap0 = axis_hi - axis_lo
    step = 0.5 * strain_rate * gap0
    speed = wp.array([step / rock.dt] * 2, dtype=wp.float64, device=d)
    total = wp.zeros(2, dtype=wp.float64, device=d)
    zero = wp.zeros(rock.n, dtype=wp.vec3, device=d)
    samples = []
    peak = 0.0
    at_peak = 0.0
    cycles = 0
    while True:
        for _ in range(check_every):
            rock.step(zero, planes=planes)
            wp.launch(
                dem.dem_plane_advance,
                dim=2,
                inputs=[speed, planes.normal, rock.dt],
                outputs=[planes.offset, planes.velocity, total, planes.reaction],
                device=d,
            )
        cycles += check_every
        f = total.numpy() / check_every
        total.zero_()
        strain = cycles * strain_rate
        force = float(f.mean())
        samples.append({"strain": strain, "force": force, "bottom": float(f[0]), "top": float(f[1])})
        if force > peak:
            peak, at_peak = force, strain
        # Past the peak for good: the force below ``stop`` of it, half as much strain again after it (a platen
        # crushing the particles it first touches drops the force for a while; the specimen's failure does not).
        if (peak > 0 and force < stop * peak and strain >= 1.5 * at_peak) or strain >= max_strain:
            break
    forces = np.array([s["force"] for s in samples])
    strains = np.array([s["strain"] for s in samples])
    k = int(np.argmax(forces))
    t, s = rock.bonds.broken_counts()
    return {
        "peak_force_N": float(forces[k]),
        "strain_at_peak": float(strains[k]),
        "samples": samples,
        "cycles": cycles,
        "broken_tensile": t,
        "broken_shear": s,
        "bonds": rock.bonds.count,
        "particles": rock.n,
        "coordination": rock.coordination,
        "area_m2": area_norm,
    }


def ucs_test(
    width_d: float = 10.0,
    *,
    particle_diameter: float = PARTICLE_DIAMETER,
    strain_rate: float = 5e-7,
    params: RockParams | None = None,
    seed: int = 0,
    check_every: int = 100,
    device=None,
) -> dict:
    """Unconfined compression of a W x W x 2W prism (W = ``width_d`` mean diameters): UCS [Pa], Young's modulus
    [Pa] (secant between 20% and 50% of the peak), the curve and the broken bonds. ``strain_rate``: axial strain
    per cycle."""
    w = width_d * particle_diameter
    scene = scene_box_specimen((w, w, 2.0 * w), particle_diameter, seed=seed)
    rock = BondedRock(scene, params=params, seed=seed, device=device)
    z = scene.centers[:, 2]
    lo = float(np.min(z - rock.radii))
    hi = float(np.max(z + rock.radii))
    t0 = time.perf_counter()
    out = _platen_test(rock, lo, hi, w * w, strain_rate=strain_rate, stop=0.7, max_strain=0.02, check_every=check_every)
    stress = np.array([s["force"] for s in out["samples"]]) / (w * w)
    strain = np.array([s["strain"] for s in out["samples"]])
    peak = float(stress.max())
    k = int(np.argmax(stress))
    pre = slice(0, k + 1)
    e = float("nan")
    s20 = np.interp(0.2 * peak, stress[pre], strain[pre])
    s50 = np.interp(0.5 * peak, stress[pre], strain[pre])
    if s50 > s20:
        e = 0.3 * peak / (s50 - s20)
    out.update(
        test="ucs",
        ucs_Pa=peak,
        young_Pa=e,
        width_m=w,
        height_m=2.0 * w,
        strain_rate_per_cycle=strain_rate,
        dt_s=rock.dt,
        seconds=time.perf_counter() - t0,
    )
    return out


def brazilian_test(
    diameter_d: float = 12.0,
    *,
    particle_diameter: float = PARTICLE_DIAMETER,
    flat_deg: float = FLAT_DEG,
    strain_rate: float = 1e-6,
    params: RockParams | None = None,
    seed: int = 0,
    check_every: int = 50,
    device=None,
) -> dict:
    """Brazilian test of a disk D across (``diameter_d`` mean diameters) and D/2 thick, axis along y, between
    platens normal to z, its top and bottom flattened over a loading angle 2 alpha = ``flat_deg`` (the particles
    beyond z = +-(D/2) cos alpha removed): tensile strength sigma_t = 2 F_peak / (pi D t) [Pa]. ``strain_rate``:
    platen closure per cycle over D."""
    dia = diameter_d * particle_diameter
    thick = 0.5 * dia
    # Particles to give the mean diameter asked for at the cylinder specimen's porosity rule.
    dmin = 2.0 * particle_diameter / (1.0 + RATIO)
    mean_d3 = dmin**3 * (RATIO**4 - 1.0) / (4.0 * (RATIO - 1.0))
    vol = np.pi * dia * dia / 4.0 * thick
    count = round(0.58 * vol / (np.pi / 6.0 * mean_d3))
    porosity = 0.39 + 0.35 * (1.8 / count) ** (1.0 / 3.0)
    count = round((1.0 - porosity) * vol / (np.pi / 6.0 * mean_d3))
    cyl = scene_cylinder_specimen(dia, thick, particles=count, porosity=porosity, seed=seed)
    c = cyl.centers[:, [0, 2, 1]]  # the disk's axis along y
    flat = 0.5 * dia * np.cos(np.radians(0.5 * flat_deg))
    keep = np.abs(c[:, 2]) + cyl.radii <= flat
    scene = Scene("Brazilian disk", c[keep], cyl.radii[keep], np.zeros(3))
    rock = BondedRock(scene, params=params, seed=seed, device=device)
    z = scene.centers[:, 2]
    lo = float(np.min(z - rock.radii))
    hi = float(np.max(z + rock.radii))
    t0 = time.perf_counter()
    out = _platen_test(
        rock, lo, hi, dia * thick, strain_rate=strain_rate, stop=0.5, max_strain=0.015, check_every=check_every
    )
    out.update(
        test="brazilian",
        tensile_Pa=2.0 * out["peak_force_N"] / (np.pi * dia * thick),
        diameter_m=dia,
        thickness_m=thick,
        flat_deg=flat_deg,
        strain_rate_per_cycle=strain_rate,
        dt_s=rock.dt,
        seconds=time.perf_counter() - t0,
    )
    return out


def tension_test(
    width_d: float = 10.0,
    *,
    particle_diameter: float = PARTICLE_DIAMETER,
    strain_rate: float = 5e-7,
    params: RockParams | None = None,
    seed: int = 0,
    check_every: int = 100,
    device=None,
) -> dict:
    """Direct tension of a W x W x 2W prism: the particles within a mean diameter of its bottom are held, those
    within a mean diameter of its top are held and pulled up at ``strain_rate`` of the height per cycle; the
    tensile strength is the peak of the force on the top grip over W^2 [Pa]."""
    w = width_d * particle_diameter
    scene = scene_box_specimen((w, w, 2.0 * w), particle_diameter, seed=seed)
    rock = BondedRock(scene, params=params, seed=seed, device=device)
    d = rock.device
    z = rock.centers[:, 2]
    r = rock.radii
    lo, hi = float(np.min(z - r)), float(np.max(z + r))
    bottom = np.flatnonzero(z - r < lo + particle_diameter)
    top = np.flatnonzero(z + r > hi - particle_diameter)
    grips = [
        (
            wp.array(ids.astype(np.int32), dtype=wp.int32, device=d),
            wp.array(rock.centers[ids], dtype=wp.vec3d, device=d),
        )
        for ids in (bottom, top)
    ]
    dz = strain_rate * (hi - lo)  # the top grip's step per cycle [m]
    step = wp.vec3d(0.0, 0.0, dz)
    pull = wp.zeros(3, dtype=wp.int64, device=d)
    zero = wp.zeros(rock.n, dtype=wp.vec3, device=d)
    sim = rock.dem
    samples = []
    peak, at_peak, cycles = 0.0, 0.0, 0
    t0 = time.perf_counter()
    while True:
        pull.zero_()
        for _ in range(check_every):
            sim.begin()
            sim.contacts()
            sim.bonds(rock.bonds)
            wp.launch(dem.dem_held_force, dim=len(top), inputs=[grips[1][0], sim.force], outputs=[pull], device=d)
            sim.integrate(zero)
            sim.hold(*grips[0])
            sim.hold(*grips[1], velocity=(0.0, 0.0, dz / rock.dt))
            wp.launch(dem.dem_held_advance, dim=len(top), inputs=[step], outputs=[grips[1][1]], device=d)
        cycles += check_every
        # The rock pulls the top grip down (-z) while the specimen holds: the tension it carries.
        force = float(-pull.numpy()[2] / dem.FORCE_SCALE / check_every)
        strain = cycles * strain_rate
        samples.append({"strain": strain, "force": force})
        if force > peak:
            peak, at_peak = force, strain
        if (peak > 0 and force < 0.3 * peak and strain >= 1.5 * at_peak) or strain >= 0.01:
            break
    t, s = rock.bonds.broken_counts()
    return {
        "test": "tension",
        "tensile_Pa": peak / (w * w),
        "peak_force_N": peak,
        "strain_at_peak": at_peak,
        "samples": samples,
        "cycles": cycles,
        "broken_tensile": t,
        "broken_shear": s,
        "bonds": rock.bonds.count,
        "particles": rock.n,
        "coordination": rock.coordination,
        "width_m": w,
        "strain_rate_per_cycle": strain_rate,
        "dt_s": rock.dt,
        "seconds": time.perf_counter() - t0,
    }


#: Specimen sizes (mean diameters across) of the study and of the CPU test.
CALIBRATION_SIZES = {"study": {"ucs": 10.0, "brazilian": 14.0}, "tiny": {"ucs": 6.0, "brazilian": 12.0}}


def calibrate(
    size: str = "study", *, seeds=(0, 1, 2), params: RockParams | None = None, device=None, verbose: bool = False
) -> dict:
    """The three tests at ``size`` ("study" or "tiny") on specimens of each seed (packing and bond strengths):
    UCS, Brazilian and direct tensile strength, Young's modulus, as means over the seeds with their range."""
    dims = CALIBRATION_SIZES[size]
    runs = {"ucs": [], "brazilian": [], "tension": []}
    for seed in seeds:
        u = ucs_test(dims["ucs"], params=params, seed=seed, device=device)
        b = brazilian_test(dims["brazilian"], params=params, seed=seed, device=device)
        t = tension_test(dims["ucs"], params=params, seed=seed, device=device)
        runs["ucs"].append(u)
        runs["brazilian"].append(b)
        runs["tension"].append(t)
        if verbose:
            print(
                f"  seed {seed}: UCS {u['ucs_Pa'] / 1e6:.1f} MPa, E {u['young_Pa'] / 1e9:.1f} GPa ({u['particles']} "
                f"particles, {u['cycles']} cycles, {u['seconds']:.1f} s); Brazilian {b['tensile_Pa'] / 1e6:.1f} MPa "
                f"({b['particles']} particles, {b['cycles']} cycles, {b['seconds']:.1f} s); direct tension "
                f"{t['tensile_Pa'] / 1e6:.1f} MPa ({t['cycles']} cycles, {t['seconds']:.1f} s)",
                flush=True,
            )

    def stat(key, test):
        v = np.array([r[key] for r in runs[test]])
        return float(v.mean()), [float(v.min()), float(v.max())]

    ucs, ucs_range = stat("ucs_Pa", "ucs")
    bra, bra_range = stat("tensile_Pa", "brazilian")
    ten, ten_range = stat("tensile_Pa", "tension")
    young, _ = stat("young_Pa", "ucs")
    return {
        "size": size,
        "seeds": list(seeds),
        "ucs_Pa": ucs,
        "ucs_range_Pa": ucs_range,
        "tensile_Pa": bra,
        "tensile_range_Pa": bra_range,
        "direct_tensile_Pa": ten,
        "direct_tensile_range_Pa": ten_range,
        "ucs_over_tensile": ucs / bra,
        "ucs_over_direct_tensile": ucs / ten,
        "young_Pa": young,
        "coordination": float(np.mean([u["coordination"] for u in runs["ucs"]])),
        "params": (params or RockParams()).as_dict(),
        **runs,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tiny", action="store_true", help="the CPU test's small specimens")
    parser.add_argument("--device", default=None)
    parser.add_argument("--bond-friction-deg", type=float, default=BOND_FRICTION_DEG, help="bond friction angle")
    parser.add_argument("--json", default=None, help="write the results as JSON")
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    params = RockParams(bond_friction_deg=args.bond_friction_deg)
    out = calibrate("tiny" if args.tiny else "study", params=params, device=args.device, verbose=True)
    out["device"] = str(wp.get_device(args.device))
    print(
        f"UCS {out['ucs_Pa'] / 1e6:.1f} MPa, Brazilian sigma_t {out['tensile_Pa'] / 1e6:.1f} MPa, direct tension "
        f"{out['direct_tensile_Pa'] / 1e6:.1f} MPa, UCS / sigma_t {out['ucs_over_tensile']:.1f}, "
        f"E {out['young_Pa'] / 1e9:.1f} GPa"
    )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
