"""``warp-lamp bench``'s sections for the lamp's modes: speed against error for each.

- ``small_body``: the SphereTest specimen at 2, 4, 8, 16 cells per diameter, the default depth pass against the
  previous release's one thread per sphere (``split=0, order=False``, kept as ``v4`` in the JSON) in the same
  run; the 1M and 8M lattice boxes on CUDA.
- ``area``: per-particle force error against the exact visible areas
  (:func:`~warp_lamp.reference.visible_area_reference`) on the specimen, criterion 1 against ``criterion="area"``
  (both resolvers, D = 3 and 4), each with its update time and its ratio to criterion 1 at 4 cells per diameter.
- ``wetted``: ``surfaces="first"`` against ``"all"`` (rho = one mean radius): update time, loaded
  particles, and the slot block's wall and floor load ratios.
- ``frames``: direction error (the angle between a surface particle's force and the inward normal of
  the body's envelope) of a jittered block, aligned, rotated under an axis-aligned lamp and rotated with its lamp,
  and of the SphereTest ball with frame averaging, each with its update time.

Every row names its device. Every time is a median of repeats after a warm-up with the device synchronised
(:mod:`warp_lamp.timing`): on CUDA between CUDA events, eager updates and captured graphs replayed; on the CPU,
eager updates only. ``update_s`` is the figure rows are compared by: the graph replay on CUDA, the eager update
on the CPU. A "moving body" alternates two position sets 1% of a mean radius apart (normal jitter per coordinate,
seed 5), updated in turn, so that each update starts from owners found at other positions; its time is per update.
"""

from __future__ import annotations

import hashlib
import time

import numpy as np
import warp as wp

from warp_lamp.bench.common import lattice_grid, markdown_table
from warp_lamp.grid import LampGrid
from warp_lamp.lamp import ShiningLamp
from warp_lamp.measures import (
    ball_outer_normals,
    block_face_interior,
    direction_error,
    lone_sphere_area_error,
    slot_load_ratios,
    visible_area_error,
)
from warp_lamp.scenes import (
    Scene,
    scene_lattice_box,
    scene_overlapping_polydisperse,
    scene_slot_block,
    scene_sphere_specimen,
)
from warp_lamp.timing import Progress, time_median, time_median_events

__all__ = [
    "BALL_DEPTH_RADII",
    "BLOCK_EDGE",
    "BLOCK_ROTATION_DEG",
    "bench_modes",
    "block_rotation",
    "exact_areas",
    "format_modes",
    "frames_block_case",
    "frames_block_scene",
    "plot_area",
    "section_area",
    "section_frames",
    "section_small_body",
    "section_wetted",
    "time_update",
]

#: Pressure of the error measures [Pa]: every error is relative to it.
P = 1.0
#: The rotated block's turn: 10, 20 and 30 degrees about x, then y, then z (world axes), about its centre.
BLOCK_ROTATION_DEG = (10.0, 20.0, 30.0)
#: Lattice sites left out next to each face edge when taking the block's face interiors.
BLOCK_EDGE = 2
#: The ball's outer particles: centres within this many mean radii of the envelope sphere.
BALL_DEPTH_RADII = 3.0

_EXACT: dict[str, tuple[np.ndarray, float]] = {}


def exact_areas(scene: Scene) -> tuple[np.ndarray, float]:
    """The exact visible area of every particle from every lamp [m^2], shape (N, 6), and the seconds it took,
    cached in memory per scene (keyed by its centres and radii): about 20 s on the CPU for the specimen, by surface
    depth."""
    from warp_lamp.reference import visible_area_reference

    c = np.ascontiguousarray(scene.centers, dtype=np.float64)
    r = np.ascontiguousarray(scene.radii, dtype=np.float64)
    key = hashlib.sha1(c.tobytes() + r.tobytes()).hexdigest()
    if key not in _EXACT:
        t0 = time.perf_counter()
        areas = visible_area_reference(c, r)
        _EXACT[key] = (areas, time.perf_counter() - t0)
    return _EXACT[key]


def block_rotation(degrees=BLOCK_ROTATION_DEG) -> np.ndarray:
    """R = Rz(gz) Ry(gy) Rx(gx): a turn about world x, then y, then z, by ``degrees`` (gx, gy, gz)."""
    ax, ay, az = np.radians(np.asarray(degrees, dtype=np.float64))
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


# --- timing ---------------------------------------------------------------------------------------------------


def _moved(scene: Scene) -> np.ndarray:
    jitter = np.random.default_rng(5).normal(scale=0.01 * float(scene.radii.mean()), size=scene.centers.shape)
    return scene.centers + jitter


def _positions(centers, grid: LampGrid, device, in_frame: bool) -> wp.array:
    x = grid.to_frame(centers) if in_frame else np.asarray(centers, dtype=np.float64)
    return wp.array(x.astype(np.float32), dtype=wp.vec3, device=device)


def time_update(
    lamp: ShiningLamp,
    scene: Scene,
    device,
    *,
    repeats: int,
    in_frame: bool = True,
    moving: bool = True,
) -> dict:
    """Time ``lamp.update`` on a scene; the lamp is left updated at the scene's positions.

    Args:
        lamp: The lamp, on ``device``.
        scene: The particles.
        device: Warp device.
        repeats: Timed repeats per figure.
        in_frame: Pass positions in frame coordinates (``grid.to_frame`` in float64 on the host, as
            :func:`~warp_lamp.lamp_forces` does), or world positions for the lamp to move on the device (frame
            averaging needs those).
        moving: Also time the moving body.

    Returns:
        ``eager_s``; on CUDA ``replay_s`` (a captured update replayed); ``moving_s`` (graph replay on CUDA, eager on
        the CPU, per update; None unless ``moving``); ``update_s``: ``replay_s`` on CUDA, ``eager_s`` on the CPU.
    """
    device = wp.get_device(device)
    pos = _positions(scene.centers, lamp.grid, device, in_frame)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    moved = _positions(_moved(scene), lamp.grid, device, in_frame) if moving else None

    def update(x):
        lamp.update(x, rad, in_frame=in_frame)

    update(pos)  # allocates, sorts (with order) and compiles, outside any capture
    out = {"eager_s": time_median_events(lambda: update(pos), device, repeats=repeats), "replay_s": None}
    out["moving_s"] = None
    if device.is_cuda:
        with wp.ScopedCapture(device=device) as cap:
            update(pos)
        out["replay_s"] = time_median_events(lambda: wp.capture_launch(cap.graph), device, repeats=repeats)
        if moving:
            with wp.ScopedCapture(device=device) as cap_moving:
                update(moved)
                update(pos)
            t = time_median_events(lambda: wp.capture_launch(cap_moving.graph), device, repeats=repeats)
            out["moving_s"] = t / 2
        wp.capture_launch(cap.graph)
    elif moving:
        out["moving_s"] = time_median(lambda: (update(moved), update(pos)), device, repeats=repeats) / 2
        update(pos)
    out["update_s"] = out["replay_s"] if device.is_cuda else out["eager_s"]
    return out


def _lattice_grid(scene: Scene, spec) -> tuple[LampGrid, str, float]:
    """The bench's lattice grid for ``spec``: a cell size [m], or "d/k" (k cells per mean diameter)."""
    d = 2.0 * float(scene.radii.mean())
    if isinstance(spec, str):
        if not spec.startswith("d/"):
            raise ValueError(f"large: a grid is a cell size or 'd/k', got {spec!r}")
        cell = d / float(spec[2:])
        label = spec
    else:
        cell = float(spec)
        label = f"cell {cell:g}"
    return lattice_grid(scene, cell), label, d / cell


def _default_repeats(device, quick: bool) -> int:
    if device.is_cuda:
        return 20 if quick else 50
    return 3 if quick else 5


def _step(bar, what):
    if bar is not None:
        bar.step(what)


# --- small bodies -----------------------------------------------------------------------------------------------

#: The previous release's depth pass: one thread per sphere, no work order (``v4`` in result files).
V4 = {"split": 0, "order": False}


def section_small_body(
    device,
    *,
    repeats: int,
    specimen: Scene | None = None,
    cells_per_diameter=(2, 4, 8, 16),
    large=(),
    bar: Progress | None = None,
) -> list[dict]:
    """The default lamp against the previous release's depth pass, in one run on one device: eager update, graph
    replay and moving body, and the speed-up previous / default.

    Args:
        device: Warp device.
        repeats: Timed repeats per figure (large scenes: at most 20).
        specimen: The small body (the SphereTest specimen by default), on enclosing grids.
        cells_per_diameter: Resolutions of the small body.
        large: ``(n_per_axis, grid)`` pairs of jittered lattice boxes (:func:`~warp_lamp.scenes.scene_lattice_box`),
            ``grid`` a cell size [m] or ``"d/k"``: ``(100, 0.25), (100, "d/16"), (200, 0.25)`` for the 1M and 8M
            rows.
        bar: Progress bar, one step per row.

    Returns:
        One row per scene and grid: ``default`` and ``v4`` (timings of :func:`time_update`, with ``split`` and
        ``order``), ``speedup`` (the previous release's time over the default's: eager, replay, moving) and
        ``same_counts`` (the two paths' counts are bitwise equal, as they must be).
    """
    device = wp.get_device(device)
    specimen = scene_sphere_specimen() if specimen is None else specimen
    jobs = []
    for k in cells_per_diameter:
        grid = LampGrid.enclosing(specimen.centers, specimen.radii, cells_per_diameter=k)
        jobs.append((specimen, grid, f"d/{k:g}", float(k), repeats))
    cache = {}
    for m, spec in large:
        scene = cache.setdefault(m, scene_lattice_box(m))
        grid, label, k = _lattice_grid(scene, spec)
        jobs.append((scene, grid, label, k, min(repeats, 20)))
    rows = []
    for scene, grid, label, k, reps in jobs:
        row = {"device": device.alias, "scene": scene.name, "n": scene.n, "grid": label}
        row.update(cells_per_diameter=k, cells=grid.n_cells)
        counts = {}
        for name, options in (("default", {}), ("v4", V4)):
            lamp = ShiningLamp(grid, device=device, **options)
            t = time_update(lamp, scene, device, repeats=reps)
            t.update(split=int(lamp.split), order=bool(lamp.order.shape[0]))
            row[name] = t
            counts[name] = lamp.counts_numpy()
            del lamp
        row["same_counts"] = bool(np.array_equal(counts["default"], counts["v4"]))
        row["speedup"] = {
            key: (row["v4"][f"{key}_s"] / row["default"][f"{key}_s"] if row["default"][f"{key}_s"] else None)
            for key in ("eager", "replay", "moving")
        }
        rows.append(row)
        _step(bar, f"{device.alias} small body {scene.n:,} {label}")
    return rows


# --- the area criterion ------------------------------------------------------------------------------------------

#: The area criterion's estimators in the section: (resolver, depth_slots).
AREA_ESTIMATORS = (("subpoints", 3), ("subpoints", 4), ("exact", 3), ("exact", 4))


def _estimator_name(row: dict) -> str:
    if row["criterion"] == 1:
        return "criterion 1"
    s = f", S = {row['subpoints']}" if row["resolver"] == "subpoints" else ""
    return f"area, {row['resolver']}{s}, D = {row['depth_slots']}"


def section_area(
    device,
    *,
    repeats: int,
    specimen: Scene | None = None,
    criterion1_cpd=(2, 4, 8, 16, 32),
    area_cpd=(2, 3, 4),
    estimators=AREA_ESTIMATORS,
    overlap: Scene | bool = False,
    overlap_cpd=(3, 4),
    lone_samples: int = 0,
    large=(),
    bar: Progress | None = None,
) -> dict:
    """Per-particle force error against the exact visible areas, and update time, of criterion 1 and the area
    criterion on the specimen (:func:`~warp_lamp.measures.visible_area_error`: RMS over the surface particles of
    |F - F_exact| / (P pi rbar^2), and the worst particle); graph replay on CUDA, eager on the CPU, without the
    moving body.

    Args:
        device: Warp device.
        repeats: Timed repeats per figure.
        specimen: The body (the SphereTest specimen by default), on enclosing grids.
        criterion1_cpd: Resolutions of criterion 1 [cells per mean diameter]; 4 is the reference of ``ratio``.
        area_cpd: Resolutions of the area criterion.
        estimators: ``(resolver, depth_slots)`` pairs of the area criterion (8 x 8 sub-points).
        overlap: The overlapping polydisperse ball, measured as the specimen at ``overlap_cpd`` (error only, not
            timed): a scene, True for :func:`~warp_lamp.scenes.scene_overlapping_polydisperse`, False for none.
        overlap_cpd: Resolutions of the overlapping body.
        lone_samples: Random offsets of the lone sphere per resolver and resolution (0: none).
        large: Lattice sizes per axis (the 1M box: 100) whose update at cell 0.25 is timed for criterion 1 and
            for the area criterion with the lamp's defaults at cell 0.25 and at 3 cells per diameter.
        bar: Progress bar, one step per row.

    Returns:
        ``{"scene", "n", "mean_radius", "reference_s", "rows", "large"}``: a row per estimator and resolution with
        its error (``rms``, ``rms_all``, ``worst``, ``worst_particle``, ``surface``), ``update_s`` and ``ratio``
        (over criterion 1 at 4 cells per diameter on this device; None without that row), the area kernel's
        ``overflow`` and ``one_sided`` cells, and whether the forces sum to exactly zero (``balanced``); also
        ``overlap`` (rows of the overlapping body, with its ``overlap_scene``, ``overlap_n`` and
        ``overlap_reference_s``) and ``lone`` (per resolver and resolution, the lone sphere's per-lamp load error,
        :func:`~warp_lamp.measures.lone_sphere_area_error`).
    """
    device = wp.get_device(device)
    specimen = scene_sphere_specimen() if specimen is None else specimen
    exact, ref_s = exact_areas(specimen)
    rbar = float(specimen.radii.mean())
    jobs = [(1, None, 1, 8, k) for k in criterion1_cpd]
    jobs += [("area", res, d, 8, k) for k in area_cpd for res, d in estimators]
    rows = []
    for criterion, resolver, slots, s, k in jobs:
        grid = LampGrid.enclosing(specimen.centers, specimen.radii, cells_per_diameter=k)
        options = {} if criterion == 1 else {"resolver": resolver, "depth_slots": slots, "subpoints": s}
        lamp = ShiningLamp(grid, criterion=criterion, device=device, **options)
        t = time_update(lamp, specimen, device, repeats=repeats, moving=False)
        f = lamp.forces_numpy(P)
        diag = lamp.diagnostics()
        row = {"device": device.alias, "criterion": criterion, "resolver": resolver, "depth_slots": slots}
        row.update(subpoints=s if resolver == "subpoints" else None, cells_per_diameter=float(k), cells=grid.n_cells)
        row.update(t)
        row.update(visible_area_error(f, exact, P, rbar))
        row.update(
            overflow=int(diag.area_overflow),
            one_sided=int(diag.area_one_sided),
            balanced=bool(np.all(f.sum(axis=0) == 0.0)),
        )
        rows.append(row)
        _step(bar, f"{device.alias} area {_estimator_name(row)} d/{k:g}")
    base = next((r for r in rows if r["criterion"] == 1 and r["cells_per_diameter"] == 4), None)
    for r in rows:
        r["ratio"] = r["update_s"] / base["update_s"] if base else None
    out = {"scene": specimen.name, "n": specimen.n, "mean_radius": rbar, "reference_s": ref_s, "rows": rows}
    out["overlap"] = []
    if overlap is not False:
        body = scene_overlapping_polydisperse() if overlap is True else overlap
        exact_o, ref_o = exact_areas(body)
        out.update(overlap_scene=body.name, overlap_n=body.n, overlap_reference_s=ref_o)
        for k in overlap_cpd:
            grid = LampGrid.enclosing(body.centers, body.radii, cells_per_diameter=k)
            for resolver, slots in estimators:
                lamp = ShiningLamp(grid, criterion="area", resolver=resolver, depth_slots=slots, device=device)
                t = time_update(lamp, body, device, repeats=1, moving=False)
                f = lamp.forces_numpy(P)
                row = {"device": device.alias, "criterion": "area", "resolver": resolver, "depth_slots": slots}
                row.update(subpoints=8 if resolver == "subpoints" else None, cells_per_diameter=float(k))
                row.update(visible_area_error(f, exact_o, P, float(body.radii.mean())))
                row.update(balanced=bool(np.all(f.sum(axis=0) == 0.0)), eager_s=t["eager_s"])
                out["overlap"].append(row)
                _step(bar, f"{device.alias} area overlap {_estimator_name(row)} d/{k:g}")
    out["lone"] = []
    for k in area_cpd if lone_samples else ():
        for resolver in ("subpoints", "exact"):
            e = lone_sphere_area_error(resolver, k, device, samples=lone_samples)
            out["lone"].append({"device": device.alias, "resolver": resolver, "cells_per_diameter": float(k), **e})
            _step(bar, f"{device.alias} area lone sphere {resolver} d/{k:g}")
    out["large"] = []
    for m in large:
        scene = scene_lattice_box(m)
        d = 2.0 * float(scene.radii.mean())
        big = []
        for criterion, cell in ((1, 0.25), ("area", 0.25), ("area", d / 3.0)):
            grid = lattice_grid(scene, cell)
            lamp = ShiningLamp(grid, criterion=criterion, device=device)
            t = time_update(lamp, scene, device, repeats=min(repeats, 20), moving=False)
            row = {"device": device.alias, "scene": scene.name, "n": scene.n, "criterion": criterion}
            row.update(cell=cell, cells_per_diameter=d / cell, cells=grid.n_cells, **t)
            if criterion == "area":
                row.update(resolver=lamp.resolver, depth_slots=lamp.depth_slots, subpoints=lamp.subpoints)
            del lamp
            big.append(row)
            _step(bar, f"{device.alias} area {scene.n:,} criterion {criterion} cell {cell:.3g}")
        for r in big:
            r["ratio"] = r["update_s"] / big[0]["update_s"]
        out["large"] += big
    return out


# --- the wetted surface ------------------------------------------------------------------------------------------


def section_wetted(
    device,
    *,
    repeats: int,
    specimen: Scene | None = None,
    slot: Scene | None = None,
    large=(),
    cells_per_diameter: float = 4,
    bar: Progress | None = None,
) -> list[dict]:
    """``surfaces="first"`` against ``"all"`` with rho = one mean radius, on the same grid (enclosing, its margin
    grown by rho): update time (static and moving body), loaded particles, and the slot block's load ratios
    (:func:`~warp_lamp.measures.slot_load_ratios`).

    Args:
        device: Warp device.
        repeats: Timed repeats per figure.
        specimen: The convex body (the SphereTest specimen by default).
        slot: The slot block (:func:`~warp_lamp.scenes.scene_slot_block`, by default).
        large: Lattice sizes per axis (the 1M box: 100), at cell 0.25 (with the margin grown by rho).
        cells_per_diameter: Resolution of the specimen and the slot block.
        bar: Progress bar, one step per row.

    Returns:
        A row per scene and mode: timings (:func:`time_update`), ``rho``, ``loaded`` (particles that took a cell
        or a crossing), ``nonzero`` (particles with a nonzero net force), ``balanced`` (the forces sum to exactly
        zero); ``"all"``: the connectivity ``rounds`` and ``nonconverged``; the slot block: ``ratios``.
    """
    device = wp.get_device(device)
    specimen = scene_sphere_specimen() if specimen is None else specimen
    slot = scene_slot_block() if slot is None else slot
    jobs = []
    for scene in (specimen, slot):
        rho = float(scene.radii.mean())
        grid = LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=cells_per_diameter, probe_radius=rho)
        jobs.append((scene, grid, f"d/{cells_per_diameter:g}", rho, repeats))
    for m in large:
        scene = scene_lattice_box(m)
        rho = float(scene.radii.mean())
        cell = 0.25
        lo = scene.centers.min(axis=0) - scene.radii.max() - cell - rho
        hi = scene.centers.max(axis=0) + scene.radii.max() + cell + rho
        jobs.append((scene, LampGrid(lo, hi, cell), f"cell {cell:g}", rho, min(repeats, 20)))
    rows = []
    for scene, grid, label, rho, reps in jobs:
        for surfaces in ("first", "all"):
            # From scratch: replays at fixed positions would time the skin's kept decisions at rest.
            options = {"surfaces": "all", "probe_radius": rho, "skin": False} if surfaces == "all" else {}
            lamp = ShiningLamp(grid, device=device, **options)
            row = {"device": device.alias, "scene": scene.name, "n": scene.n, "grid": label, "surfaces": surfaces}
            row.update(rho=rho if surfaces == "all" else None, cells=grid.n_cells)
            row.update(time_update(lamp, scene, device, repeats=reps))
            f = lamp.forces_numpy(P)
            diag = lamp.diagnostics()
            row.update(
                loaded=int(diag.surface.sum()),
                nonzero=int(np.any(f != 0.0, axis=1).sum()),
                balanced=bool(np.all(f.sum(axis=0) == 0.0)),
            )
            if surfaces == "all":
                row.update(rounds=int(diag.rounds), nonconverged=bool(diag.nonconverged))
            if getattr(scene, "cut", None) and scene.cut.get("kind") == "slot":
                row["ratios"] = slot_load_ratios(scene, f, P)
            del lamp, diag
            rows.append(row)
            _step(bar, f"{device.alias} wetted {scene.n:,} {surfaces}")
    return rows


# --- lamp frames -------------------------------------------------------------------------------------------------


def section_frames(
    device,
    *,
    repeats: int,
    block_size: int = 20,
    ball: Scene | None = None,
    cells_per_diameter=(4, 8),
    frames=(1, 2, 4, 8),
    bar: Progress | None = None,
) -> list[dict]:
    """Direction error and update time of the block (aligned; rotated under an axis-aligned lamp; rotated with its
    lamp) and of the ball with frame averaging.

    The block is :func:`~warp_lamp.scenes.scene_lattice_box` (spacing 1, jitter 0.05, r in [0.4, 0.5]) of
    ``block_size`` per axis, turned by :func:`block_rotation` about its centre. Its surface particles are its
    face interiors (:func:`~warp_lamp.measures.block_face_interior`: the outermost lattice layer of each face,
    :data:`BLOCK_EDGE` sites or more from the face's edges), measured against the turned face normal. The ball
    is the SphereTest specimen; its surface particles are those whose centre lies within
    :data:`BALL_DEPTH_RADII` mean radii of the envelope sphere (:func:`~warp_lamp.measures.ball_outer_normals`),
    measured against the inward radial direction. Particles with no force are counted, not measured
    (:func:`~warp_lamp.measures.direction_error`). Grids are enclosing grids (in the lamp's frame where it turns;
    frame averaging turns the axis-aligned one, :meth:`LampGrid.rotated`); positions go in world coordinates, so
    the timed update includes the device's move into the frame.

    Returns:
        A row per case, frames and resolution: ``body``, ``lamp`` ("axis-aligned" or "rotated with the body"),
        ``frames``, the direction error (``mean_deg``, ``p90_deg``, ``weighted_mean_deg``, ``particles``,
        ``loaded``, ``unloaded``), timings (:func:`time_update`) and ``balanced`` (the float64 forces sum to exactly
        zero, as they must in any frame and averaged over frames).
    """
    device = wp.get_device(device)
    block, turned, index, rot = frames_block_scene(block_size)
    ball = scene_sphere_specimen() if ball is None else ball
    ball_select, ball_normals = ball_outer_normals(
        ball.centers, ball.center, ball.radius, BALL_DEPTH_RADII * float(ball.radii.mean())
    )
    cases = []
    for name, scene, body_rot, lamp_rot in (
        ("block aligned", block, None, None),
        ("block rotated", turned, rot, None),
        ("block rotated", turned, rot, rot),
    ):
        select, normals = block_face_interior(index, block_size, rotation=body_rot, edge=BLOCK_EDGE)
        cases.append((name, scene, lamp_rot, 1, select, normals))
    cases += [("ball", ball, None, k, ball_select, ball_normals) for k in frames]
    rows = []
    for k in cells_per_diameter:
        for name, scene, lamp_rot, n_frames, select, normals in cases:
            grid = LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=k, rotation=lamp_rot)
            lamp = ShiningLamp(grid, frames=n_frames, device=device)
            t = time_update(lamp, scene, device, repeats=repeats, in_frame=False)
            f = lamp.forces_numpy(P)
            row = {"device": device.alias, "body": name, "n": scene.n, "cells_per_diameter": float(k)}
            row.update(lamp="axis-aligned" if lamp_rot is None else "rotated with the body", frames=int(n_frames))
            row["rotation_deg"] = list(BLOCK_ROTATION_DEG) if name == "block rotated" else None
            row.update(direction_error(f, normals, select))
            row.update(t)
            row["balanced"] = bool(np.all(f.sum(axis=0) == 0.0))
            del lamp
            rows.append(row)
            _step(bar, f"{device.alias} frames {name} K={n_frames} d/{k:g}")
    return rows


def frames_block_scene(block_size: int = 20) -> tuple[Scene, Scene, np.ndarray, np.ndarray]:
    """The frames section's block: :func:`~warp_lamp.scenes.scene_lattice_box` of ``block_size`` per axis (seed 0),
    and the same block turned by :func:`block_rotation` about its centre.

    Returns:
        ``(block, turned, index, rotation)``: the two scenes, each particle's lattice index, shape (N, 3), and the
        turn.
    """
    block = scene_lattice_box(block_size)
    index = np.stack(np.unravel_index(np.arange(block.n), (block_size,) * 3), axis=1)
    rot = block_rotation()
    turned = Scene(
        block.name + ", rotated", (block.centers - block.center) @ rot.T + block.center, block.radii, block.center
    )
    return block, turned, index, rot


def frames_block_case(*, lamp_turned: bool, cells_per_diameter: float = 4, block_size: int = 20, device=None) -> dict:
    """One row of the frames section's turned block, without the timing: the lamp axis-aligned or turned with the
    block, its forces (world positions in float32, moved into the frame on the device, as the section times them)
    and their direction error over the face interiors. ``examples/frames_block.py`` draws this.

    Returns:
        ``forces`` (N, 3) [N at P = 1 Pa], ``index`` (lattice index, (N, 3)), ``select`` and ``normals``
        (:func:`~warp_lamp.measures.block_face_interior`), ``rotation``, and the keys of
        :func:`~warp_lamp.measures.direction_error`.
    """
    device = wp.get_device(device)
    _, turned, index, rot = frames_block_scene(block_size)
    lamp_rot = rot if lamp_turned else None
    grid = LampGrid.enclosing(turned.centers, turned.radii, cells_per_diameter=cells_per_diameter, rotation=lamp_rot)
    lamp = ShiningLamp(grid, device=device)
    lamp.update(
        _positions(turned.centers, grid, device, False),
        wp.array(turned.radii.astype(np.float32), dtype=wp.float32, device=device),
    )
    f = lamp.forces_numpy(P)
    select, normals = block_face_interior(index, block_size, rotation=rot, edge=BLOCK_EDGE)
    return {
        "forces": f,
        "index": index,
        "select": select,
        "normals": normals,
        "rotation": rot,
        **direction_error(f, normals, select),
    }


# --- driver and tables ------------------------------------------------------------------------------------------


def bench_modes(devices=None, *, quick: bool = False, progress: bool = True, repeats: int | None = None) -> dict:
    """Run the four sections on every device and return ``{"small_body", "area", "wetted", "frames"}``.

    The large scenes (the 1M and 8M lattice boxes) run only on CUDA and only when not ``quick``.

    Args:
        devices: Warp devices (names); all present when None.
        quick: The CPU-sized subset (criterion 1 to 16 cells per diameter; no large scenes).
        progress: Show a progress bar on stderr.
        repeats: Timed repeats per figure (default 50 on CUDA, 5 on the CPU; 20 and 3 when quick).
    """
    devices = [wp.get_device(d) for d in (devices or ["cpu"] + [d.alias for d in wp.get_cuda_devices()])]
    specimen = scene_sphere_specimen()
    c1 = (2, 4, 8, 16) if quick else (2, 4, 8, 16, 32)
    plan = [(device, device.is_cuda and not quick) for device in devices]
    # Rows per device: small body 4 (+3 large), area len(c1) + 12 + 8 overlap + 6 lone (+3), wetted 4 (+2),
    # frames 2 x 7.
    total = sum(4 + len(c1) + 26 + 4 + 14 + 8 * big for _, big in plan)
    bar = Progress(total, "bench modes", enabled=progress)
    out = {"small_body": [], "area": [], "wetted": [], "frames": []}
    for device, big in plan:
        reps = repeats or _default_repeats(device, quick)
        large = ((100, 0.25), (100, "d/16"), (200, 0.25)) if big else ()
        out["small_body"] += section_small_body(device, repeats=reps, specimen=specimen, large=large, bar=bar)
        out["area"].append(
            section_area(
                device,
                repeats=reps,
                specimen=specimen,
                criterion1_cpd=c1,
                overlap=scene_overlapping_polydisperse(300 if quick else 1000),
                lone_samples=16 if quick else 64,
                large=(100,) if big else (),
                bar=bar,
            )
        )
        out["wetted"] += section_wetted(device, repeats=reps, specimen=specimen, large=(100,) if big else (), bar=bar)
        out["frames"] += section_frames(device, repeats=reps, ball=specimen, bar=bar)
    bar.close()
    return out


def _ms(x) -> str:
    return "-" if x is None else f"{x * 1e3:.3f}"


def _x(x) -> str:
    return "-" if x is None else f"{x:.2f}x"


def _deg(x) -> str:
    return "-" if x is None else f"{x:.2f}"


def format_modes(result: dict) -> str:
    """The four sections of a result (those present) as Markdown tables."""
    lines = []
    if result.get("small_body"):
        lines += [
            "",
            "Small bodies: the depth pass against the previous release's one thread per sphere (split=0, order=False), "
            "same run; update / replay / moving body [ms]; speed-up = previous release time / today's time:",
            "",
        ]
        rows = []
        for r in result["small_body"]:
            d, v = r["default"], r["v4"]
            rows.append(
                [
                    r["device"],
                    f"{r['scene']}, {r['n']:,}",
                    r["grid"],
                    f"{r['cells']:,}",
                    str(d["split"]),
                    f"{_ms(d['eager_s'])} / {_ms(d['replay_s'])} / {_ms(d['moving_s'])}",
                    f"{_ms(v['eager_s'])} / {_ms(v['replay_s'])} / {_ms(v['moving_s'])}",
                    " / ".join(_x(r["speedup"][k]) for k in ("eager", "replay", "moving")),
                    "yes" if r["same_counts"] else "**no**",
                ]
            )
        header = [
            "device",
            "scene",
            "grid",
            "cells",
            "split",
            "today ms",
            "previous release ms",
            "speed-up",
            "same counts",
        ]
        lines += markdown_table(header, rows)
    for sec in result.get("area") or []:
        lines += [
            "",
            f"Area criterion on the {sec['scene']} ({sec['n']:,} spheres): per-particle force error "
            "|F - F_exact| / (P pi rbar^2) against the exact visible areas (RMS over surface particles; worst "
            f"particle); update = graph replay on CUDA, eager on the CPU (exact reference: {sec['reference_s']:.2f} s "
            "NumPy):",
            "",
        ]
        rows = [
            [
                r["device"],
                _estimator_name(r),
                f"{r['cells_per_diameter']:g}",
                f"{r['rms']:.3%}",
                f"{r['worst']:.2%}",
                _ms(r["update_s"]),
                _x(r["ratio"]),
                f"{r['overflow']} / {r['one_sided']}",
            ]
            for r in sec["rows"]
        ]
        header = ["device", "estimator", "cells/d", "RMS", "worst", "update ms", "x C1 at d/4"]
        lines += markdown_table([*header, "overflow / one-sided"], rows)
        if sec.get("overlap"):
            lines += [
                "",
                f"The same on the {sec['overlap_scene']} ({sec['overlap_n']:,} spheres, radius ratio 3, overlaps up "
                f"to 30% of the smaller radius; exact reference by surface depth: {sec['overlap_reference_s']:.2f} s):",
                "",
            ]
            rows = [
                [
                    r["device"],
                    _estimator_name(r),
                    f"{r['cells_per_diameter']:g}",
                    f"{r['rms']:.3%}",
                    f"{r['worst']:.2%}",
                ]
                for r in sec["overlap"]
            ]
            lines += markdown_table(["device", "estimator", "cells/d", "RMS", "worst"], rows)
        if sec.get("lone"):
            lines += [
                "",
                "A lone sphere: each lamp's load over P pi r^2, minus 1, over random offsets and six lamps:",
                "",
            ]
            rows = [
                [r["device"], r["resolver"], f"{r['cells_per_diameter']:g}", f"{r['rms']:.2e}", f"{r['worst']:.2e}"]
                for r in sec["lone"]
            ]
            lines += markdown_table(["device", "resolver", "cells/d", "RMS", "worst"], rows)
        if sec.get("large"):
            lines += ["", "The area criterion's defaults on the lattice box, against criterion 1 at cell 0.25:", ""]
            rows = [
                [
                    r["device"],
                    f"{r['n']:,}",
                    _estimator_name(r),
                    f"{r['cell']:.4g} ({r['cells_per_diameter']:.2f}/d)",
                    _ms(r["update_s"]),
                    _x(r["ratio"]),
                ]
                for r in sec["large"]
            ]
            lines += markdown_table(["device", "spheres", "criterion", "cell", "update ms", "x C1 cell 0.25"], rows)
    if result.get("wetted"):
        lines += [
            "",
            "Wetted surface: first against all (rho = one mean radius), same grid; update and moving "
            "body [ms]; loaded particles; slot block: walls (-y / +y) over P L D, floor over P L w:",
            "",
        ]
        rows = []
        for r in result["wetted"]:
            q = r.get("ratios")
            rows.append(
                [
                    r["device"],
                    f"{r['scene']}, {r['n']:,}",
                    r["grid"],
                    r["surfaces"] + ("" if r["rho"] is None else f", rho {r['rho']:.4g}"),
                    _ms(r["update_s"]),
                    _ms(r["moving_s"]),
                    f"{r['loaded']:,}",
                    "-" if q is None else f"{q['wall_lo']:.3f} / {q['wall_hi']:.3f}",
                    "-" if q is None else f"{q['floor']:.3f}",
                ]
            )
        header = ["device", "scene", "grid", "surfaces", "update ms", "moving ms", "loaded", "walls", "floor"]
        lines += markdown_table(header, rows)
    if result.get("frames"):
        lines += [
            "",
            "Lamp frames: angle between each surface particle's force and the envelope's inward normal "
            f"(block: face interiors, {BLOCK_EDGE}+ sites from the edges, turned {BLOCK_ROTATION_DEG} deg about "
            f"x, y, z; ball: centres within {BALL_DEPTH_RADII:g} rbar of the envelope, radial direction):",
            "",
        ]
        rows = [
            [
                r["device"],
                r["body"],
                r["lamp"],
                str(r["frames"]),
                f"{r['cells_per_diameter']:g}",
                _deg(r["mean_deg"]),
                _deg(r["p90_deg"]),
                f"{r['loaded']:,} / {r['particles']:,}",
                _ms(r["update_s"]),
            ]
            for r in result["frames"]
        ]
        header = ["device", "body", "lamp", "frames", "cells/d", "mean deg", "p90 deg", "loaded / surface"]
        lines += markdown_table([*header, "update ms"], rows)
    return "\n".join(lines)


def plot_area(ax, result: dict) -> list:
    """Update time against the specimen's per-particle force error (the ``area`` section), on a matplotlib axes:
    a colour per estimator, solid on CUDA (graph replay) and dashed on the CPU (eager), the axis label naming
    only the styles drawn. Returns the point labels
    (``(text, (x, y), fontsize)``) for :func:`warp_lamp.bench.place_labels`, which the caller places once the
    figure's layout is fixed."""
    labels = []
    colours = {}
    sections = result.get("area") or []
    # The benchmark writes a section per device; CPU curves are labelled only where no GPU ran (one legend entry
    # per estimator).
    has_cuda = any(r["device"].startswith("cuda") for sec in sections for r in sec["rows"])
    for sec in sections:
        keys = []
        for r in sec["rows"]:
            key = (r["device"], _estimator_name(r))
            if key not in keys:
                keys.append(key)
        for dev, name in keys:
            pts = [r for r in sec["rows"] if (r["device"], _estimator_name(r)) == (dev, name)]
            err = [100.0 * r["rms"] for r in pts]
            t = [r["update_s"] * 1e3 for r in pts]
            cuda = dev.startswith("cuda")
            colour = colours.setdefault(name, f"C{len(colours)}")
            ax.loglog(
                err,
                t,
                ("o" if name.startswith("criterion") else "s") + ("-" if cuda else "--"),
                color=colour,
                alpha=1.0 if cuda else 0.45,
                markersize=4,
                label=name if cuda or not has_cuda else None,
            )
            if cuda or not has_cuda:
                labels += [(f"d/{r['cells_per_diameter']:g}", (x, y), 6) for r, x, y in zip(pts, err, t, strict=True)]
        ax.set_title(f"{sec['scene']} ({sec['n']:,} spheres)", fontsize=9)
    ax.set_xlabel("per-particle force error [%], RMS, vs exact visible areas", fontsize=9)
    # Name only the line styles that are drawn: a result timed on one kind of device has one.
    kinds = {r["device"].startswith("cuda") for sec in sections for r in sec["rows"]}
    styles = {frozenset({True}): "CUDA graph replay", frozenset({False}): "CPU, eager"}
    ax.set_ylabel(f"update [ms]: {styles.get(frozenset(kinds), 'CUDA replay (solid), CPU eager (dashed)')}", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, loc="upper right")
    return labels
