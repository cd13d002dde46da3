"""The distributed lamp and porosity checked against one process holding all particles, on every rank of a
collective: the cases that ``test_distributed.py`` runs on thread ranks (NCCL stand-in) and, through
``distributed_ranks.py``, on MPI processes, and that ``bench/gpu/parts/distributed.sh`` runs on GPUs.

Every rank builds the whole scene from one seed, runs the single-process lamp on all particles in global-id order,
runs the distributed lamp on its share, and compares its rows bitwise. Each case returns a dict: its name, ``ok``,
and what differed.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_lamp import LAMPS, LampGrid, ShiningLamp, porosity
from warp_lamp.distributed import DistributedLamp, enclosing_grid, porosity_distributed
from warp_lamp.scenes import scene_lattice_box

SPLITS = ("random", "interleaved", "spatial", "blocks", "lopsided")
PRESSURE = (2.0e5, 1.5e5, 3.0e5)
#: A turned lamp frame, as a unit quaternion (x, y, z, w).
TURN = (0.1, 0.2, 0.3, float(np.sqrt(0.86)))


def scenes(kind: str):
    """(centres, radii): ``"lattice"`` has exact ties everywhere (no jitter, equal radii, touching), ``"random"``
    overlapping polydisperse spheres."""
    if kind == "lattice":
        s = scene_lattice_box((7, 6, 5), jitter=0.0, rmin=0.5, rmax=0.5)
        return s.centers, s.radii
    rng = np.random.default_rng(7)
    return rng.uniform(0.0, 5.0, (260, 3)), rng.uniform(0.2, 0.6, 260)


def split_rows(kind: str, centers: np.ndarray, rank: int, size: int, seed: int = 3) -> np.ndarray:
    """The global ids of rank ``rank``, in the order the rank holds them: ``random`` (a random share, held in a
    random order, so the library sorts), ``interleaved`` (i % size), ``spatial`` (slabs along x), ``blocks`` (a
    grid of blocks across y and z, as square as the rank count allows), ``lopsided`` (everything on the last rank;
    the others hold none)."""
    n = len(centers)
    if kind == "random":
        rng = np.random.default_rng(seed)
        owner = rng.integers(0, size, n)
        mine = np.flatnonzero(owner == rank)
        return rng.permutation(mine) if len(mine) else mine
    if kind == "interleaved":
        return np.arange(rank, n, size)
    if kind == "spatial":
        x = centers[:, 0]
        edges = np.quantile(x, np.linspace(0, 1, size + 1)[1:-1])
        return np.flatnonzero(np.searchsorted(edges, x, side="right") == rank)
    if kind == "blocks":
        py = max(d for d in range(1, int(np.sqrt(size)) + 1) if size % d == 0)
        pz = size // py
        y_edges = np.quantile(centers[:, 1], np.linspace(0, 1, py + 1)[1:-1])
        z_edges = np.quantile(centers[:, 2], np.linspace(0, 1, pz + 1)[1:-1])
        by = np.searchsorted(y_edges, centers[:, 1], side="right")
        bz = np.searchsorted(z_edges, centers[:, 2], side="right")
        return np.flatnonzero(by * pz + bz == rank)
    if kind == "lopsided":
        return np.arange(n) if rank == size - 1 else np.zeros(0, dtype=np.int64)
    raise ValueError(kind)


def _compare(name, got, want) -> dict:
    got = np.asarray(got)
    want = np.asarray(want)
    if got.shape != want.shape:
        return {"case": name, "ok": False, "why": f"shape {got.shape} != {want.shape}"}
    same = np.array_equal(got.view(np.uint8), want.view(np.uint8)) if got.size else True
    out = {"case": name, "ok": bool(same)}
    if not same:
        bad = np.flatnonzero(np.any((got != want).reshape(len(got), -1), axis=1)) if got.ndim else [0]
        out["why"] = f"{len(bad)} rows differ, first {int(bad[0])}: {got[bad[0]]!r} != {want[bad[0]]!r}"
    return out


def _arrays(centers, radii, rows, device, in_frame_grid=None):
    c = centers[rows]
    if in_frame_grid is not None:
        c = in_frame_grid.to_frame(c)
    pos = wp.array(c.astype(np.float32).reshape(-1, 3), dtype=wp.vec3, device=device)
    rad = wp.array(radii[rows].astype(np.float32), dtype=wp.float32, device=device)
    return pos, rad


def lamp_case(coll, name, centers, radii, grid, split, *, active=None, in_frame=True, **options) -> list[dict]:
    """One mode on one split: counts, exact forces and float32 forces of the rank's rows against one process,
    and the diagnostics' lit cells and skip counters."""
    device = coll.device
    n = len(radii)
    frame = grid if in_frame else None
    pos, rad = _arrays(centers, radii, np.arange(n), device, frame)
    act = None if active is None else wp.array(active.astype(np.int32), dtype=wp.int32, device=device)
    ref = ShiningLamp(grid, device=device, **options)
    ref.update(pos, rad, act, in_frame=in_frame)
    ref_forces = wp.zeros(n, dtype=wp.vec3, device=device)
    ref.add_forces(ref_forces, PRESSURE)
    ref_diag = ref.diagnostics()

    rows = split_rows(split, centers, coll.rank, coll.size)
    lamp = DistributedLamp(grid, coll, **options)
    lamp.set_ids(rows)
    lpos, lrad = _arrays(centers, radii, rows, device, frame)
    lact = None if active is None else wp.array(active[rows].astype(np.int32), dtype=wp.int32, device=device)
    lamp.update(lpos, lrad, lact, in_frame=in_frame)
    forces = wp.zeros(len(rows), dtype=wp.vec3, device=device)
    lamp.add_forces(forces, PRESSURE)
    diag = lamp.diagnostics()
    tag = f"{name} / {split}"
    out = [
        _compare(f"{tag}: counts", lamp.counts_numpy(), ref.counts_numpy()[rows]),
        _compare(f"{tag}: forces float64", lamp.forces_numpy(PRESSURE), ref.forces_numpy(PRESSURE)[rows]),
        _compare(f"{tag}: forces float32", forces.numpy(), ref_forces.numpy()[rows]),
        _compare(f"{tag}: surface", diag.lamp.surface, ref_diag.surface[rows]),
    ]
    same = diag.lamp.lit == ref_diag.lit and (diag.lamp.invalid, diag.lamp.outside) == (
        ref_diag.invalid,
        ref_diag.outside,
    )
    out.append({"case": f"{tag}: lit and skipped", "ok": bool(same)})
    if options.get("follow"):
        out.append(_compare(f"{tag}: follow shift", lamp.follow_shift.numpy(), ref.follow_shift.numpy()))
    if options.get("walls"):
        # Every rank holds the walls' counts of the whole grid; the owner maps (global ids = the reference's rows)
        # with the walls applied, and the walls' maps, are the whole grid's too.
        out.append(_compare(f"{tag}: wall forces", lamp.wall_forces_numpy(PRESSURE), ref.wall_forces_numpy(PRESSURE)))
        maps = ("owners", "wall_owners")
        same = all(np.array_equal(getattr(diag.lamp, m)[k], getattr(ref_diag, m)[k]) for m in maps for k in LAMPS)
        out.append({"case": f"{tag}: owners and wall owners", "ok": bool(same and np.abs(ref_diag.wall_counts).sum())})
    # Warm again on another split: the rank's keys still name its old particles (a migration); the seed then offers
    # what the depth pass would, so the result is the same.
    moved = split_rows("random" if split != "random" else "interleaved", centers, coll.rank, coll.size, seed=11)
    lamp.set_ids(moved)
    mpos, mrad = _arrays(centers, radii, moved, device, frame)
    mact = None if active is None else wp.array(active[moved].astype(np.int32), dtype=wp.int32, device=device)
    lamp.update(mpos, mrad, mact, in_frame=in_frame)
    out.append(_compare(f"{tag}: counts after migration", lamp.counts_numpy(), ref.counts_numpy()[moved]))
    return out


def lamp_cases(coll, *, quick: bool = False) -> list[dict]:
    """Criteria 0 and 1, a lamp subset, the area criterion, world positions in a turned frame with the following
    grid, invalid and inactive particles, walls: each on every split."""
    out = []
    lattice = scenes("lattice")
    rand = scenes("random")
    g_lat = LampGrid.enclosing(*lattice, cells_per_diameter=4)
    g_rand = LampGrid.enclosing(*rand, cells_per_diameter=3)
    turn = LampGrid.enclosing(*rand, cells_per_diameter=3, rotation=TURN)
    c_bad, r_bad = rand[0].copy(), rand[1].copy()
    c_bad[5] = np.nan
    r_bad[9] = 0.0
    active = (np.arange(len(r_bad)) % 7 != 3).astype(np.int32)
    # A platen under the body's lower part and a tilted wall across a corner.
    walls = [((0.0, 0.0, 1.5), (0.0, 0.0, 1.0)), ((4.2, 0.0, 0.0), (-1.0, 0.2, 0.1))]
    splits = ("random", "spatial") if quick else SPLITS
    for split in splits:
        out += lamp_case(coll, "criterion 0, lattice ties", *lattice, g_lat, split, criterion=0)
        out += lamp_case(coll, "criterion 1, lattice ties", *lattice, g_lat, split, criterion=1)
        out += lamp_case(coll, "criterion 1, random", *rand, g_rand, split, criterion=1)
        out += lamp_case(
            coll, "criterion 0, lamps -x +y +z", *rand, g_rand, split, criterion=0, lamps=("-x", "+y", "+z")
        )
        out += lamp_case(coll, "area, subpoints, D=3", *rand, g_rand, split, criterion="area", depth_slots=3)
        out += lamp_case(coll, "criterion 1, invalid and inactive", c_bad, r_bad, g_rand, split, active=active)
        out += lamp_case(coll, "criterion 1, walls", *rand, g_rand, split, walls=walls)
        if not quick:
            out += lamp_case(coll, "area, lattice ties, D=2", *lattice, g_lat, split, criterion="area", depth_slots=2)
            out += lamp_case(
                coll, "criterion 1, turned frame, world, follow", *rand, turn, split, in_frame=False, follow=True
            )
            out += lamp_case(
                coll, "criterion 0, walls, turned frame, world, follow", *rand, turn, split, in_frame=False,
                follow=True, criterion=0, walls=walls,
            )  # fmt: skip
    return out


def reach_cases(coll) -> list[dict]:
    """The reach (each rank seeds, reduces and scatters only the cells its particles can reach) on every split and
    margin, on a body long in x: counts bitwise equal to one process; with slabs on two or more ranks, fewer cells
    reduced than the grid holds; particles moved within the margin (a warm update: no escapes, still bitwise);
    with slabs, one sphere moved onto another slab (exactly one escape); moved past it (escapes counted on every
    rank), then the reach agreed again (bitwise again); the diagnostics'
    whole-grid maps; and ``reach="all"``."""
    out = []
    rng = np.random.default_rng(21)
    c = rng.uniform((0.0, 0.0, 0.0), (12.0, 4.0, 3.0), (420, 3))
    r = rng.uniform(0.2, 0.45, 420)
    lattice = scene_lattice_box((14, 4, 3), jitter=0.0, rmin=0.5, rmax=0.5)
    device = coll.device

    def reference(centers, radii, grid, criterion):
        ref = ShiningLamp(grid, device=device, criterion=criterion)
        pos, rad = _arrays(centers, radii, np.arange(len(radii)), device, grid)
        ref.update(pos, rad, in_frame=True)
        return ref

    for scene_name, (cs, rs), criterion in (
        ("random", (c, r), 1),
        ("lattice ties", (lattice.centers, lattice.radii), 0),
    ):
        grid = LampGrid.enclosing(cs, rs, cells_per_diameter=4)
        ref = reference(cs, rs, grid, criterion)
        for split in SPLITS:
            rows = split_rows(split, cs, coll.rank, coll.size)
            for margin in (0, 2):
                tag = f"reach, {scene_name}, criterion {criterion}, margin {margin} / {split}"
                lamp = DistributedLamp(grid, coll, criterion=criterion, reach_margin=margin)
                lamp.set_ids(rows)
                pos, rad = _arrays(cs, rs, rows, device, grid)
                lamp.update(pos, rad, in_frame=True)
                out.append(_compare(f"{tag}: counts", lamp.counts_numpy(), ref.counts_numpy()[rows]))
                out.append({"case": f"{tag}: no escapes", "ok": lamp.reach_escapes() == 0})
                est = lamp.estimator
                if split == "spatial" and coll.size >= 2 and margin == 0:
                    fewer = est.shared_cells < grid.n_cells and lamp.reduction_bytes == 16 * est.shared_cells
                    out.append({"case": f"{tag}: fewer cells reduced", "ok": bool(fewer)})
            diag = lamp.diagnostics()
            ref_diag = ref.diagnostics()
            same = all(np.array_equal(diag.lamp.owners[k], ref_diag.owners[k]) for k in LAMPS)
            out.append({"case": f"reach, {scene_name} / {split}: whole-grid owners", "ok": bool(same)})
            # A small move (a tenth of a cell) stays within the margin of 2 cells: warm seeds, no escape.
            step = 0.1 * float(grid.cell[0, 0])
            moved = cs + np.array([step, -0.5 * step, 0.3 * step])
            want = reference(moved, rs, grid, criterion).counts_numpy()[rows]
            mpos, _ = _arrays(moved, rs, rows, device, grid)
            lamp.update(mpos, rad, in_frame=True)
            out.append(_compare(f"reach, {scene_name} / {split}: moved within the margin", lamp.counts_numpy(), want))
            out.append({"case": f"reach, {scene_name} / {split}: no escapes", "ok": lamp.reach_escapes() == 0})
            if split == "spatial" and coll.size >= 2:
                # One sphere of the first slab moved onto the last slab's end leaves its rank's window on the y and
                # z grids and nothing else moves: exactly one escape, counted once (not once per grid).
                hop = moved.copy()
                hop[np.argmin(cs[:, 0])] = moved[np.argmax(cs[:, 0])]
                hpos, _ = _arrays(hop, rs, rows, device, grid)
                lamp.update(hpos, rad, in_frame=True)
                out.append({"case": f"reach, {scene_name} / {split}: one escape", "ok": lamp.reach_escapes() == 1})
            # Past the margin: the escapes are counted on every rank; agreed again, the update is bitwise again.
            far = cs + np.array([1.5, 0.0, 0.0]) * (1.0 if scene_name == "random" else -1.0)
            ref_far = reference(far, rs, grid, criterion)
            fpos, _ = _arrays(far, rs, rows, device, grid)
            lamp.update(fpos, rad, in_frame=True)
            escaped = lamp.reach_escapes()
            out.append({"case": f"reach, {scene_name} / {split}: escapes counted", "ok": escaped > 0})
            lamp.agree_reach()
            lamp.update(fpos, rad, in_frame=True)
            got = lamp.counts_numpy()
            out.append(_compare(f"reach, {scene_name} / {split}: agreed again", got, ref_far.counts_numpy()[rows]))
            out.append({"case": f"reach, {scene_name} / {split}: none after", "ok": lamp.reach_escapes() == 0})
            every = DistributedLamp(grid, coll, criterion=criterion, reach="all")
            every.set_ids(rows)
            every.update(pos, rad, in_frame=True)
            out.append(_compare(f"reach all, {scene_name} / {split}", every.counts_numpy(), ref.counts_numpy()[rows]))
    return out


def grid_cases(coll) -> list[dict]:
    """enclosing_grid on each split against LampGrid.enclosing on all particles (bitwise), turned and not."""
    out = []
    for kind in ("lattice", "random"):
        c, r = scenes(kind)
        for rotation in (None, TURN):
            want = LampGrid.enclosing(c, r, cells_per_diameter=3.5, rotation=rotation)
            for split in SPLITS:
                rows = split_rows(split, c, coll.rank, coll.size)
                got = enclosing_grid(coll, c[rows], r[rows], rows, cells_per_diameter=3.5, rotation=rotation)
                same = all(
                    np.array_equal(getattr(got, k), getattr(want, k))
                    for k in ("corner", "cell", "counts", "origin", "rotation")
                )
                out.append({"case": f"enclosing grid, {kind}, rotation {rotation}, {split}", "ok": bool(same)})
    return out


def porosity_cases(coll, *, quick: bool = False) -> list[dict]:
    """Every porosity method on every split: union methods bitwise equal to ``porosity`` on all spheres; sum methods
    bitwise equal to the one-rank fixed-point sums, and within their stated bound of ``porosity``."""
    out = []
    c, r = scenes("random")
    lower, upper, shape = (-0.5, -0.5, -0.5), (5.5, 5.5, 4.5), (6, 6, 5)
    splits = ("random", "spatial") if quick else SPLITS
    for method in ("voxel", "midpoint", "centroid", "polyhedron", "exact"):
        want = porosity(c, r, lower, upper, shape, method=method, subdivisions=4, device=coll.device)
        one = porosity_distributed(None, c, r, lower, upper, shape, method=method, subdivisions=4, device=coll.device)
        for split in splits:
            rows = split_rows(split, c, coll.rank, coll.size)
            got = porosity_distributed(
                coll, c[rows], r[rows], lower, upper, shape, method=method, subdivisions=4, device=coll.device
            )
            if method in ("voxel", "midpoint"):
                out.append(_compare(f"porosity {method} / {split}", got, want))
                continue
            out.append(_compare(f"porosity {method} / {split} (fixed point)", got, one))
            # Each cell gets at most len(r) sphere-cell volumes, each rounded by at most 2^-41 of the cell.
            bound = len(r) * 2.0**-41 + 1e-13
            err = float(np.max(np.abs(got - want)))
            out.append({"case": f"porosity {method} / {split} vs porosity()", "ok": err <= bound, "error": err})
    return out


def all_cases(coll, *, quick: bool = False) -> list[dict]:
    return lamp_cases(coll, quick=quick) + reach_cases(coll) + grid_cases(coll) + porosity_cases(coll, quick=quick)
