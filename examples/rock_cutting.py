"""Rock cutting under mud pressure: the memo's own application (its first paragraph, section 1.1) and section 1.6.

    python examples/rock_cutting.py --json rock-cutting.json --plot rock-cutting.png     # the study (a GPU)
    python examples/rock_cutting.py --tiny --device cpu                                   # the same path, tiny
    python examples/rock_cutting.py --report rock-cutting.json --plot rock-cutting.png    # tables and figures

A rigid cutter moves at a set velocity and depth of cut across a bonded-particle rock slab, and the forces on it and
the damage in the rock are monitored, while drilling mud presses on the rock: the shining lamp puts the pressure P
on the surface, either the memo's way (``surfaces="first"``: each lamp loads the first particle its rays meet) or
on every wetted surface (``surfaces="all"``: the boundary of the region a probe ball of radius rho reaches from
outside, :mod:`warp_lamp.wetted`).

* Rock: ``examples/bonded_rock.py`` (the memo's Table 1 microproperties of Carthage limestone, PFC-style parallel
  bonds, calibrated there by unconfined compression and Brazilian tests). The slab is a box specimen
  (``warp_lamp.scenes.scene_box_specimen``), its bottom layer (CLAMP_D mean diameters) clamped: those particles
  stay where they are, so the base holds the slab against the cutter and takes any load put on it.
* Cutter: a rigid box (``dem.dem_tool``) whose working face has a back rake of RAKE_DEG (the face leans forward
  over the rock, so its normal points forward and down, as a PDC cutter's), centred across the slab, its cutting
  edge DEPTH below the slab's top, driven along +x at a constant speed. It meets the particles only: the lamp does
  not know it (the memo: "The cutter is assumed to interact with the rock, but not with the membrane"), so the
  lamp's rays pass through it and the particles it touches are loaded by P too. The force the cutter measures is
  then what a dynamometer on a cutter in the fluid reads: the contact force less the fluid's push on the cutter.
  ``face_lamp`` reports the lamp's force on the particles the cutter touches: added to the cutter's force, it gives
  the total force across a cutter face that sealed the fluid off.
* The slab's base and the fluid (``base``, one switch): "clamped" (the default), all six lamps on, the -z lamp's
  load on the slab's bottom taken by the clamped layer, which does not move; "lamp-off", the -z lamp off (the
  memo's practice for a supported face: the base takes the top's load through the rock; but then anything the
  lamp lights from above and nothing lights from below, debris thrown past the slab's edge or a chip the fluid
  gets under, is pressed down with nothing pushing back); "wall", the lamp's walls
  (``ShiningLamp(walls=[((0, 0, z_base), (0, 0, 1))])``: the fluid cannot pass below the base). The cutter is no
  wall: it never meets the fluid.
* Lamp: ``ShiningLamp(grid, follow=True)`` on a box grid whose capacity is the lamp's domain (the slab's box with
  DOMAIN_SIDE depths of cut of room on its sides and DOMAIN_TOP above it, for the broken material) plus a radius
  and, in the wetted mode, the probe and a cell; a particle whose centre leaves the domain (debris thrown clear)
  drops out of the lamp (its ``active`` flag, set on the device), as if the mud had carried it off. Cells of a
  mean diameter / ``cells_per_diameter``, updated every ``update_every`` cycles, forces every cycle, the pressure
  a device value (ramped while the slab settles).
* Cycle: frame copy, the lamp (on its cycles), ball contacts, bonds, cutter contacts, integration, clamp, cutter
  step; the whole cycle in one CUDA graph on a GPU, eager on the CPU.
* Procedure: the pressure ramps up over ``ramp_cycles`` and holds for ``settle_cycles`` with the cutter at rest
  behind the slab; the cutter then travels ``travel`` at the speed that moves it a mean diameter every
  ``cycles_per_d`` cycles.

Measurements, every ``check_every`` cycles: the cutter's displacement, its mean cutting force F_c (the rock's push
against the motion, +x on the rock) and normal force F_n (the rock's push up on the cutter) since the last sample,
the lamp's force on the particles it touches, bonds broken in tension and in shear; every ``fragments_every``
samples the fragments (connected components of intact bonds, labelled on the device): the main body (the one
holding the clamped base), chips (fragments of at least CHIP_MIN particles), small fragments and loose particles.
Mechanical specific energy: the cutter's work over the volume it sweeps in the rock, MSE = sum F_c du / (w delta
u), over the steady part of the cut (from STEADY_FROM depths of cut past the slab's end face). At the end: the
damage zone (broken bonds below the cut's floor), the lamp's balance (the counts on every axis whose two lamps are
on sum to zero exactly; the float32 forces to float32 rounding), and where the two modes load the rock differently:
both lamps on the final configuration, summed over the trough's walls, its floor and the detached pile ahead of
the cutter (``region_loads``), each over the load a fluid at P would put there.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import warp as wp

import warp_lamp as wl
from warp_lamp.lamp import lamp_mask
from warp_lamp.scenes import scene_box_specimen


def _sibling(name: str):
    """Import a sibling example by path: examples/ is no package, and the tests load examples by file."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name(f"{name}.py"))
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


dem = _sibling("dem")
rock_mod = _sibling("bonded_rock")

RAKE_DEG = 15.0  # back rake of the cutter face [degrees]
TOOL_MU = 0.5  # cutter-rock friction
CLAMP_D = 1.0  # thickness of the clamped base layer [mean diameters]
CHIP_MIN = 5  # particles a detached fragment needs to count as a chip
STEADY_FROM = 2.0  # the steady part of the cut starts this many depths of cut past the slab's end face
DOMAIN_SIDE = 1.5  # the lamp's domain reaches this many depths of cut (plus a diameter) past the slab's sides
DOMAIN_TOP = 3.0  # ... and this many above its top
LAMPS_NO_BASE = ("-x", "+x", "-y", "+y", "+z")
BASES = ("auto", "lamp-off", "clamped", "wall")


@dataclass(frozen=True)
class CutConfig:
    """A cutting configuration; lengths in mean particle diameters d unless marked [m]."""

    name: str
    particle_diameter: float = rock_mod.PARTICLE_DIAMETER  # d [m]
    length: float = 26.0  # slab along the cut (x)
    width: float = 18.0  # slab across (y)
    height: float = 10.0  # slab depth (z)
    depth: float = 4.0  # depth of cut delta
    cutter_width: float = 10.0  # w
    end_margin: float = 5.0  # rock left ahead of the cutting edge at the end of the travel
    cycles_per_d: int = 3000  # cycles per mean diameter of cutter travel (sets the speed)
    ramp_cycles: int = 2000  # pressure ramp
    settle_cycles: int = 2000  # hold at P before the cut
    cells_per_diameter: float = 4.0
    probe_radius: float = 1.0  # the wetted mode's probe radius, in mean particle radii
    update_every: int = 10  # lamp update every n_u cycles (the memo's ct_pressrate)
    check_every: int = 500  # cycles between samples (a multiple of the captured block)
    fragments_every: int = 4  # samples between fragment labellings
    bond_friction_deg: float = rock_mod.BOND_FRICTION_DEG  # friction angle of the bonds' shear strength
    seed: int = 0


#: The GPU study: about 4,900 particles, delta = 4 d, w = 10 d.
STUDY = CutConfig("study")
#: The CPU test: about 440 particles, delta = 2 d, w = 4 d; the same code path.
TINY = CutConfig(
    "tiny",
    length=12.0,
    width=8.0,
    height=5.0,
    depth=2.0,
    cutter_width=4.0,
    end_margin=3.0,
    cycles_per_d=500,
    ramp_cycles=400,
    settle_cycles=400,
    cells_per_diameter=2.0,
    check_every=100,
    fragments_every=5,
)
#: Pressures of the study [Pa], in the order they run (the extremes first): 0 to about 9 times the calibrated
#: Brazilian tensile strength and 1.5 times the direct one, two thirds of the UCS (bonded_rock.py).
STUDY_PRESSURES = (0.0, 60e6, 20e6, 40e6, 10e6)
TINY_PRESSURES = (0.0, 60e6)


def resolve_base(base: str, surfaces: str) -> str:
    """The base treatment to use ("auto" is "clamped" in both modes), or ValueError naming ``base``."""
    if base not in BASES:
        raise ValueError(f"base: expected one of {BASES}, got {base!r}")
    if base == "auto":
        return "clamped"
    return base


class RockCutting(dem.BlockRunner):
    """The slab, its clamped base, the cutter, the lamp, one cycle, the procedure and the measurements."""

    def __init__(
        self,
        config: CutConfig = STUDY,
        *,
        pressure: float = 0.0,
        surfaces: str = "first",
        base: str = "auto",
        device=None,
        scene=None,
    ):
        """Args:
        config: Geometry, speed and lamp settings.
        pressure: Mud pressure P [Pa].
        surfaces: The lamp's mode: "first" (the memo's) or "all" (every wetted surface).
        base: How the slab's base meets the fluid (module docstring): "auto", "lamp-off", "clamped" or "wall".
        device: Warp device.
        scene: A ready packing of the slab's box instead of generating it (``scene_box_specimen``).
        """
        if surfaces not in ("first", "all"):
            raise ValueError(f"surfaces: expected 'first' or 'all', got {surfaces!r}")
        if not (np.isfinite(pressure) and pressure >= 0):
            raise ValueError(f"pressure: must be finite and >= 0 [Pa], got {pressure!r}")
        self.config = c = config
        self.device = d = wp.get_device(device)
        self.pressure_value = float(pressure)
        self.surfaces = surfaces
        self.base = resolve_base(base, surfaces)
        dd = c.particle_diameter
        size = np.array([c.length, c.width, c.height]) * dd
        self.scene = scene or scene_box_specimen(size, dd, seed=c.seed)
        params = rock_mod.RockParams(bond_friction_deg=c.bond_friction_deg)
        self.rock = rock_mod.BondedRock(self.scene, params=params, seed=c.seed, stats=False, device=d)
        self.dem = self.rock.dem
        self.n = self.rock.n
        r = self.rock.radii
        x0 = self.rock.centers
        self.d_mean = self.rock.d_mean
        self.size = size
        self.dt = self.rock.dt
        # Clamped base: every particle whose bottom lies within CLAMP_D of the slab's bottom.
        z_min = float(np.min(x0[:, 2] - r))
        self.z_base = z_min
        clamped = np.flatnonzero(x0[:, 2] - r < z_min + CLAMP_D * dd)
        self.clamped = clamped
        self.fixed = (
            wp.array(clamped.astype(np.int32), dtype=wp.int32, device=d),
            wp.array(x0[clamped], dtype=wp.vec3d, device=d),
        )
        # Cutter: face normal forward and down (back rake), edge across the slab, centred in y.
        theta = np.radians(RAKE_DEG)
        self.rake = theta
        self.depth = c.depth * dd
        self.cutter_width = c.cutter_width * dd
        self.z_top = float(size[2])
        self.z_cut = self.z_top - self.depth
        self.y_c = 0.5 * float(size[1])
        face = np.array([np.cos(theta), 0.0, -np.sin(theta)])
        # Start behind the slab: the face, leaning forward, clear of the end face up to a diameter above the top.
        self.x_start = -(self.depth + dd) * np.tan(theta) - 0.5 * dd
        height = (self.depth + max(3.0 * self.depth, 4.0 * dd)) / np.cos(theta)
        tool_mat = dem.material(rock_mod.E_C, kn_ks=rock_mod.KN_KS, mu=TOOL_MU, damping=rock_mod.DAMPING)
        self.tool = dem.Tool.create(
            [self.x_start, self.y_c, self.z_cut],
            face,
            [0.0, 1.0, 0.0],
            [3.0 * dd, self.cutter_width, height],
            self.n,
            tool_mat,
            d,
        )
        self.tool_height = height
        self.travel = float(size[0]) - c.end_margin * dd - self.x_start
        self.speed = dd / (c.cycles_per_d * self.dt)
        # The lamp on a following grid around the slab (frame coordinates: relative to the DEM's frame centre).
        self.frame_center = np.asarray(self.scene.center, dtype=np.float64)
        self.lamp_force = wp.zeros(self.n, dtype=wp.vec3, device=d)
        self.pressure = wp.zeros(1, dtype=wp.float32, device=d)
        self.probe_radius = c.probe_radius * 0.5 * self.d_mean if surfaces == "all" else None
        # The lamp's domain: the slab's box with room for the broken material; a particle whose centre leaves it
        # (debris thrown clear) drops out of the lamp (its active flag), as if carried off by the mud.
        side = DOMAIN_SIDE * self.depth + dd
        self.domain = (np.array([-side, -side, -dd]), size + np.array([side, side, DOMAIN_TOP * self.depth]))
        self.active = wp.ones(self.n, dtype=wp.int32, device=d)
        cell = self.d_mean / c.cells_per_diameter
        # The grid's capacity: the domain, a largest radius and (wetted) the probe and a cell beyond it.
        pad = float(r.max()) + (self.probe_radius + cell if surfaces == "all" else 0.0)
        lo = self.domain[0] - self.frame_center - pad
        hi = self.domain[1] - self.frame_center + pad
        self.grid = wl.LampGrid(lo, hi, cell)
        self.lamp = wl.ShiningLamp(self.grid, follow=True, device=d, **self.lamp_options())
        self.lamp.reserve(self.n)
        self.block = c.update_every if c.update_every % 2 == 0 else 2 * c.update_every
        self.check_every = max(self.block, int(np.ceil(c.check_every / self.block)) * self.block)
        self._graph = None
        self._loaded = False
        self.samples = []
        self.phase_cycles = {}
        self.main_label = None

    def lamp_options(self) -> dict:
        """The ShiningLamp keywords of this mode and base."""
        opts = {"lamps": "all" if self.base in ("clamped", "wall") else LAMPS_NO_BASE}
        if self.surfaces == "all":
            # No skin: flying chips move more than half of it between nearly every two updates (373 of 400 on an
            # H200), so its kept decisions are dropped before they are read (lamp share 47.5% with it, 45.3% without).
            opts.update(surfaces="all", probe_radius=self.probe_radius, skin=False)
        if self.base == "wall":
            # The slab's base as the lamp's wall, in the lamp's coordinates (the DEM frame), normal into the fluid.
            opts["walls"] = [((0.0, 0.0, self.z_base - self.frame_center[2]), (0.0, 0.0, 1.0))]
        return opts

    @property
    def cycle(self) -> int:
        return self.dem.cycle

    # --- one cycle ----------------------------------------------------------------------------------------------

    def step(self, *, lamp_update: bool = True, lamp: bool = True) -> None:
        """One cycle: frame copy, the lamp on its cycles (who is lit, then its forces), contacts, bonds, cutter,
        integration, clamp, cutter step. ``lamp=False`` leaves the lamp out (to time its share)."""
        sim = self.dem
        sim.begin()
        if lamp and lamp_update:
            wp.launch(
                dem.dem_in_box,
                dim=self.n,
                inputs=[sim.x, wp.vec3d(*self.domain[0]), wp.vec3d(*self.domain[1])],
                outputs=[self.active],
                device=self.device,
            )
            self.lamp.update(sim.pos32, sim.radius32, self.active)
            self.lamp_force.zero_()
            self.lamp.add_forces(self.lamp_force, self.pressure)
        sim.contacts()
        sim.bonds(self.rock.bonds)
        sim.tool(self.tool, self.lamp_force)
        sim.integrate(self.lamp_force)
        sim.hold(*self.fixed)
        sim.advance_tool(self.tool)

    def _block(self, *, lamp: bool = True) -> None:
        for k in range(self.block):
            self.step(lamp_update=k % self.config.update_every == 0, lamp=lamp)

    def capture(self, *, lamp: bool = True):
        """One block of cycles (n_u, or 2 n_u when n_u is odd: the contact slots swap by parity) in one CUDA graph."""
        ticks = iter(range(self.block))
        return self.dem.capture(
            lambda: self.step(lamp_update=next(ticks) % self.config.update_every == 0, lamp=lamp), self.block
        )

    def time_cycle(self, repeats: int = 10) -> dict:
        """Seconds per cycle (graph replays on CUDA, wall time on the CPU), with and without the lamp, and the
        lamp's share. The timed cycles run (uncounted; the cutter moves on), so call it at the end."""
        if not self._loaded and self.device.is_cuda:
            self.advance(self.block)
        out = {"update_every": self.config.update_every}
        for name, with_lamp in (("cycle_s", True), ("cycle_without_lamp_s", False)):
            if self.device.is_cuda:
                graph = self.capture(lamp=with_lamp)
                t = dem.median_gpu_time(lambda g=graph: wp.capture_launch(g), self.device, repeats)
            else:
                t = dem.median_gpu_time(lambda w=with_lamp: self._block(lamp=w), self.device, repeats)
            out[name] = t / self.block
        out["lamp_share"] = 1.0 - out["cycle_without_lamp_s"] / out["cycle_s"]
        return out

    # --- the procedure ------------------------------------------------------------------------------------------

    def settle(self, *, verbose: bool = False) -> None:
        """The pressure ramps linearly to P over ``ramp_cycles`` (set before each block: the lamp's forces change
        in steps of a block's share), then holds for ``settle_cycles``; the cutter waits behind the slab."""
        c = self.config
        start = self.cycle
        ramp = max(c.ramp_cycles, 1)
        while self.cycle - start < c.ramp_cycles:
            frac = min(1.0, (self.cycle - start + self.block) / ramp)
            self.pressure.assign(np.array([self.pressure_value * frac], dtype=np.float32))
            self.advance(self.block)
        self.pressure.assign(np.array([self.pressure_value], dtype=np.float32))
        while self.cycle - start < c.ramp_cycles + c.settle_cycles:
            self.advance(min(self.check_every, c.ramp_cycles + c.settle_cycles - (self.cycle - start)))
        t, s = self.rock.bonds.broken_counts()
        self.settle_broken = (t, s)
        self.phase_cycles["settle"] = self.cycle - start
        if verbose:
            print(
                f"  settled at {self.pressure_value / 1e6:g} MPa in {self.cycle - start} cycles; bonds broken "
                f"{t} + {s}",
                flush=True,
            )

    def cut(self, *, verbose: bool = False) -> list:
        """The cutter at constant speed over its travel; samples every ``check_every`` cycles."""
        start = self.cycle
        self.tool.velocity.assign(np.array([[self.speed, 0.0, 0.0]]))
        self.tool.reset_totals()
        total_cycles = int(np.ceil(self.travel / (self.speed * self.dt)))
        k = 0
        while self.cycle - start < total_cycles:
            self.advance(min(self.check_every, total_cycles - (self.cycle - start)))
            smp = self.sample(fragments=(k % self.config.fragments_every == 0))
            self.samples.append(smp)
            k += 1
            if verbose:
                print(
                    f"  u {smp['u_d']:6.2f} d: Fc {smp['fc']:8.1f} N  Fn {smp['fn']:8.1f} N  broken "
                    f"{smp['broken_tensile']} + {smp['broken_shear']}  contacts {smp['contacts']:.1f}",
                    flush=True,
                )
        self.tool.velocity.zero_()
        self.phase_cycles["cut"] = self.cycle - start
        if self.samples and self.samples[-1]["fragments"] is None:
            self.samples[-1]["fragments"] = self.fragments()
        return self.samples

    # --- measurements -------------------------------------------------------------------------------------------

    def tip(self) -> np.ndarray:
        """The cutting edge's middle [m], world coordinates (host copy)."""
        return self.tool.tip.numpy()[0].astype(np.float64)

    def sample(self, *, fragments: bool = False) -> dict:
        """Means since the last sample (then reset), the cutter's displacement, broken bonds, fragments."""
        tot = self.tool.totals()
        self.tool.reset_totals()
        tip = self.tip()
        t, s = self.rock.bonds.broken_counts()
        f = tot["force"]  # on the particles
        lamp = tot["lamp"]
        return {
            "cycle": self.cycle,
            "u": float(tip[0] - self.x_start),
            "u_d": float((tip[0] - self.x_start) / self.config.particle_diameter),
            "tip_x": float(tip[0]),
            "fc": float(f[0]),
            "fn": float(-f[2]),
            "fy": float(f[1]),
            "face_lamp_x": float(lamp[0]),
            "face_lamp_z": float(-lamp[2]),
            "contacts": float(tot["contacts"]),
            "broken_tensile": t,
            "broken_shear": s,
            "fragments": self.fragments() if fragments else None,
        }

    def fragments(self) -> dict:
        """Connected components of intact bonds (labelled on the device): the main body (the component holding
        the clamped base), chips (at least CHIP_MIN particles), small fragments, loose particles."""
        label = self.rock.fragments()
        self.labels = label
        sizes = np.bincount(label, minlength=self.n)
        main = int(np.bincount(label[self.clamped]).argmax())
        self.main_label = main
        others = np.flatnonzero(sizes > 0)
        others = others[others != main]
        frag = sizes[others]
        vol = 4.0 / 3.0 * np.pi * self.rock.radii**3
        detached = label != main
        return {
            "main": int(sizes[main]),
            "detached": int(detached.sum()),
            "detached_volume_m3": float(vol[detached].sum()),
            "loose": int(np.sum(frag == 1)),
            "small": int(np.sum((frag > 1) & (frag < CHIP_MIN))),
            "chips": int(np.sum(frag >= CHIP_MIN)),
            "in_chips": int(frag[frag >= CHIP_MIN].sum()),
            "largest": int(frag.max()) if len(frag) else 0,
            "sizes": sorted((int(v) for v in frag[frag > 1]), reverse=True),
            "rounds": int(self.rock.bonds.rounds.numpy()[0]),
        }

    def balance(self) -> dict:
        """The lamp's balance now: exact count sums per axis (zero on every axis whose two lamps are on) and the
        float32 forces' sums against float32 rounding (each force is the correctly rounded exact one)."""
        counts = self.lamp.counts_numpy()
        f32 = self.lamp_force.numpy().astype(np.float64)
        mask = lamp_mask(self.lamp_options()["lamps"])
        both = [bool((mask >> (2 * a)) & 1 and (mask >> (2 * a + 1)) & 1) for a in range(3)]
        return {
            "count_sums": [int(v) for v in counts.sum(axis=0)],
            "balanced_axes": both,
            "force_sums_N": [float(v) for v in f32.sum(axis=0)],
            "force_abs_sums_N": [float(v) for v in np.abs(f32).sum(axis=0)],
            "loaded": int(np.count_nonzero(np.abs(counts).sum(axis=1))),
        }

    def geometry(self) -> dict:
        dd = self.config.particle_diameter
        return {
            "d_m": dd,
            "d_mean_m": self.d_mean,
            "size_m": self.size.tolist(),
            "depth_m": self.depth,
            "cutter_width_m": self.cutter_width,
            "rake_deg": RAKE_DEG,
            "x_start_m": self.x_start,
            "z_cut_m": self.z_cut,
            "z_top_m": self.z_top,
            "y_c_m": self.y_c,
            "tool_height_m": self.tool_height,
            "travel_m": self.travel,
        }

    def region_loads(self, positions=None, *, present=None) -> dict:
        """Both lamps (this run's grid, each mode with its own lamps and base) on the configuration now, summed
        over regions, each over what a fluid at P would put there (1 = a fluid's load):

        * ``walls``: the trough's two walls behind the cutter (from STEADY_FROM delta past the end face to a delta
          behind the edge), the push into each wall (-y on the near wall, +y on the far one) over P times their
          area (2 L delta);
        * ``floor``: the trough's floor there, the push down over P L (w - d);
        * ``pile``: the detached particles (not in the main body) ahead of the cutter (within 3 delta of the edge,
          above the cut's floor): their net force, x and z, over P w delta, and how many.

        ``positions`` [m], shape (N, 3): another configuration (the DEM's now by default); ``present``, bool,
        shape (N,): the particles there are (all by default; those outside the lamp's domain never are).
        """
        p = self.pressure_value
        if p <= 0:
            return {}
        x = self.dem.x.numpy() if positions is None else np.asarray(positions, dtype=np.float64)
        r = self.rock.radii
        local = x - self.frame_center
        origin = self.lamp.frame_origin()
        # The live lamp's grid where it stands now (the upper corner half a cell short: the same cell counts).
        grid = wl.LampGrid(origin, origin + (self.grid.box_counts - 0.5) * self.grid.box_cell, self.grid.box_cell)
        out = {}
        if self.main_label is None:
            self.fragments()
        detached = self.labels != self.main_label
        dd = self.config.particle_diameter
        tip = self.tip()
        x0 = STEADY_FROM * self.depth
        x1 = tip[0] - self.depth
        length = max(x1 - x0, 0.0)
        along = (x[:, 0] > x0) & (x[:, 0] < x1)
        dy = x[:, 1] - self.y_c
        half = 0.5 * self.cutter_width
        high = (x[:, 2] > self.z_cut) & (x[:, 2] < self.z_top)
        near = along & high & (dy > -half - dd) & (dy < -half + 0.5 * dd)
        far = along & high & (dy < half + dd) & (dy > half - 0.5 * dd)
        floor = (
            along
            & (np.abs(dy) < half - 0.5 * dd)
            & (x[:, 2] > self.z_cut - 1.5 * dd)
            & (x[:, 2] < self.z_cut + 0.5 * dd)
        )
        pile = detached & (x[:, 0] > tip[0] - dd) & (x[:, 0] < tip[0] + 3.0 * self.depth) & (x[:, 2] > self.z_cut)
        pile &= np.abs(dy) < half + 2.0 * dd
        inside = np.all((x >= self.domain[0]) & (x <= self.domain[1]), axis=1)
        if present is not None:
            inside &= np.asarray(present, dtype=bool)
        for mode in ("first", "all"):
            base = self.base
            lamps = "all" if base in ("clamped", "wall") else LAMPS_NO_BASE
            opts = {"lamps": lamps, "active": inside}
            if mode == "all":
                opts.update(surfaces="all", probe_radius=self.config.probe_radius * 0.5 * self.d_mean)
            if base == "wall":
                opts["walls"] = [((0.0, 0.0, self.z_base - self.frame_center[2]), (0.0, 0.0, 1.0))]
            f = wl.lamp_forces(local, r, p, grid=grid, device=self.device, **opts)
            walls = (-f[near, 1].sum() + f[far, 1].sum()) / (p * 2.0 * length * self.depth) if length > 0 else None
            flo = -f[floor, 2].sum() / (p * length * (self.cutter_width - dd)) if length > 0 else None
            out[mode] = {
                "walls": None if walls is None else float(walls),
                "floor": None if flo is None else float(flo),
                "pile_x": float(f[pile, 0].sum() / (p * self.cutter_width * self.depth)),
                "pile_z": float(f[pile, 2].sum() / (p * self.cutter_width * self.depth)),
                "pile_particles": int(pile.sum()),
                "trough_length_m": float(length),
            }
        return out

    def damage(self) -> dict:
        """Broken bonds by where they were in the intact slab (their ends' midpoint at the start): depth below the
        cut's floor (positive down) in mean diameters, of those under the cutter's path; percentiles and counts."""
        state = self.rock.bonds.state.numpy()
        broken = np.flatnonzero(state != 0)
        x = self.rock.centers
        mid = 0.5 * (x[self.rock.pairs[broken, 0]] + x[self.rock.pairs[broken, 1]])
        dd = self.config.particle_diameter
        below = (self.z_cut - mid[:, 2]) / dd
        under = np.abs(mid[:, 1] - self.y_c) < 0.5 * self.cutter_width + 2 * dd
        deep = below[under & (below > 0)]
        return {
            "broken": int(len(broken)),
            "below_floor": int(len(deep)),
            "below_floor_fraction": float(len(deep) / max(len(broken), 1)),
            "depth_p50_d": float(np.percentile(deep, 50)) if len(deep) else 0.0,
            "depth_p90_d": float(np.percentile(deep, 90)) if len(deep) else 0.0,
            "depth_max_d": float(deep.max()) if len(deep) else 0.0,
            "lateral_p90_d": float(np.percentile(np.abs(mid[:, 1] - self.y_c) / dd, 90)) if len(mid) else 0.0,
        }

    def snapshot(self, band: float | None = None) -> dict:
        """For the damage picture: particles within ``band`` of the cutter's mid-plane (half its width by
        default), in micrometres, their fragment class (0 main, 1 chip, 2 small, 3 loose), and the broken bonds
        (midpoints in micrometres, 1 tensile / 2 shear) in the band."""
        if self.main_label is None:
            self.fragments()
        x = self.dem.x.numpy()
        r = self.rock.radii
        band = 0.5 * self.cutter_width if band is None else band
        sel = np.abs(x[:, 1] - self.y_c) < band
        sizes = np.bincount(self.labels, minlength=self.n)
        size = sizes[self.labels]
        kind = np.where(self.labels == self.main_label, 0, np.where(size >= CHIP_MIN, 1, np.where(size > 1, 2, 3)))
        state = self.rock.bonds.state.numpy()
        broken = np.flatnonzero(state != 0)
        mid = 0.5 * (x[self.rock.pairs[broken, 0]] + x[self.rock.pairs[broken, 1]])
        bsel = np.abs(mid[:, 1] - self.y_c) < band

        def um(a):
            return np.round(np.asarray(a) * 1e6).astype(int).tolist()

        return {
            "x_um": um(x[sel][:, 0]),
            "z_um": um(x[sel][:, 2]),
            "r_um": um(r[sel]),
            "kind": kind[sel].tolist(),
            "chip_id": self.labels[sel].tolist(),
            "bond_x_um": um(mid[bsel][:, 0]),
            "bond_z_um": um(mid[bsel][:, 2]),
            "bond_mode": state[broken][bsel].tolist(),
            "tip_um": um(self.tip()),
        }

    def summary(self) -> dict:
        """Means over the steady part of the cut, the specific energy, the damage and the fragments at the end."""
        s = self.samples
        u = np.array([v["u"] for v in s])
        tip = np.array([v["tip_x"] for v in s])
        fc = np.array([v["fc"] for v in s])
        fn = np.array([v["fn"] for v in s])
        steady = tip > STEADY_FROM * self.depth
        du = np.diff(np.r_[0.0, u])
        area = self.cutter_width * self.depth
        mean = {}
        for key, arr in (("fc", fc), ("fn", fn), ("face_lamp_x", None), ("face_lamp_z", None)):
            arr = np.array([v[key] for v in s]) if arr is None else arr
            mean[key] = float(np.sum(arr[steady] * du[steady]) / np.sum(du[steady])) if steady.any() else None
        work = float(np.sum(fc * du))
        in_rock = np.clip(tip, 0.0, None)
        swept = float(in_rock[-1]) * area if len(in_rock) else 0.0
        last = s[-1]
        frag = last["fragments"]
        t, sh = last["broken_tensile"], last["broken_shear"]
        return {
            "pressure_Pa": self.pressure_value,
            "surfaces": self.surfaces,
            "base": self.base,
            "particles": self.n,
            "bonds": self.rock.bonds.count,
            "coordination": self.rock.coordination,
            "clamped": len(self.clamped),
            "dt_s": self.dt,
            "speed_m_s": self.speed,
            "cut_cycles": self.phase_cycles.get("cut"),
            "settle_cycles": self.phase_cycles.get("settle"),
            "settle_broken": list(self.settle_broken),
            "fc_mean_N": mean["fc"],
            "fn_mean_N": mean["fn"],
            "fn_over_fc": mean["fn"] / mean["fc"] if mean["fc"] else None,
            "face_lamp_x_mean_N": mean["face_lamp_x"],
            "face_lamp_z_mean_N": mean["face_lamp_z"],
            "mse_Pa": mean["fc"] / area if mean["fc"] is not None else None,
            "mse_sealed_Pa": (mean["fc"] + mean["face_lamp_x"]) / area if mean["fc"] is not None else None,
            "mse_whole_cut_Pa": work / swept if swept > 0 else None,
            "work_J": work,
            "fc_peak_N": float(fc.max()),
            "fc_cv": float(np.std(fc[steady]) / np.mean(fc[steady]))
            if steady.sum() > 1 and np.mean(fc[steady])
            else None,
            "broken_tensile": t,
            "broken_shear": sh,
            "broken_in_cut": t + sh - sum(self.settle_broken),
            "fragments": frag,
            "chip_fraction": frag["in_chips"] / frag["detached"] if frag["detached"] else 0.0,
            "damage": self.damage(),
        }


# --- the study -----------------------------------------------------------------------------------------------


def run_one(
    config, pressure, surfaces, *, base="auto", device=None, scene=None, snapshot=False, verbose=False, time_it=True
) -> dict:
    """One cut: settle at P, cut, summarise; the loads of both modes on the final configuration, the balance,
    the timing, and a snapshot for the damage picture when asked."""
    t0 = time.perf_counter()
    test = RockCutting(config, pressure=pressure, surfaces=surfaces, base=base, device=device, scene=scene)
    test.settle(verbose=verbose)
    t1 = time.perf_counter()
    test.cut(verbose=verbose)
    t2 = time.perf_counter()
    out = {
        "summary": test.summary(),
        "samples": [{k: v for k, v in smp.items() if k != "fragments"} for smp in test.samples],
        "fragment_samples": [
            {"u_d": smp["u_d"], **{k: v for k, v in smp["fragments"].items() if k != "sizes"}}
            for smp in test.samples
            if smp["fragments"] is not None
        ],
        "balance": test.balance(),
        "loads": test.region_loads(),
        "geometry": test.geometry(),
        "seconds": {"settle": t1 - t0, "cut": t2 - t1},
    }
    if snapshot:
        out["snapshot"] = test.snapshot()
    if time_it:
        out["timing"] = test.time_cycle()
    out["seconds"]["total"] = time.perf_counter() - t0
    return out


def study(
    config=STUDY,
    pressures=STUDY_PRESSURES,
    modes=("first", "all"),
    *,
    base="auto",
    device=None,
    snapshot_pressures=None,
    checkpoint=None,
    verbose=False,
) -> dict:
    """Every pressure (in the order given) in every mode. P = 0 runs once (no lamp force in either mode: the same
    run) and is listed under both. Snapshots at the lowest and the highest pressure by default. ``checkpoint``,
    called with the results so far after each run (to write them, so that a run cut short keeps what it did)."""
    dd = config.particle_diameter
    size = np.array([config.length, config.width, config.height]) * dd
    scene = scene_box_specimen(size, dd, seed=config.seed)
    if snapshot_pressures is None:
        snapshot_pressures = (min(pressures), max(pressures))
    data = {
        "config": asdict(config),
        "pressures_Pa": list(pressures),
        "modes": list(modes),
        "rock": rock_mod.RockParams(bond_friction_deg=config.bond_friction_deg).as_dict(),
        "device": str(wp.get_device(device)),
        "runs": [],
    }
    runs = data["runs"]
    zero = None
    for p in pressures:
        for mode in modes:
            if p == 0 and zero is not None:
                runs.append({**zero, "mode": mode, "shared_with": zero["mode"]})
                continue
            if verbose:
                print(f"{mode}: P = {p / 1e6:g} MPa", flush=True)
            res = run_one(
                config,
                p,
                mode,
                base=base,
                device=device,
                scene=scene,
                snapshot=p in snapshot_pressures,
                verbose=verbose,
            )
            res["mode"] = mode
            runs.append(res)
            if p == 0:
                zero = res
            if verbose:
                s = res["summary"]
                print(
                    f"  Fc {s['fc_mean_N']:.1f} N, Fn {s['fn_mean_N']:.1f} N, MSE {s['mse_Pa'] / 1e6:.1f} MPa, "
                    f"broken {s['broken_in_cut']}, chips {s['fragments']['chips']}, {res['seconds']['total']:.1f} s",
                    flush=True,
                )
            if checkpoint is not None:
                checkpoint(data)
    runs.sort(key=lambda r: (modes.index(r["mode"]), r["summary"]["pressure_Pa"]))
    return data


# --- the report: tables and figures from the JSON -------------------------------------------------------------


def _row(cells) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"


def _head(names) -> list:
    return [_row(names), _row(["---"] * len(names))]


def _g(v, fmt=".2f") -> str:
    return "-" if v is None else format(v, fmt)


def table(data: dict) -> str:
    """The study's tables in Markdown: per mode and pressure the mean forces, the specific energy, damage and
    fragments; the loads the two lamps put on the trough and the pile; time per cycle and the lamp's share."""
    cal = data.get("calibration") or {}
    st = cal.get("tensile_Pa")
    ucs = cal.get("ucs_Pa")
    lines = _head(
        [
            "lamp",
            "P MPa",
            "P / UCS",
            "P / sigma_t",
            "F_c N",
            "F_n N",
            "F_n / F_c",
            "MSE MPa",
            "MSE / UCS",
            "MSE, face sealed, MPa",
            "bonds broken (tension + shear)",
            "damage depth p90 [d]",
            "chips (particles)",
            "loose",
        ]
    )
    for run in data["runs"]:
        s = run["summary"]
        p = s["pressure_Pa"]
        f = s["fragments"]
        lines.append(
            _row(
                [
                    f"`{run['mode']}`",
                    f"{p / 1e6:g}",
                    _g(p / ucs if ucs else None),
                    _g(p / st if st else None),
                    _g(s["fc_mean_N"], ".1f"),
                    _g(s["fn_mean_N"], ".1f"),
                    _g(s["fn_over_fc"]),
                    _g(s["mse_Pa"] / 1e6, ".1f"),
                    _g(s["mse_Pa"] / ucs if ucs else None),
                    _g(s["mse_sealed_Pa"] / 1e6, ".1f"),
                    f"{s['broken_tensile']} + {s['broken_shear']}",
                    _g(s["damage"]["depth_p90_d"]),
                    f"{f['chips']} ({f['in_chips']})",
                    f["loose"],
                ]
            )
        )
    lines.append("")
    lines += _head(
        [
            "P MPa (run)",
            *(f"{region}: {mode}" for region in ("walls", "floor", "pile x", "pile z") for mode in ("first", "all")),
            "pile particles",
        ]
    )
    for run in data["runs"]:
        loads = run.get("loads") or {}
        if not loads or run.get("shared_with"):
            continue
        a, b = loads["first"], loads["all"]
        lines.append(
            _row(
                [f"{run['summary']['pressure_Pa'] / 1e6:g} (`{run['mode']}`)"]
                + [_g(x[key]) for key in ("walls", "floor", "pile_x", "pile_z") for x in (a, b)]
                + [a["pile_particles"]]
            )
        )
    lines.append("")
    lines += _head(["lamp", "P MPa", "cycle µs", "without the lamp µs", "lamp share", "cut cycles", "cut s"])
    for run in data["runs"]:
        t = run.get("timing")
        if not t or run.get("shared_with"):
            continue
        s = run["summary"]
        lines.append(
            _row(
                [
                    f"`{run['mode']}`",
                    f"{s['pressure_Pa'] / 1e6:g}",
                    f"{t['cycle_s'] * 1e6:.1f}",
                    f"{t['cycle_without_lamp_s'] * 1e6:.1f}",
                    f"{t['lamp_share']:.1%}",
                    s["cut_cycles"],
                    f"{run['seconds']['cut']:.1f}",
                ]
            )
        )
    return "\n".join(lines)


def plot(data: dict, path: str) -> list:
    """Two figures: ``path`` (forces against displacement and the summary against P, both modes) and
    ``<stem>-damage.png`` (the damage zone and fragments at the lowest and highest pressure pictured). Returns
    the paths written. Needs matplotlib (the ``plot`` extra)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    for suffix, fig in figures(data):
        out = path if not suffix else str(Path(path).with_name(Path(path).stem + suffix + ".png"))
        fig.savefig(out, dpi=110)
        plt.close(fig)
        written.append(out)
    return written


def figures(data: dict) -> list:
    """The figures of :func:`plot` as ``(suffix, matplotlib Figure)``: ``""`` for the forces and the summary,
    ``"-damage"`` for the sections (where the runs kept snapshots)."""
    import matplotlib.pyplot as plt
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Circle, Polygon

    cal = data.get("calibration") or {}
    runs = data["runs"]
    modes = data["modes"]
    pressures = sorted({r["summary"]["pressure_Pa"] for r in runs})
    cmap = plt.get_cmap("viridis")
    colour = {p: cmap(i / max(len(pressures) - 1, 1)) for i, p in enumerate(pressures)}
    style = {"first": "--", "all": "-"}
    fig, ax = plt.subplots(2, 3, figsize=(15, 8.5))
    for run in runs:
        if run.get("shared_with"):
            continue
        p = run["summary"]["pressure_Pa"]
        u = np.array([s["u_d"] for s in run["samples"]])
        ax[0, 0].plot(u, [s["fc"] for s in run["samples"]], style[run["mode"]], color=colour[p], lw=1)
        ax[0, 1].plot(u, [s["fn"] for s in run["samples"]], style[run["mode"]], color=colour[p], lw=1)
        ax[0, 2].plot(
            u,
            [s["broken_tensile"] + s["broken_shear"] for s in run["samples"]],
            style[run["mode"]],
            color=colour[p],
            lw=1,
        )
    for p in pressures:
        ax[0, 0].plot([], [], color=colour[p], label=f"P = {p / 1e6:g} MPa")
    for m in modes:
        ax[0, 0].plot([], [], style[m], color="k", label=f'surfaces="{m}"')
    ax[0, 0].legend(fontsize=7)
    ax[0, 0].set(xlabel="cutter displacement [d]", ylabel="cutting force F_c [N]", title="cutting force")
    ax[0, 1].set(xlabel="cutter displacement [d]", ylabel="normal force F_n [N]", title="normal (thrust) force")
    ax[0, 2].set(xlabel="cutter displacement [d]", ylabel="bonds broken", title="damage")
    st = cal.get("tensile_Pa")
    for m in modes:
        rs = sorted((r for r in runs if r["mode"] == m), key=lambda r: r["summary"]["pressure_Pa"])
        p = np.array([r["summary"]["pressure_Pa"] for r in rs]) / 1e6
        s = [r["summary"] for r in rs]
        lab = f'"{m}"'
        ax[1, 0].plot(p, [v["fc_mean_N"] for v in s], "o" + style[m], label=f"F_c {lab}")
        ax[1, 0].plot(p, [v["fn_mean_N"] for v in s], "s" + style[m], label=f"F_n {lab}")
        ax[1, 1].plot(p, [v["mse_Pa"] / 1e6 for v in s], "o" + style[m], label=f"MSE {lab}")
        ax[1, 1].plot(p, [v["mse_sealed_Pa"] / 1e6 for v in s], "^" + style[m], ms=4, label=f"MSE, face sealed {lab}")
        ax[1, 2].plot(p, [v["broken_in_cut"] for v in s], "o" + style[m], label=f"bonds broken {lab}")
        ax[1, 2].plot(p, [v["fragments"]["in_chips"] for v in s], "s" + style[m], label=f"particles in chips {lab}")
        ax[1, 2].plot(p, [v["fragments"]["loose"] for v in s], "v" + style[m], label=f"loose particles {lab}")
    if cal.get("ucs_Pa"):
        # The UCS is an order of magnitude above the MSE: a line at it would squash the curves to the floor, so
        # it is named in the title instead.
        mse = [r["summary"]["mse_Pa"] for r in runs] + [r["summary"]["mse_sealed_Pa"] for r in runs]
        ratio = max(mse) / cal["ucs_Pa"]
        ax[1, 1].set_title(
            f"mechanical specific energy\n(UCS {cal['ucs_Pa'] / 1e6:.0f} MPa from the calibration: MSE / UCS "
            f"<= {ratio:.2f})",
            fontsize=10,
        )
    for a in ax[1]:
        a.set_xlabel("mud pressure P [MPa]" + (f" (sigma_t = {st / 1e6:.1f} MPa)" if st else ""))
        a.legend(fontsize=7)
    ax[1, 0].set(ylabel="mean force, steady cut [N]", title="forces against pressure")
    ax[1, 1].set(ylabel="specific energy [MPa]")
    if not cal.get("ucs_Pa"):
        ax[1, 1].set_title("mechanical specific energy")
    ax[1, 2].set(ylabel="count", title="damage and fragments")
    cfg = data["config"]
    fig.suptitle(
        f"Rock cutting under mud pressure ({cfg['name']}: depth of cut {cfg['depth']:g} d, cutter "
        f"{cfg['cutter_width']:g} d wide, rake {RAKE_DEG:g} deg, d = {cfg['particle_diameter'] * 1e3:g} mm, "
        f"{cfg['cycles_per_d']} cycles per d; {data['device']})",
        fontsize=10,
    )
    fig.tight_layout()
    out = [("", fig)]
    snaps = [r for r in runs if "snapshot" in r and not r.get("shared_with")]
    if snaps:
        snaps.sort(key=lambda r: (r["summary"]["pressure_Pa"], r["mode"]))
        # Side by side: each section is wider than tall, so a column of them would leave most of the width empty.
        fig, axes = plt.subplots(1, len(snaps), figsize=(5.4 * len(snaps), 5.0), squeeze=False)
        colours = {0: "0.85", 1: "tab:orange", 2: "tab:green", 3: "0.2"}
        for a, run in zip(axes[0], snaps, strict=True):
            sn = run["snapshot"]
            geo = run["geometry"]
            xs = np.array(sn["x_um"]) / 1e3
            zs = np.array(sn["z_um"]) / 1e3
            rs = np.array(sn["r_um"]) / 1e3
            kinds = np.array(sn["kind"])
            patches = [Circle((x, z), r) for x, z, r in zip(xs, zs, rs, strict=True)]
            pc = PatchCollection(patches, facecolors=[colours[k] for k in kinds], edgecolors="0.5", linewidths=0.2)
            a.add_collection(pc)
            bx = np.array(sn["bond_x_um"]) / 1e3
            bz = np.array(sn["bond_z_um"]) / 1e3
            bm = np.array(sn["bond_mode"])
            a.plot(bx[bm == 1], bz[bm == 1], "r.", ms=2.5, label="bond broken in tension")
            a.plot(bx[bm == 2], bz[bm == 2], "b.", ms=2.5, label="bond broken in shear")
            tip = np.array(sn["tip_um"]) / 1e3
            th = np.radians(geo["rake_deg"])
            face = np.array([np.cos(th), -np.sin(th)])
            up = np.array([np.sin(th), np.cos(th)])
            t0 = np.array([tip[0], tip[2]])
            h = geo["tool_height_m"] * 1e3
            thick = 3.0 * geo["d_m"] * 1e3
            corners = [t0, t0 + h * up, t0 + h * up - thick * face, t0 - thick * face]
            a.add_patch(Polygon(corners, closed=True, facecolor="tab:blue", alpha=0.35, edgecolor="tab:blue"))
            a.axhline(geo["z_cut_m"] * 1e3, color="tab:blue", lw=0.6, ls=":")
            s = run["summary"]
            a.set_title(
                f'P = {s["pressure_Pa"] / 1e6:g} MPa, surfaces="{run["mode"]}"\nF_c {s["fc_mean_N"]:.0f} N, '
                f"MSE {s['mse_Pa'] / 1e6:.0f} MPa, {s['broken_in_cut']} bonds broken, {s['fragments']['chips']} chips",
                fontsize=9,
            )
            size = geo["size_m"]
            a.set_xlim(min(-2.0, corners[3][0] - 0.5), size[0] * 1e3 + 0.5)
            a.set_ylim(-0.3, size[2] * 1e3 + 3.0 * geo["depth_m"] * 1e3)
            a.set_aspect("equal")
            a.set_xlabel("x [mm]")
            a.legend(fontsize=7, loc="upper left")
        axes[0, 0].set_ylabel("z [mm]")
        fig.suptitle(
            f"Sections |y - y_c| < {geo['cutter_width_m'] * 500:.2g} mm (the cutter's width): chips orange, small "
            "fragments green, loose particles dark, intact grey",
            fontsize=10,
        )
        fig.tight_layout()
        out.append(("-damage", fig))
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tiny", action="store_true", help="the CPU test's configuration (seconds per run)")
    parser.add_argument("--device", default=None)
    parser.add_argument("--pressures", type=float, nargs="*", default=None, help="pressures [MPa]")
    parser.add_argument("--modes", nargs="*", default=["first", "all"], choices=["first", "all"])
    parser.add_argument("--base", default="auto", choices=BASES, help="how the slab's base meets the fluid")
    parser.add_argument("--cycles-per-d", type=int, default=None, help="cutter speed: cycles per mean diameter")
    parser.add_argument("--bond-friction-deg", type=float, default=None, help="bond friction angle (PFC5; memo: 0)")
    parser.add_argument("--calibrate", action="store_true", help="run the UCS and Brazilian tests first")
    parser.add_argument("--calibration", default=None, help="read the calibration from this JSON (bonded_rock.py)")
    parser.add_argument("--json", default=None, help="write the results as JSON")
    parser.add_argument("--plot", default=None, help="draw the figures (PNG; a second one gets -damage)")
    parser.add_argument("--report", default=None, help="print the tables (and --plot) from this result JSON")
    parser.add_argument("--quiet", action="store_true")
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_WARNING
    if args.report:
        with open(args.report) as f:
            data = json.load(f)
    else:
        config = TINY if args.tiny else STUDY
        if args.cycles_per_d:
            config = replace(config, cycles_per_d=args.cycles_per_d)
        if args.bond_friction_deg is not None:
            config = replace(config, bond_friction_deg=args.bond_friction_deg)
        pressures = (
            tuple(p * 1e6 for p in args.pressures)
            if args.pressures
            else (TINY_PRESSURES if args.tiny else STUDY_PRESSURES)
        )
        cal = None
        if args.calibration:
            with open(args.calibration) as f:
                cal = json.load(f)
        elif args.calibrate:
            t0 = time.perf_counter()
            cal = rock_mod.calibrate("tiny" if args.tiny else "study", device=args.device, verbose=not args.quiet)
            cal["seconds"] = time.perf_counter() - t0
        t0 = time.perf_counter()

        def finish(data):
            data["seconds"] = time.perf_counter() - t0
            if cal is not None:
                # The calibration's figures, without its curves (they stay in the calibration file).
                data["calibration"] = {k: v for k, v in cal.items() if k not in ("ucs", "brazilian", "tension")}
                if args.calibration:
                    data["calibration"]["file"] = args.calibration
            if args.json:
                with open(args.json, "w") as f:
                    json.dump(data, f, indent=1)

        data = study(
            config,
            pressures,
            tuple(args.modes),
            base=args.base,
            device=args.device,
            checkpoint=finish,
            verbose=not args.quiet,
        )
        finish(data)
    print(table(data))
    if args.plot:
        for p in plot(data, args.plot):
            print(f"wrote {p}")


if __name__ == "__main__":
    main()
