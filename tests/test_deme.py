"""The DEM-Engine (DEME) adapter: clump layouts, the owner kernels against their float64 references, the adapter on a
CPU stand-in for DEME's solver and tracker (both transfer paths), its errors, and inside real DEME where there is a
CUDA device and ``deme`` (``pip install -e ".[deme]"``)."""

from pathlib import Path

import numpy as np
import pytest
import warp as wp
from deme_standin import StandInSolver, StandInTracker

import warp_lamp as wl
from warp_lamp.engines import DemeClumps, DemeLamp, EngineLamp, deme_unavailable, load_deme
from warp_lamp.engines import deme as deme_module
from warp_lamp.kernels import owners as owner_kernels
from warp_lamp.reference.owners import owner_loads_reference, quaternion_matrices, sphere_centers_reference
from warp_lamp.scenes import scene_lattice_ball, scene_sphere_specimen

P = 1.0e6


def _random_quats(rng, k):
    q = rng.normal(size=(k, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _three_sphere_template(r=1e-3):
    offsets = np.array([[-1.2 * r, 0.0, 0.0], [0.0, 0.0, 0.0], [1.2 * r, 0.3 * r, 0.0]])
    return np.array([r, 0.8 * r, r]), offsets - offsets.mean(axis=0)


def _clump_body(rng, n_side=5):
    """A block of three-sphere clumps, randomly turned: (clumps, owner positions, quaternions)."""
    tpl = [_three_sphere_template(), (np.array([1e-3]), np.zeros((1, 3)))]
    axis = np.arange(n_side) * 4.5e-3
    pos = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    types = rng.integers(0, 2, len(pos))
    return DemeClumps.from_templates(tpl, types), pos, _random_quats(rng, len(pos))


# --- layouts and kernels -------------------------------------------------------------------------------------------


def test_clumps_layout_from_templates():
    """from_templates lists each owner's template spheres in tracker order, with the owner starts and offsets."""
    r3, d3 = _three_sphere_template()
    c = DemeClumps.from_templates([(r3, d3), ([2e-3], [[0, 0, 0]])], [1, 0, 1])
    assert c.owners == 3 and not c.single
    assert c.owner.tolist() == [0, 1, 1, 1, 2]
    assert c.start.tolist() == [0, 1, 4, 5]
    assert np.array_equal(c.radii, [2e-3, *r3, 2e-3])
    assert np.array_equal(c.offsets[1:4], d3)
    assert DemeClumps([1e-3, 2e-3]).single


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"radii": [1e-3, -1.0]}, r"radii\[1\]"),
        ({"radii": []}, "radii: expected shape"),
        ({"radii": [1e-3] * 3, "owner": [0, 2, 2]}, r"owner\[1\] = 2 follows 0"),
        ({"radii": [1e-3] * 3, "owner": [0, 1, 0]}, r"owner\[2\] = 0 follows 1"),
        ({"radii": [1e-3] * 3, "owner": [1, 1, 2]}, "owner 0"),
        ({"radii": [1e-3] * 3, "owner": [0.0, 1.0, 2.0]}, "owner: expected 3 integers"),
        ({"radii": [1e-3] * 2, "offsets": np.zeros((3, 3))}, r"offsets: expected shape \(2, 3\)"),
        ({"radii": [1e-3] * 2, "offsets": [[0, 0, 0], [np.nan, 0, 0]]}, r"offsets\[1\]"),
    ],
)
def test_clumps_refuse_bad_layouts(kwargs, message):
    """Bad radii, owners out of order or left out, and bad offsets are refused, naming the argument and index."""
    with pytest.raises(ValueError, match=message):
        DemeClumps(**kwargs)


def test_clumps_refuse_bad_templates():
    """Template indices out of range and templates whose offsets do not match their radii are refused."""
    tpl = [_three_sphere_template()]
    with pytest.raises(ValueError, match=r"types\[1\] = 1"):
        DemeClumps.from_templates(tpl, [0, 1])
    with pytest.raises(ValueError, match=r"templates\[0\]"):
        DemeClumps.from_templates([([1e-3, 1e-3], [[0, 0, 0]])], [0])


def test_owner_kernels_match_reference(device, rng):
    """The sphere-centre and owner-load kernels equal their float64 references to float32 rounding, random clumps."""
    clumps, pos, quats = _clump_body(rng)
    k, s = clumps.owners, len(clumps.radii)
    force = rng.normal(size=(s, 3))
    mass = rng.uniform(0.5, 2.0, k)
    moi = rng.uniform(0.5, 2.0, (k, 3)) * 1e-6
    arr = lambda a, t: wp.array(np.asarray(a, dtype=np.float32), dtype=t, device=device)  # noqa: E731
    centers = wp.zeros(s, dtype=wp.vec3, device=device)
    ref_shift = np.array([1e-3, -2e-3, 0.5e-3])
    wp.launch(
        owner_kernels.sphere_centers_from_owners,
        dim=s,
        inputs=[arr(pos, wp.vec3), arr(quats, wp.quat), wp.array(clumps.owner, dtype=wp.int32, device=device),
                arr(clumps.offsets, wp.vec3), wp.vec3(*ref_shift), 1],
        outputs=[centers],
        device=device,
    )  # fmt: skip
    expected = sphere_centers_reference(pos, quats, clumps.owner, clumps.offsets) - ref_shift
    assert np.allclose(centers.numpy(), expected, rtol=0, atol=1e-8)
    acc = wp.zeros(k, dtype=wp.vec3, device=device)
    ang = wp.zeros(k, dtype=wp.vec3, device=device)
    wp.launch(
        owner_kernels.owner_accelerations,
        dim=k,
        inputs=[arr(force, wp.vec3), arr(clumps.offsets, wp.vec3), wp.array(clumps.start, dtype=wp.int32,
                device=device), arr(quats, wp.quat), arr(mass, wp.float32), arr(moi, wp.vec3), 1],
        outputs=[acc, ang],
        device=device,
    )  # fmt: skip
    ref_acc, ref_ang = owner_loads_reference(force, clumps.offsets, clumps.owner, quats, mass, moi)
    assert np.allclose(acc.numpy(), ref_acc, rtol=1e-5, atol=1e-6 * np.abs(ref_acc).max())
    assert np.allclose(ang.numpy(), ref_ang, rtol=1e-4, atol=1e-5 * np.abs(ref_ang).max())


def test_host_loads_match_reference(rng):
    """DemeClumps.centers and .loads (the CPU path, quaternion formula) equal the rotation-matrix references."""
    clumps, pos, quats = _clump_body(rng)
    s = len(clumps.radii)
    force = rng.normal(size=(s, 3))
    mass = rng.uniform(0.5, 2.0, clumps.owners)
    moi = rng.uniform(0.5, 2.0, (clumps.owners, 3))
    assert np.allclose(clumps.centers(pos, quats), sphere_centers_reference(pos, quats, clumps.owner, clumps.offsets))
    acc, ang = clumps.loads(force, quats, mass, moi)
    ref_acc, ref_ang = owner_loads_reference(force, clumps.offsets, clumps.owner, quats, mass, moi)
    assert np.allclose(acc, ref_acc, rtol=1e-12, atol=1e-12) and np.allclose(ang, ref_ang, rtol=1e-10, atol=1e-12)


def test_quaternion_reference_is_a_rotation(rng):
    """The reference's matrices are proper rotations and turn x by a quarter turn about z into y."""
    rot = quaternion_matrices(_random_quats(rng, 20))
    assert np.allclose(rot @ rot.transpose(0, 2, 1), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(rot), 1.0)
    quarter = quaternion_matrices([[0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)]])[0]
    assert np.allclose(quarter @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)


# --- the adapter on the stand-in -----------------------------------------------------------------------------------


def _spheres(n_mass=None):
    s = scene_lattice_ball(diameter=0.03, particle_diameter=0.005)
    mass = np.full(s.n, 2.0) if n_mass is None else n_mass
    tracker = StandInTracker(s.centers, masses=mass)
    return s, tracker, StandInSolver(tracker)


@pytest.mark.parametrize("transfer", ["host", "device"])
def test_one_sphere_owners_take_lamp_forces_over_mass(transfer):
    """One-sphere clumps: each owner's acceleration is lamp_forces (on the adapter's grid, at DEME's float32
    positions) over its mass; device and host paths read the positions and write to the right owners."""
    s, tracker, solver = _spheres(np.linspace(1.0, 3.0, scene_lattice_ball(diameter=0.03).n))
    lamp = DemeLamp(solver, tracker, P, radii=s.radii, transfer=transfer, device="cpu")
    lamp.update()
    x32 = s.centers.astype(np.float32).astype(np.float64)
    f = wl.lamp_forces(x32, s.radii, P, grid=lamp.core.grid, device="cpu")
    acc, ang = lamp.accelerations()
    assert ang is None
    assert np.abs(f).max() > 0
    assert np.allclose(acc, f / tracker.mass[:, None], rtol=1e-6, atol=1e-6 * np.abs(f).max())
    lamp.apply()
    assert np.allclose(tracker.acc, acc, rtol=1e-6, atol=1e-9)
    read = "PositionsToDevice" if transfer == "device" else "Positions"
    assert tracker.calls[read] >= 1 and "OrientationQuaternionsToDevice" not in tracker.calls


def test_device_and_host_paths_agree_on_clumps(rng):
    """Clumps of several spheres: both paths give each clump the sum of its spheres' lamp forces over its mass and
    their moment about its centre as an angular acceleration (the reference's), with the forces of the lamp."""
    clumps, pos, quats = _clump_body(rng)
    k = clumps.owners
    mass = rng.uniform(1.0, 2.0, k)
    moi = rng.uniform(1.0, 2.0, (k, 3)) * 1e-7
    out = {}
    for transfer in ("host", "device"):
        tracker = StandInTracker(pos, quats=quats, masses=mass, mois=moi)
        lamp = DemeLamp(StandInSolver(tracker), tracker, P, clumps=clumps, transfer=transfer, device="cpu")
        lamp.update()
        lamp.apply()
        out[transfer] = (lamp.forces(), tracker.acc.copy(), tracker.ang_acc.copy())
    f_host, acc_host, ang_host = out["host"]
    f_dev, acc_dev, ang_dev = out["device"]
    x = clumps.centers(pos.astype(np.float32), quats.astype(np.float32))
    lamp_f = EngineLamp(x, clumps.radii, P, grid=lamp.core.grid).forces(x)
    assert np.allclose(f_host, lamp_f, rtol=1e-6, atol=1e-6 * np.abs(lamp_f).max())
    assert np.allclose(f_dev, f_host, rtol=1e-5, atol=1e-5 * np.abs(f_host).max())
    ref_acc, ref_ang = owner_loads_reference(f_host, clumps.offsets, clumps.owner, quats, mass, moi)
    scale_a, scale_w = np.abs(ref_acc).max(), np.abs(ref_ang).max()
    assert scale_a > 0 and scale_w > 0
    for acc, ang in ((acc_host, ang_host), (acc_dev, ang_dev)):
        assert np.allclose(acc, ref_acc, rtol=1e-4, atol=1e-5 * scale_a)
        assert np.allclose(ang, ref_ang, rtol=1e-3, atol=1e-4 * scale_w)
    sums = np.add.reduceat(f_host, clumps.start[:-1], axis=0)
    assert np.allclose(acc_host * mass[:, None], sums, rtol=1e-5, atol=1e-6 * np.abs(sums).max())


def test_clumps_without_torques():
    """torques=False queues no angular acceleration and keeps the clump sums."""
    rng = np.random.default_rng(2)
    clumps, pos, quats = _clump_body(rng, 3)
    tracker = StandInTracker(pos, quats=quats)
    lamp = DemeLamp(StandInSolver(tracker), tracker, P, clumps=clumps, torques=False, device="cpu", transfer="device")
    lamp.update()
    lamp.apply()
    assert tracker.ang_acc is None and "AddAngAccFromDevice" not in tracker.calls
    assert np.allclose(tracker.acc, np.add.reduceat(lamp.forces(), clumps.start[:-1], axis=0), rtol=1e-5, atol=1e-3)


def test_step_runs_the_lamp_every_n_and_queues_every_step():
    """step(): the lamp runs every `every` steps over all calls; its last load is queued before every DEME step."""
    s, tracker, solver = _spheres()
    lamp = DemeLamp(solver, tracker, P, radii=s.radii, every=3, device="cpu", transfer="device")
    lamp.step(4)
    lamp.step(3)
    assert lamp.calls == 3 and lamp.steps == 7  # updates at steps 0, 3, 6
    assert len(solver.applied) == 7 and all(a is not None for a in solver.applied)
    assert tracker.calls["AddAccFromDevice"] == 7 and tracker.calls["PositionsToDevice"] == 3
    assert np.array_equal(solver.applied[0], solver.applied[2]) and np.abs(solver.applied[0]).max() > 0
    cost = lamp.cost()
    assert set(cost) >= {"wall", "cpu", "apply", "step", "calls"} and cost["step"] >= 0


@pytest.mark.parametrize(
    "options",
    [
        {"surfaces": "all", "probe_radius": 2.5e-3},
        {"criterion": "area"},
        {"walls": [((0.0, 0.0, -0.012), (0.0, 0.0, 1.0))]},
        {"follow": True},
    ],
)
def test_modes_pass_through(options):
    """Lamp modes (wetted, area, walls, follow) pass through: the device path's forces equal EngineLamp's."""
    s, tracker, solver = _spheres()
    lamp = DemeLamp(solver, tracker, P, radii=s.radii, device="cpu", transfer="device", **options)
    lamp.update()
    x32 = s.centers.astype(np.float32).astype(np.float64)
    ref = EngineLamp(x32, s.radii, P, **options).forces(x32)  # the same fit as the adapter's
    assert ref.shape == (s.n, 3)
    f = lamp.forces()
    assert np.abs(ref).max() > 0
    assert np.allclose(f, ref, rtol=1e-5, atol=1e-5 * np.abs(ref).max())


def test_adapter_errors():
    """Bad arguments are refused, naming them: radii and clumps, owner counts, every, transfer, masses, order."""
    s, tracker, solver = _spheres()
    with pytest.raises(ValueError, match="radii, clumps: give one"):
        DemeLamp(solver, tracker, P)
    with pytest.raises(ValueError, match="radii, clumps: give one"):
        DemeLamp(solver, tracker, P, radii=s.radii, clumps=DemeClumps(s.radii))
    with pytest.raises(ValueError, match=f"radii: describes {s.n - 1} owners, the tracker follows {s.n}"):
        DemeLamp(solver, tracker, P, radii=s.radii[:-1], device="cpu")
    with pytest.raises(ValueError, match="every"):
        DemeLamp(solver, tracker, P, radii=s.radii, every=0, device="cpu")
    with pytest.raises(ValueError, match="transfer"):
        DemeLamp(solver, tracker, P, radii=s.radii, transfer="gpu", device="cpu")
    with pytest.raises(TypeError, match="clumps: expected DemeClumps"):
        DemeLamp(solver, tracker, P, clumps=s.radii, device="cpu")
    bad = StandInTracker(s.centers, masses=np.where(np.arange(s.n) == 4, 0.0, 1.0))
    with pytest.raises(ValueError, match="tracked owner 4"):
        DemeLamp(StandInSolver(bad), bad, P, radii=s.radii, device="cpu")
    lamp = DemeLamp(solver, tracker, P, radii=s.radii, device="cpu")
    with pytest.raises(RuntimeError, match="apply: no load yet"):
        lamp.apply()


def test_real_deme_device_path_needs_cuda(monkeypatch):
    """A real DEME tracker with a lamp on the CPU is refused for the device path (DEME takes CUDA memory only)."""
    s, tracker, solver = _spheres()
    monkeypatch.setattr(StandInTracker, "__module__", "deme._deme")
    with pytest.raises(ValueError, match="transfer: DEME's device calls need the lamp on a CUDA device"):
        DemeLamp(solver, tracker, P, radii=s.radii, device="cpu", transfer="device")


def test_load_deme_errors(monkeypatch):
    """load_deme names the extra where deme is missing and says DEME needs a GPU where CUDA is absent."""
    real = deme_module.importlib.util.find_spec
    monkeypatch.setattr(deme_module.importlib.util, "find_spec", lambda name: None if name == "deme" else real(name))
    with pytest.raises(ImportError, match=r"warp-lamp\[deme\]"):
        load_deme()
    assert "not installed" in deme_unavailable()
    monkeypatch.setattr(deme_module.importlib.util, "find_spec", lambda name: object())
    monkeypatch.setattr(deme_module.wp, "is_cuda_available", lambda: False)
    with pytest.raises(RuntimeError, match="NVIDIA GPUs only"):
        load_deme()
    assert "no CUDA device" in deme_unavailable()


# --- inside DEME ---------------------------------------------------------------------------------------------------


@pytest.mark.skipif(deme_unavailable() is not None, reason=str(deme_unavailable()))
def test_inside_deme():
    """Inside DEME (GPU): the adapter reads DEME's positions on the device, and its queued load moves each owner by
    a = F / m for one step (gravity off, spheres apart: no contacts). Built as the SphereTest example builds its
    solver, so that DEME's compiled kernels are reused."""
    from helpers import load_example

    example = load_example("deme_sphere_test")
    deme = load_deme()
    # The SphereTest's box and templates (one of its radii here, all of them loaded): DEME compiles both into its
    # kernels, so this solver reuses the example's compiled kernels.
    specimen = scene_sphere_specimen()
    r = float(specimen.radii.max())
    axis = np.arange(4) * 3.0 * r
    xyz = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    radii = np.full(len(xyz), r)
    dt = 0.1 * example.rayleigh_step(float(specimen.radii.min()))
    solver, tracker, _ = example.build(deme, xyz, radii, dt=dt, template_radii=specimen.radii)
    lamp = DemeLamp(solver, tracker, 1e4, radii=radii)
    assert lamp.transfer == "device"
    lamp.update()
    assert np.allclose(lamp._pos.numpy(), np.asarray(tracker.Positions()), rtol=0, atol=1e-7)
    acc, _ = lamp.accelerations()
    lamp.step(1)
    vel = np.asarray(tracker.Velocities(), dtype=np.float64)
    assert np.abs(acc).max() > 0
    assert np.allclose(vel, acc * dt, rtol=1e-3, atol=1e-3 * np.abs(acc).max() * dt)


def test_add_deme_spheres_and_the_example_on_the_stand_in():
    """add_deme_spheres loads one template per distinct radius with its mass; the SphereTest example runs its whole
    loop on the stand-in (lamp steps, contacts, stress, report), so its DEME calls are the ones the stand-in knows."""
    from deme_standin import StandInDeme
    from helpers import load_example

    s = scene_lattice_ball(diameter=0.03, particle_diameter=0.005)
    radii = np.round(s.radii, 4)  # a few distinct radii
    solver = StandInDeme.DEMSolver(1)
    _, tracker = deme_module.add_deme_spheres(solver, s.centers, radii, {"E": 1.0}, density=1000.0)
    assert len(solver.templates) == len(np.unique(radii))
    assert np.allclose(tracker.mass, 1000.0 * 4.0 / 3.0 * np.pi * radii**3)
    assert np.allclose(tracker.pos, s.centers)
    with pytest.raises(ValueError, match="density"):
        deme_module.add_deme_spheres(solver, s.centers, radii, {}, density=0.0)
    extra = np.array([1e-3, radii[0], 4e-3])  # a superset: DEME's kernels compiled for another body's templates
    solver = StandInDeme.DEMSolver(1)
    _, tracker = deme_module.add_deme_spheres(solver, s.centers, radii, {}, density=1000.0, template_radii=extra)
    assert [t[1] for t in solver.templates] == np.unique(np.concatenate([radii, extra])).tolist()
    assert np.allclose(tracker.mass, 1000.0 * 4.0 / 3.0 * np.pi * radii**3)  # each sphere its own radius's template
    example = load_example("deme_sphere_test")
    scene = scene_lattice_ball(diameter=0.03, particle_diameter=0.005)
    scene.centers *= 0.97  # touching: contacts for the stress
    lines = []
    result = example.run(StandInDeme, scene, every=2, steps=6, check=3, device="cpu", log=lines.append)
    assert result["steps"] == 6 and len(result["history"]) == 2 and result["contacts"] > 0
    assert result["deme_force_on"] == "A" and result["mean_over_P"] > 0
    assert result["cost_s"]["calls"] == 3 and "step" in result["cost_s"]
    assert "| DEME stand-in |" in example.report(result) and "spheres, Initialize" in lines[0]


def test_stand_in_speaks_deme_3_0_19():
    """Every DEME method the stand-in implements, and so every one the adapter and example call, is in deme
    3.0.19's bindings."""
    from deme_standin import CONTACT_NAMES, SOLVER_NAMES, TRACKER_NAMES, StandInContacts

    for cls, names in (
        (StandInTracker, TRACKER_NAMES),
        (StandInSolver, SOLVER_NAMES),
        (StandInContacts, CONTACT_NAMES),
    ):
        own = {n for n in vars(cls) if n[:1].isupper()}
        assert own and own <= names, own - names
    with pytest.raises(AttributeError):
        StandInSolver().SetTimestepSize(1e-6)  # a misspelling the real binding lacks


def test_share_bench_on_the_stand_in_and_its_engines_row(tmp_path):
    """bench/deme_share.py runs all its stages on the stand-in (the child process too) and writes one JSON with the
    SphereTest and a share row per size and mode; `bench engines` reads and prints that file's numbers."""
    import importlib.util

    from warp_lamp.bench import engines as bench_engines

    # The repository's bench/, beside tests/ (warp_lamp may be installed elsewhere, as CI installs it).
    spec = importlib.util.spec_from_file_location(
        "deme_share", Path(__file__).resolve().parents[1] / "bench/deme_share.py"
    )
    share = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(share)
    out = tmp_path / "x-2026-11-28-deme.json"
    args = ["--standin", "--json", str(out), "--big", "300", "--steps", "4", "--settle", "10", "--cap", "1"]
    assert share.main(args) == 0
    result = bench_engines.deme_section(path=out, run=False)
    assert result["stages"]["share_big"] > 0  # the child process ran and its rows came back
    rows = result["share"]
    assert [(r["mode"], r["n"] > 100) for r in rows] == [
        ("first-hit", False), ("wetted", False), ("first-hit", True), ("wetted", True)
    ]  # fmt: skip
    for r in rows:
        assert 0 < r["share_every_10"] < r["share_every_1"] < 1 and r["updates"] >= 3
    text = bench_engines.format_deme(result)
    assert "| DEME stand-in |" in text and f"| {rows[2]['n']:,} | wetted" in text
    assert "skipped" in bench_engines.format_deme({"skipped": "x"})
