"""The distributed lamp and porosity: bitwise equal to one process on every split, over MPI processes, NCCL's code
path on thread ranks, and one rank; the distributed kernels against their references; the refusals."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import distributed_cases
import numpy as np
import pytest
import warp as wp
from fake_collectives import fake_nccl_collectives, run_ranks
from helpers import polydisperse_scene

from warp_lamp import LampGrid, ShiningLamp
from warp_lamp.distributed import (
    FRAMES_REFUSAL,
    WETTED_REFUSAL,
    DistributedLamp,
    LocalCollective,
    as_collective,
    porosity_fixed_units,
)
from warp_lamp.kernels import distributed as dist_kernels
from warp_lamp.kernels import lamp as lamp_kernels
from warp_lamp.pipeline import LampFrame
from warp_lamp.reference.area import ordered_key
from warp_lamp.reference.distributed import (
    EMPTY_KEY,
    fixed_units_reference,
    global_keys_reference,
    merge_lists_reference,
    reach_reference,
    scatter_reference,
    scatter_walls_reference,
)
from warp_lamp.validate import check_walls

ROOT = Path(__file__).resolve().parent.parent


def _failures(results):
    return [r for r in results if not r["ok"]]


def _mpiexec():
    """The mpiexec beside this Python (the ``mpich`` wheel's), else one on PATH; None where there is none, or where
    mpi4py cannot load an MPI library (asked in a child process, so that this one stays no MPI process)."""
    local = Path(sys.executable).parent / "mpiexec"
    found = str(local) if local.exists() else shutil.which("mpiexec")
    if found is None:
        return None
    probe = subprocess.run([sys.executable, "-c", "from mpi4py import MPI"], capture_output=True, timeout=60)
    return found if probe.returncode == 0 else None


def test_one_rank_equals_shining_lamp(device):
    """One rank (no library) reproduces ShiningLamp bitwise on every mode, and porosity on every method."""
    results = distributed_cases.all_cases(LocalCollective(device), quick=True)
    assert len(results) > 50
    assert not _failures(results)


@pytest.mark.parametrize("ranks", [2, 3])
def test_nccl_path_on_thread_ranks(ranks):
    """The NCCL code path (raw pointers on Warp's stream, dtype and op codes, the gathered OR) on 2 and 3 thread
    ranks, the 3-rank run reducing keys as int64 through the top-bit flip as torch does: every mode, split and
    porosity method bitwise equal to one process."""
    colls = fake_nccl_collectives(ranks, int64_only=ranks == 3)
    results = run_ranks(colls, distributed_cases.all_cases)
    flat = [r for part in results for r in part]
    assert not _failures(flat)
    names = " ".join(r["case"] for r in flat)
    for split in distributed_cases.SPLITS:
        assert f"/ {split}" in names
    assert colls[0].comm.world.calls > 100
    assert colls[0].comm.streams == {0}  # the CPU's stand-in for Warp's stream


def _skip_outside_ci(reason: str) -> None:
    """Skips, except in CI (``CI=true``), whose test extra installs MPI and torch: there a missing rank library is a
    failure, not a skip, so that CI cannot pass without running the process tests."""
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail("CI runs the rank tests: " + reason)
    pytest.skip(reason)


def _torch_distributed():
    try:
        import torch.distributed as torch_dist
    except ImportError:
        _skip_outside_ci("needs torch (the test extra installs it)")
    if not torch_dist.is_available():
        _skip_outside_ci("torch.distributed is not available in this torch build")
    return torch_dist


def test_mpi_processes(tmp_path):
    """Two MPI processes (mpiexec from the mpich wheel, over mpi4py) on the CPU: forces bitwise equal to one process
    for criteria 0, 1, a lamp subset and the area criterion on random, interleaved, spatial and lopsided splits,
    the agreed enclosing grid equal to LampGrid.enclosing, and porosity equal for each method."""
    mpiexec = _mpiexec()
    if mpiexec is None:
        _skip_outside_ci("needs mpiexec and mpi4py with an MPI library: pip install '.[distributed]' (mpi4py, mpich)")
    # Compile every kernel once here, so that the two ranks load them from the cache instead of both compiling.
    distributed_cases.lamp_cases(LocalCollective("cpu"), quick=True)
    out = tmp_path / "ranks.json"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    # Containers often run as root, which OpenMPI's mpiexec refuses unless told (MPICH ignores these).
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = [mpiexec, "-n", "2", sys.executable, str(ROOT / "tests" / "distributed_ranks.py"), "--json", str(out)]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    summary = json.loads(out.read_text())
    assert summary["ranks"] == 2 and summary["ok"] and summary["failed"] == 0
    cases = [r["case"] for r in summary["per_rank"][0]["results"]]
    needles = ("criterion 0", "criterion 1", "lamps -x +y +z", "area", "follow", "enclosing grid", "porosity", "reach")
    for needle in needles:
        assert any(needle in c for c in cases), needle
    for method in ("voxel", "midpoint", "centroid", "polyhedron", "exact"):
        assert any(f"porosity {method}" in c for c in cases)


def test_capture_replays_the_update(cuda_device):
    """A distributed update recorded in a CUDA graph (one rank, a capturable collective) replays bitwise as eager,
    at new positions too."""
    rng = np.random.default_rng(4)
    c, r = polydisperse_scene(rng, n=400)
    grid = LampGrid.enclosing(c, r, cells_per_diameter=4)
    lamp = DistributedLamp(grid, LocalCollective(cuda_device))
    lamp.set_ids(rng.permutation(len(r)))
    pos = wp.array(c.astype(np.float32), dtype=wp.vec3, device=cuda_device)
    moved = wp.array((c + rng.normal(scale=0.05, size=c.shape)).astype(np.float32), dtype=wp.vec3, device=cuda_device)
    rad = wp.array(r.astype(np.float32), dtype=wp.float32, device=cuda_device)
    lamp.update(moved, rad)
    eager_moved = lamp.counts_numpy()
    lamp.update(pos, rad)
    eager = lamp.counts_numpy()
    with wp.ScopedCapture(device=cuda_device) as capture:
        lamp.update(moved, rad)
    wp.capture_launch(capture.graph)
    assert np.array_equal(lamp.counts_numpy(), eager_moved)
    lamp.update(pos, rad)
    assert np.array_equal(lamp.counts_numpy(), eager)


def test_keys_to_global_and_flip(device):
    """dist_keys_to_global against its reference, with and without the flip, on random keys and EMPTY; flipped keys
    read as int64 sort as the unsigned keys do (the reason for the flip)."""
    rng = np.random.default_rng(1)
    n = 50
    gids = rng.choice(1 << 31 - 1, size=n, replace=False).astype(np.int32)
    gids[0] = (1 << 31) - 2
    depth = rng.normal(scale=10.0, size=400).astype(np.float32)
    depth[:4] = (0.0, -0.0, np.float32(3.4e38), -np.float32(3.4e38))
    keys = ordered_key(depth, rng.integers(0, n, 400))
    keys[::7] = EMPTY_KEY
    k = wp.array(keys, dtype=wp.uint64, device=device)
    g = wp.array(gids, dtype=wp.int32, device=device)
    out = wp.empty(len(keys), dtype=wp.uint64, device=device)
    for flip in (0, 1):
        wp.launch(dist_kernels.dist_keys_to_global, dim=len(keys), inputs=[k, g, flip], outputs=[out], device=device)
        got = out.numpy()
        assert np.array_equal(got, global_keys_reference(keys, gids, flip=bool(flip)))
    unflipped = global_keys_reference(keys, gids)
    assert np.array_equal(np.argsort(got.view(np.int64), kind="stable"), np.argsort(unflipped, kind="stable"))


def test_scatter_reference(device):
    """dist_scatter against its reference on keys where some cells are the rank's, some another rank's, some EMPTY,
    with a caller permutation."""
    rng = np.random.default_rng(2)
    grid = LampGrid((0.0, 0.0, 0.0), (3.0, 2.0, 2.5), 0.5)
    cells = grid.n_cells
    n = 30
    gids = np.sort(rng.choice(1000, size=n, replace=False)).astype(np.int32)
    caller = rng.permutation(n).astype(np.int32)
    keys = ordered_key(rng.normal(size=2 * cells), rng.integers(0, n, 2 * cells))
    keys[rng.random(2 * cells) < 0.2] = EMPTY_KEY
    mine = global_keys_reference(keys, gids)
    reduced = mine.copy()
    other = rng.random(2 * cells) < 0.4
    reduced[other] = ordered_key(rng.normal(size=other.sum()), rng.integers(1000, 2000, other.sum()))
    reduced[rng.random(2 * cells) < 0.1] = EMPTY_KEY
    axis = np.concatenate([np.full(int(grid.counts[a, 0] * grid.counts[a, 1]), a) for a in range(3)])
    want = scatter_reference(reduced, keys, gids, caller, axis, n)
    assert np.abs(want).sum() > 10
    origin, rotation = grid.pose_arrays(device, in_frame=True)
    counts = wp.zeros(3 * n, dtype=wp.int64, device=device)
    wp.launch(
        dist_kernels.dist_scatter,
        dim=cells,
        inputs=[
            grid.params(origin, rotation),
            wp.array(keys, dtype=wp.uint64, device=device),
            wp.array(gids, dtype=wp.int32, device=device),
            wp.array(caller, dtype=wp.int32, device=device),
            0,
            wp.array(reduced, dtype=wp.uint64, device=device),
        ],
        outputs=[counts],
        device=device,
    )
    assert np.array_equal(counts.numpy().reshape(n, 3), want)


@pytest.mark.parametrize("criterion", [0, 1])
def test_reach_box_holds_every_lit_cell(device, criterion):
    """dist_reach's box per grid holds every cell the spheres light (brute force over every cell, float64), and is
    at most one cell wider on each side; a grid whose lamps are off is left unreached."""
    rng = np.random.default_rng(5 + criterion)
    grid = LampGrid((0.0, 0.0, 0.0), (4.0, 3.0, 3.5), (0.25, 0.3, 0.2))
    c = rng.uniform(0.8, 2.6, (12, 3))
    r = rng.uniform(0.1, 0.4, 12)
    want = reach_reference(c, r, grid.corner, grid.cell, grid.counts, criterion)
    origin, rotation = grid.pose_arrays(device, in_frame=True)
    particles = lamp_kernels.LampParticles()
    particles.positions = wp.array(c.astype(np.float32), dtype=wp.vec3, device=device)
    particles.radii = wp.array(r.astype(np.float32), dtype=wp.float32, device=device)
    particles.active = wp.empty(0, dtype=wp.int32, device=device)
    particles.n = 12
    for mask in (0b111111, 0b110011):
        big = np.iinfo(np.int32).max
        box = wp.array(np.array([big, -1, big, -1] * 3, dtype=np.int32), dtype=wp.int32, device=device)
        wp.launch(
            dist_kernels.dist_reach,
            dim=12,
            inputs=[grid.params(origin, rotation), particles, criterion, mask],
            outputs=[box],
            device=device,
        )
        got = box.numpy().astype(np.int64).reshape(3, 4)
        ref = want.reshape(3, 4)
        for a in range(3):
            if (mask >> (2 * a)) & 3 == 0:
                assert list(got[a]) == [big, -1, big, -1]
                continue
            assert ref[a, 1] >= 0  # the spheres light this grid
            lo, hi = got[a, [0, 2]], got[a, [1, 3]]
            assert np.all(lo <= ref[a, [0, 2]]) and np.all(hi >= ref[a, [1, 3]])
            assert np.all(lo >= ref[a, [0, 2]] - 1) and np.all(hi <= ref[a, [1, 3]] + 1)


@pytest.mark.parametrize("ray", [0, 1, 2])
def test_escape_filter_is_the_exact_test(device, ray):
    """dist_escapes' comparisons-only filter counts the same escapes as the exact footprint test alone, for random
    windows (inner, at the grid's edges, empty, whole) and particles crowding their edges, turned frames, lamps
    off, inactive and non-finite particles, on every device."""
    from warp_lamp.distributed import _window_struct

    rng = np.random.default_rng(40 + ray)
    low, high = np.array([-1.0, 0.5, 0.0]), np.array([4.0, 3.0, 3.5])
    grid = LampGrid(low, high, (0.25, 0.3, 0.2))
    n = 4000
    counts = grid.counts
    origin, rotation = grid.pose_arrays(device, in_frame=True)
    params = grid.params(origin, rotation)
    exact_escapes = 0
    for trial in range(12):
        rect = np.zeros((3, 4), dtype=np.int64)
        for a in range(3):
            nu, nv = (int(x) for x in counts[a])
            kind = trial % 4
            if kind == 0:  # inner
                i0, j0 = rng.integers(1, nu // 2), rng.integers(1, nv // 2)
                rect[a] = (i0, rng.integers(1, nu - i0), j0, rng.integers(1, nv - j0))
            elif kind == 1:  # at the grid's edges
                rect[a] = (0, rng.integers(1, nu + 1), rng.integers(0, nv // 2), nv)
            elif kind == 2:  # whole grid, or one grid's window empty
                rect[a] = (0, nu, 0, nv) if a else (0, 0, 0, 0)
            else:
                rect[a] = (nu // 3, nu // 3, nv // 4, nv // 2)
        # Particles near the window's edges of grid 0: centres within a few cells of them, radii up to 2 cells.
        lo = grid.corner[0] + np.array([rect[0, 0], rect[0, 2]]) * grid.cell[0]
        hi = grid.corner[0] + np.array([rect[0, 0] + rect[0, 1], rect[0, 2] + rect[0, 3]]) * grid.cell[0]
        edge = np.where(rng.random((n, 2)) < 0.5, lo, hi)
        c = rng.uniform(low - 0.5, high + 0.5, (n, 3))
        c[: n // 2, 1:] = edge[: n // 2] + rng.normal(0.0, 0.3, (n // 2, 2))
        r = rng.uniform(0.01, 0.5, n)
        c[7] = np.nan
        r[9] = -1.0
        active = (rng.random(n) > 0.1).astype(np.int32)
        particles = lamp_kernels.LampParticles()
        particles.positions = wp.array(c.astype(np.float32), dtype=wp.vec3, device=device)
        particles.radii = wp.array(r.astype(np.float32), dtype=wp.float32, device=device)
        particles.active = wp.array(active, dtype=wp.int32, device=device)
        particles.n = n
        mask = 0b111111 if trial % 3 else 0b001111
        got = []
        for bounds in (params, None):  # the filter, then every particle through the exact test
            escapes = wp.zeros(1, dtype=wp.int32, device=device)
            wp.launch(
                dist_kernels.dist_escapes,
                dim=n,
                inputs=[params, _window_struct(rect, bounds), particles, ray, mask],
                outputs=[escapes],
                device=device,
            )
            got.append(int(escapes.numpy()[0]))
        assert got[0] == got[1], (trial, got)
        exact_escapes += got[1]
    assert exact_escapes > 100  # the edges were crowded: the filter had escapes to keep


def test_area_side_pass_across_ranks(monkeypatch):
    """The area criterion's side pass (the CUDA default) across 2 thread ranks on the CPU: every area case and
    split bitwise equal to one process, as the one-thread cell pass is."""
    from warp_lamp.estimators import AreaSplit

    monkeypatch.setattr(AreaSplit, "CELL_PASS", "sides")

    def area_cases(coll):
        return [r for r in distributed_cases.all_cases(coll, quick=True) if "area" in r["case"]]

    flat = [r for part in run_ranks(fake_nccl_collectives(2), area_cases) for r in part]
    assert len(flat) > 20
    assert not _failures(flat)


def test_window_scatter_reference(device):
    """dist_pack and dist_scatter_window against the scatter's reference: the window's shared cells decided by the
    reduced keys, its other cells by the rank's own key (no other rank reaches them), nothing outside it."""
    rng = np.random.default_rng(8)
    grid = LampGrid((0.0, 0.0, 0.0), (3.0, 2.0, 2.5), 0.25)
    cells = grid.n_cells
    n = 40
    gids = np.sort(rng.choice(1000, size=n, replace=False)).astype(np.int32)
    caller = rng.permutation(n).astype(np.int32)
    rect = np.array([[1, 6, 2, 5], [0, int(grid.counts[1, 0]), 3, 4], [2, 3, 0, int(grid.counts[2, 1])]])
    inside = np.zeros(cells, dtype=bool)
    offset = 0
    for a in range(3):
        nu, nv = (int(x) for x in grid.counts[a])
        box = np.zeros((nv, nu), dtype=bool)
        box[rect[a, 2] : rect[a, 2] + rect[a, 3], rect[a, 0] : rect[a, 0] + rect[a, 1]] = True
        inside[offset : offset + nu * nv] = box.reshape(-1)
        offset += nu * nv
    keys = ordered_key(rng.normal(size=2 * cells), rng.integers(0, n, 2 * cells))
    keys[rng.random(2 * cells) < 0.2] = EMPTY_KEY
    keys[np.repeat(~inside, 2)] = EMPTY_KEY  # the rank's keys are empty outside its window
    shared = np.flatnonzero(rng.random(cells) < 0.5).astype(np.int32)
    mine = global_keys_reference(keys, gids)
    # What the other ranks offer on the shared cells: some beat this rank, some not.
    others = mine.copy()
    beat = rng.random(2 * cells) < 0.4
    others[beat] = ordered_key(rng.normal(size=beat.sum()), rng.integers(1000, 2000, beat.sum()))
    reduced = np.where(np.repeat(inside, 2), mine, EMPTY_KEY)
    both = np.repeat(np.isin(np.arange(cells), shared), 2)
    reduced[both] = np.minimum(others[both], mine[both])
    axis = np.concatenate([np.full(int(grid.counts[a, 0] * grid.counts[a, 1]), a) for a in range(3)])
    want = scatter_reference(reduced, keys, gids, caller, axis, n)
    assert np.abs(want).sum() > 10
    origin, rotation = grid.pose_arrays(device, in_frame=True)
    params = grid.params(origin, rotation)
    keys_wp = wp.array(keys, dtype=wp.uint64, device=device)
    gids_wp = wp.array(gids, dtype=wp.int32, device=device)
    packed = wp.empty(2 * len(shared), dtype=wp.uint64, device=device)
    wp.launch(
        dist_kernels.dist_pack,
        dim=len(shared),
        inputs=[keys_wp, gids_wp, wp.array(shared, dtype=wp.int32, device=device), 0],
        outputs=[packed],
        device=device,
    )
    pairs = np.stack([2 * shared, 2 * shared + 1], axis=1).reshape(-1)
    assert np.array_equal(packed.numpy(), mine[pairs])
    # The all-reduce MIN with the other ranks' offers.
    packed = wp.array(np.minimum(packed.numpy(), others[pairs]), dtype=wp.uint64, device=device)
    slot_of = np.full(cells, -1, dtype=np.int32)
    slot_of[shared] = np.arange(len(shared))
    win = dist_kernels.ReachWindow()
    sizes = rect[:, 1] * rect[:, 3]
    win.i0, win.ni = wp.vec3i(*(int(x) for x in rect[:, 0])), wp.vec3i(*(int(x) for x in rect[:, 1]))
    win.j0, win.nj = wp.vec3i(*(int(x) for x in rect[:, 2])), wp.vec3i(*(int(x) for x in rect[:, 3]))
    win.first = wp.vec3i(0, int(sizes[0]), int(sizes[0] + sizes[1]))
    win.n_cells = int(sizes.sum())
    counts = wp.zeros(3 * n, dtype=wp.int64, device=device)
    wp.launch(
        dist_kernels.dist_scatter_window,
        dim=win.n_cells,
        inputs=[
            params,
            win,
            keys_wp,
            gids_wp,
            wp.array(caller, dtype=wp.int32, device=device),
            wp.array(slot_of, dtype=wp.int32, device=device),
            packed,
        ],
        outputs=[counts],
        device=device,
    )
    assert np.array_equal(counts.numpy().reshape(n, 3), want)


def test_unflip_restores_the_keys(device):
    """dist_unflip after keys flipped for an int64 reduction gives the unflipped keys back, EMPTY included."""
    rng = np.random.default_rng(11)
    keys = ordered_key(rng.normal(size=300).astype(np.float32), rng.integers(0, 40, 300))
    keys[::5] = EMPTY_KEY
    gids = rng.permutation(1000)[:40].astype(np.int32)
    out = wp.empty(len(keys), dtype=wp.uint64, device=device)
    k = wp.array(keys, dtype=wp.uint64, device=device)
    g = wp.array(gids, dtype=wp.int32, device=device)
    wp.launch(dist_kernels.dist_keys_to_global, dim=len(keys), inputs=[k, g, 1], outputs=[out], device=device)
    wp.launch(dist_kernels.dist_unflip, dim=len(keys), outputs=[out], device=device)
    assert np.array_equal(out.numpy(), global_keys_reference(keys, gids))


def test_scatter_walls_reference(device):
    """dist_scatter_walls against its reference: rays that a wall stops, blocks or lets through (as
    lamp_walled_owners decides them on the reduced keys), cells of this rank, of another rank and EMPTY, with a
    caller permutation: the rank's counts, and the walls' counts of the whole grid."""
    rng = np.random.default_rng(12)
    grid = LampGrid((0.0, 0.0, 0.0), (3.0, 2.0, 2.5), 0.25)
    cells = grid.n_cells
    n = 40
    gids = np.sort(rng.choice(1000, size=n, replace=False)).astype(np.int32)
    caller = rng.permutation(n).astype(np.int32)
    keys = ordered_key(rng.uniform(-1.0, 3.0, 2 * cells).astype(np.float32), rng.integers(0, n, 2 * cells))
    keys[rng.random(2 * cells) < 0.2] = EMPTY_KEY
    reduced = global_keys_reference(keys, gids)
    other = rng.random(2 * cells) < 0.4
    reduced[other] = ordered_key(rng.uniform(-1.0, 3.0, other.sum()), rng.integers(1000, 2000, other.sum()))
    reduced[rng.random(2 * cells) < 0.1] = EMPTY_KEY
    walls = [((0.0, 0.0, 1.0), (0.0, 0.0, 1.0)), ((2.2, 0.0, 0.0), (-1.0, 0.3, 0.2))]
    frame = LampFrame(grid, device, walls=check_walls(walls))
    frame.launch_walls(True)
    rays, view = frame.rays(True), frame.walls_view(True)
    red = wp.array(reduced, dtype=wp.uint64, device=device)
    walled = wp.zeros(2 * cells, dtype=wp.int32, device=device)
    recoils = wp.zeros(2 * cells, dtype=wp.int32, device=device)
    wp.launch(
        lamp_kernels.lamp_walled_owners,
        dim=cells,
        inputs=[rays, red, view, 63],
        outputs=[walled, recoils],
        device=device,
    )
    walled, recoils = walled.numpy(), recoils.numpy()
    mine = (reduced == global_keys_reference(keys, gids)) & (reduced != EMPTY_KEY)
    assert (walled <= -2).sum() > 20 and ((walled >= 0) & mine).sum() > 20 and ((walled == -1) & mine).sum() > 5
    axis = np.concatenate([np.full(int(grid.counts[a, 0] * grid.counts[a, 1]), a) for a in range(3)])
    want, want_walls = scatter_walls_reference(reduced, keys, gids, caller, axis, n, walled, len(walls), recoils)
    counts = wp.zeros(3 * n, dtype=wp.int64, device=device)
    wall_counts = wp.zeros(3 * len(walls), dtype=wp.int64, device=device)
    wp.launch(
        dist_kernels.dist_scatter_walls,
        dim=cells,
        inputs=[
            rays,
            wp.array(keys, dtype=wp.uint64, device=device),
            wp.array(gids, dtype=wp.int32, device=device),
            wp.array(caller, dtype=wp.int32, device=device),
            red,
            view,
            63,
        ],
        outputs=[counts, wall_counts],
        device=device,
    )
    assert np.array_equal(counts.numpy().reshape(n, 3), want)
    assert np.array_equal(wall_counts.numpy().reshape(-1, 3), want_walls)
    assert np.abs(want_walls).sum() > 0


def test_merge_rounds_reference(device):
    """D rounds of dist_merge_offer, a MIN over ranks and dist_merge_take give, per list, the D smallest distinct
    keys of the union of the ranks' lists (shared keys, EMPTY tails, lists all EMPTY), as the reference."""
    rng = np.random.default_rng(3)
    ranks, lists, d = 3, 200, 3
    pool = np.sort(rng.choice(1 << 40, size=(lists, 8), replace=False).astype(np.uint64), axis=1)
    per_rank = []
    for _ in range(ranks):
        take = np.sort(np.stack([rng.choice(8, size=d, replace=False) for _ in range(lists)]), axis=1)
        keys = np.take_along_axis(pool, take, axis=1)
        keep = rng.integers(0, d + 1, lists)
        keys[np.arange(d)[None, :] >= keep[:, None]] = EMPTY_KEY
        per_rank.append(keys)
    per_rank[0][:5] = EMPTY_KEY
    per_rank[1][:5] = EMPTY_KEY
    per_rank[2][:5] = EMPTY_KEY
    want = merge_lists_reference(per_rank)
    local = [wp.array(k.reshape(-1), dtype=wp.uint64, device=device) for k in per_rank]
    merged = wp.empty(lists * d, dtype=wp.uint64, device=device)
    offer = wp.empty(lists, dtype=wp.uint64, device=device)
    for k in range(d):
        offers = []
        for r in range(ranks):
            wp.launch(
                dist_kernels.dist_merge_offer, dim=lists, inputs=[local[r], merged, d, k, 0], outputs=[offer],
                device=device,
            )  # fmt: skip
            offers.append(offer.numpy().copy())  # a CPU array's numpy() is a view
        offer.assign(np.minimum.reduce(offers))
        wp.launch(dist_kernels.dist_merge_take, dim=lists, inputs=[offer, d, k, 0], outputs=[merged], device=device)
    assert np.array_equal(merged.numpy().reshape(lists, d), want)


@pytest.mark.parametrize("method", ["centroid", "polyhedron", "exact"])
def test_fixed_point_units_reference(device, method):
    """porosity_fixed against the float64 reference: each sphere-cell volume rounds to the same unit of 2^-40 of a
    cell, or one unit off where the two volumes straddle a rounding boundary; spheres half outside the box and
    straddling cell faces included."""
    rng = np.random.default_rng(5)
    c, r = polydisperse_scene(rng, n=60, extent=4.0, rmin=0.3, rmax=0.9)
    c[0] = (-0.5, 2.0, 2.0)
    c[1] = (1.0, 1.0, 1.0)
    h, shape = np.array([1.0, 0.8, 1.25]), (4, 5, 3)
    units, overflow = porosity_fixed_units(c, r, h, shape, method, device)
    want = fixed_units_reference(c, r, h, shape, method)
    assert int(overflow.numpy()[0]) == 0
    assert want.sum() > 1 << 40
    assert np.abs(units.numpy() - want).max() <= len(r)
    assert np.mean(units.numpy() == want) > 0.5


def test_fixed_point_overflow_is_refused():
    """A cell holding over 2^23 cell volumes of sphere overflows the int64 units: counted, and refused by name."""
    from warp_lamp.distributed import porosity_distributed

    centers = np.array([[0.5, 0.5, 0.5]])
    with pytest.raises(ValueError, match="radii: 1 sphere-cell volumes overflowed"):
        porosity_distributed(None, centers, [200.0], (0, 0, 0), (1, 1, 1), (1, 1, 1), method="centroid")


def test_porosity_checks_are_porositys():
    """porosity_distributed checks its box and options with porosity's own code: a bad method is named alike, and
    its budget counts the bitmaps that NCCL's OR by gathering holds (1 + ranks), refused on every rank."""
    from warp_lamp import porosity
    from warp_lamp.distributed import porosity_distributed

    c = np.array([[0.5, 0.5, 0.5]])
    for call in (porosity, lambda *a, **k: porosity_distributed(None, *a, **k)):
        with pytest.raises(ValueError, match=r"method: unknown 'voxels'; expected one of"):
            call(c, [0.2], (0, 0, 0), (1, 1, 1), (4, 4, 4), method="voxels")
    # 64^3 sub-cells: a 32 KiB bitmap; 100 KiB holds one (MPI) but not three (NCCL on 2 ranks).
    args = (c, [0.2], (0, 0, 0), (1, 1, 1), (8, 8, 8))
    porosity_distributed(None, *args, subdivisions=8, max_bytes=100_000)

    def run(coll):
        try:
            porosity_distributed(coll, *args, subdivisions=8, max_bytes=100_000)
        except (ValueError, RuntimeError) as e:
            return str(e)
        return None

    got = run_ranks(fake_nccl_collectives(2), run)
    assert all(m is not None and "3 bitmaps of 32,768 bytes" in m for m in got), got


def test_or_gathered(device):
    """dist_or_gathered is the bitwise OR of every rank's words."""
    rng = np.random.default_rng(6)
    words = rng.integers(0, 1 << 32, size=(4, 100), dtype=np.uint64).astype(np.uint32)
    bits = wp.empty(100, dtype=wp.uint32, device=device)
    gathered = wp.array(words.reshape(-1), dtype=wp.uint32, device=device)
    wp.launch(dist_kernels.dist_or_gathered, dim=100, inputs=[gathered, 4], outputs=[bits], device=device)
    assert np.array_equal(bits.numpy(), np.bitwise_or.reduce(words, axis=0))


def test_reduction_bytes():
    """Criteria 0 and 1 send the whole key array (16 bytes per cell) with follow, and only the cells ranks share
    with the reach (none on one rank); the area criterion its D-slot corner lists and 16 bytes per particle of the
    body; follow adds the box's 24 bytes; a bad reach is refused."""
    grid = LampGrid((0.0, 0.0, 0.0), (3.0, 2.0, 2.5), 0.5)
    lamp = DistributedLamp(grid, None, follow=True)
    lamp.set_ids(np.arange(10))
    assert lamp.reduction_bytes == 16 * grid.n_cells + 24
    # One rank shares no cell with another: with the reach, nothing is reduced.
    alone = DistributedLamp(grid, None, reach_margin=0)
    alone.set_ids(np.arange(3))
    alone.update(wp.array(np.full((3, 3), 1.0, np.float32), dtype=wp.vec3), wp.full(3, 0.4, dtype=wp.float32))
    assert alone.estimator.windowed and alone.reduction_bytes == 0
    assert 0 < alone.estimator.window_cells < grid.n_cells
    with pytest.raises(ValueError, match="reach: expected"):
        DistributedLamp(grid, None, reach="some")
    with pytest.raises(ValueError, match="reach_margin"):
        DistributedLamp(grid, None, reach_margin=-1)
    area = DistributedLamp(grid, None, criterion="area", depth_slots=2)
    area.set_ids(np.array([3, 90]))
    assert area.reduction_bytes == 2 * 2 * 8 * grid.n_samples + 16 * 91


def test_bad_ids_are_refused():
    """set_ids names the first bad index: negative, too large, repeated; update before set_ids and a particle count
    other than set_ids' are refused by name; the wetted surface is refused with its reason."""
    grid = LampGrid((0.0, 0.0, 0.0), (3.0, 2.0, 2.5), 0.5)
    lamp = DistributedLamp(grid, None, device="cpu")
    pos = wp.zeros(3, dtype=wp.vec3, device="cpu")
    rad = wp.full(3, 0.3, dtype=wp.float32, device="cpu")
    with pytest.raises(RuntimeError, match="set_ids"):
        lamp.update(pos, rad)
    with pytest.raises(ValueError, match=r"global_ids: must be in .*index 1 is -4"):
        lamp.set_ids([0, -4, 2])
    with pytest.raises(ValueError, match="index 2 is 2147483647"):
        lamp.set_ids([0, 5, 2**31 - 1])
    with pytest.raises(ValueError, match="global_ids: index 3 repeats id 7"):
        lamp.set_ids([7, 1, 2, 7])
    with pytest.raises(ValueError, match="global_ids: index 3 repeats id 7"):
        lamp.set_ids(wp.array([7, 1, 2, 7], dtype=wp.int32, device="cpu"))
    with pytest.raises(ValueError, match="global_ids: expected a 1-D array of integers"):
        lamp.set_ids([0.5, 1.0])
    lamp.set_ids([4, 1])
    with pytest.raises(ValueError, match="positions: 3 particles, but set_ids named 2"):
        lamp.update(pos, rad)
    with pytest.raises(ValueError, match=r"surfaces='all' .* is not distributed") as err:
        DistributedLamp(grid, None, surfaces="all")
    assert str(err.value) == WETTED_REFUSAL
    with pytest.raises(TypeError, match="comm: expected an mpi4py communicator"):
        as_collective(object())


def test_frames_and_area_walls_are_refused():
    """Frame averaging is refused by name with what to do instead; walls with the area criterion as ShiningLamp
    refuses them; a bad option is named as ShiningLamp names it (the options are checked by the same code)."""
    grid = LampGrid((0.0, 0.0, 0.0), (3.0, 2.0, 2.5), 0.5)
    with pytest.raises(ValueError) as err:
        DistributedLamp(grid, None, frames=4)
    assert str(err.value) == FRAMES_REFUSAL
    platen = [((0.0, 0.0, 0.5), (0.0, 0.0, 1.0))]
    with pytest.raises(ValueError, match="walls: only with criteria 0 and 1"):
        DistributedLamp(grid, None, criterion="area", walls=platen)
    with pytest.raises(ValueError, match="depth_slots: expected an integer in"):
        DistributedLamp(grid, None, criterion="area", depth_slots=9)


def test_distributed_lamp_is_the_pipeline(device):
    """DistributedLamp is a ShiningLamp whose frame and estimator are the distributed variants: apply, the
    float32 and exact forces, force factors, the resultant in diagnostics, and the wall forces are the lamp's own
    stages, equal on one rank to ShiningLamp's; add_forces before update and a reserve for other particles are
    refused by name."""
    from warp_lamp.distributed import AgreedFrame, DistributedAreaSplit, DistributedFirstHit

    rng = np.random.default_rng(13)
    c, r = polydisperse_scene(rng, n=200)
    grid = LampGrid.enclosing(c, r, cells_per_diameter=3)
    platen = [((0.0, 0.0, float(np.median(c[:, 2]))), (0.0, 0.0, 1.0))]
    pos = wp.array(c.astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(r.astype(np.float32), dtype=wp.float32, device=device)
    ref = ShiningLamp(grid, walls=platen, device=device)
    ref.update(pos, rad)
    lamp = DistributedLamp(grid, None, walls=platen, device=device)
    assert isinstance(lamp, ShiningLamp) and isinstance(lamp.frame, AgreedFrame)
    assert isinstance(lamp.estimator, DistributedFirstHit) and "rank 0 of 1" in repr(lamp)
    assert isinstance(DistributedLamp(grid, None, criterion="area").estimator, DistributedAreaSplit)
    lamp.set_ids(np.arange(len(r)))
    forces = wp.zeros(len(r), dtype=wp.vec3, device=device)
    with pytest.raises(RuntimeError, match=r"call DistributedLamp.update \(or apply\) first"):
        lamp.add_forces(forces, 1e5)
    with pytest.raises(ValueError, match="n: set_ids named 200 particles"):
        lamp.reserve(300)
    lamp.apply(pos, rad, forces, 1e5)
    want = wp.zeros(len(r), dtype=wp.vec3, device=device)
    ref.add_forces(want, 1e5)
    assert np.array_equal(forces.numpy(), want.numpy())
    assert np.array_equal(lamp.force_factors(1e5), ref.force_factors(1e5))
    assert np.array_equal(lamp.forces_numpy(1e5), ref.forces_numpy(1e5))
    assert np.array_equal(lamp.wall_forces_numpy(1e5), ref.wall_forces_numpy(1e5))
    assert np.abs(ref.wall_forces_numpy(1e5)).sum() > 0
    got = lamp.diagnostics(c, 1e5)
    want_diag = ref.diagnostics(c, 1e5)
    assert got.ranks == 1 and got.n_global == len(r) and got.reduction_bytes == 16 * grid.n_cells
    assert np.array_equal(got.lamp.force, want_diag.force) and np.array_equal(got.lamp.moment, want_diag.moment)
    assert np.array_equal(got.lamp.wall_forces, want_diag.wall_forces)


def test_ranks_refuse_together():
    """Ranks that disagree on the grid all raise (none is left waiting in a collective), and one rank's bad ids
    make every rank raise, the others naming the other rank."""
    colls = fake_nccl_collectives(2)
    grids = [LampGrid((0.0, 0.0, 0.0), (3.0, 2.0, 2.5), 0.5), LampGrid((0.0, 0.0, 0.0), (3.0, 2.0, 2.5), 0.25)]

    def build(coll):
        try:
            DistributedLamp(grids[coll.rank], coll)
        except ValueError as e:
            return str(e)
        return None

    assert all("grid: the ranks passed different grids" in m for m in run_ranks(colls, build))

    def bad_ids(coll):
        lamp = DistributedLamp(grids[0], coll)
        try:
            lamp.set_ids([1, 1] if coll.rank == 0 else [5])
        except (ValueError, RuntimeError) as e:
            return type(e).__name__ + ": " + str(e)
        return None

    got = run_ranks(colls, bad_ids)
    assert got[0].startswith("ValueError: global_ids: index 1 repeats id 1")
    assert got[1].startswith("RuntimeError: global_ids: 1 other rank(s) refused")

    def shared_id(coll):
        lamp = DistributedLamp(grids[0], coll)
        try:
            lamp.set_ids([0, 1])
        except ValueError as e:
            return str(e)
        return None

    assert all("some id is on two ranks" in m for m in run_ranks(colls, shared_id))


def test_torch_gloo_one_rank(tmp_path):
    """torch.distributed (Gloo, one rank) as the collective: its int64 path with the key flip, on every mode and
    porosity method (torch comes with the test extra)."""
    torch_dist = _torch_distributed()
    from warp_lamp.distributed import TorchCollective

    owned = not torch_dist.is_initialized()
    if owned:
        # A file store, not a TCP port: two test runs on one machine (CI jobs, parallel workers) must not collide.
        torch_dist.init_process_group("gloo", init_method=(tmp_path / "store").as_uri(), rank=0, world_size=1)
    try:
        results = distributed_cases.all_cases(TorchCollective(None, "cpu"), quick=True)
        assert not _failures(results)
    finally:
        if owned:
            torch_dist.destroy_process_group()


@pytest.mark.parametrize("ranks", [2, 3])
def test_torch_gloo_processes(tmp_path, ranks):
    """2 and 3 processes over torch.distributed's Gloo on the CPU (int64 keys through the top-bit flip): every mode,
    split (slabs, blocks, random, lopsided, an empty rank) and porosity method bitwise equal to one process, the
    reach's escapes counted (torch comes with the test extra)."""
    _torch_distributed()
    distributed_cases.lamp_cases(LocalCollective("cpu"), quick=True)  # compile once, before the ranks load
    out, store = tmp_path / "ranks.json", tmp_path / "store"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    script = str(ROOT / "tests" / "distributed_ranks.py")
    procs = [
        subprocess.Popen(
            [sys.executable, script, "--gloo", str(store), "--rank", str(k), "--size", str(ranks), "--json", str(out)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        for k in range(ranks)
    ]
    logs = [p.communicate(timeout=300)[0] for p in procs]
    assert all(p.returncode == 0 for p in procs), "\n".join(log[-2000:] for log in logs)
    summary = json.loads(out.read_text())
    assert summary["ranks"] == ranks and summary["ok"] and summary["failed"] == 0
    assert "Gloo" in summary["library"]
    names = " ".join(r["case"] for r in summary["per_rank"][0]["results"])
    for split in distributed_cases.SPLITS:
        assert f"/ {split}" in names
    for needle in ("area", "reach", "escapes counted", "porosity exact"):
        assert needle in names, needle


def test_one_rank_on_the_whole_body_equals_shining_lamp_on_every_device(device):
    """A rank holding every particle in shuffled rows gets ShiningLamp's counts in its rows, on every device."""
    rng = np.random.default_rng(9)
    c, r = polydisperse_scene(rng, n=300)
    grid = LampGrid.enclosing(c, r, cells_per_diameter=4)
    pos = wp.array(c.astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(r.astype(np.float32), dtype=wp.float32, device=device)
    ref = ShiningLamp(grid, device=device)
    ref.update(pos, rad)
    rows = rng.permutation(len(r))
    lamp = DistributedLamp(grid, None, device=device)
    lamp.set_ids(rows)
    lamp.update(
        wp.array(c[rows].astype(np.float32), dtype=wp.vec3, device=device),
        wp.array(r[rows].astype(np.float32), dtype=wp.float32, device=device),
    )
    assert np.array_equal(lamp.counts_numpy(), ref.counts_numpy()[rows])
