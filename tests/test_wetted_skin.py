"""The wetted surface's skin: decisions kept between updates, bitwise equal to a from-scratch update."""

import numpy as np
import pytest
import warp as wp

import warp_lamp as wl
from warp_lamp.reference.wetted import dry_certificate, witness_clearance
from warp_lamp.scenes import scene_cavity_block, scene_overlapping_polydisperse
from warp_lamp.wetted import WettedSurface, cross_list_capacity, exact_queue_capacity, skin_distance, unpack_bits

RHO = 0.35  # above the cavity block's window (0.25 at r = 0.45): its cavity is sealed
H = 0.25


def cavity_scene():
    """A 7^3 jittered block (r = 0.45, spacing 1) with a sealed cavity at its centre, on a 0.25 grid."""
    scene = scene_cavity_block(7, cavity_radius=1.2)
    lower = np.floor(scene.centers.min(axis=0) - 0.45 - RHO - 2 * H)
    upper = scene.centers.max(axis=0) + 0.45 + RHO + 2 * H
    return scene, wl.LampGrid(lower, upper, H)


def upload(c, r, grid, device, active=None):
    pos = wp.array(grid.to_frame(c).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(np.asarray(r, dtype=np.float32), dtype=wp.float32, device=device)
    act = None if active is None else wp.array(np.asarray(active, dtype=np.int32), device=device)
    return pos, rad, act


def state(surface):
    """What an update answers: fluid words, counts, hits, wall counts and the exact test's counters."""
    d = surface.diagnostics()
    return (
        surface.fluid.numpy().copy(),
        d.counts.copy(),
        d.hits.copy(),
        d.wall_counts.copy(),
        d.uncertain,
        d.rescued,
        d.thin,
    )


def assert_same(a, b, step):
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y, err_msg=f"step {step}")


def differs_within_skin(s, fresh, scene, grid, device, *, tries):
    """Random moves of every sphere within half of ``s.skin`` (no new reference) until the skinned surface's fluid
    differs from a from-scratch one's: whether a lie told to the skin shows."""
    rng = np.random.default_rng(11)
    for _ in range(tries):
        step = rng.uniform(-0.9, 0.9, scene.centers.shape) * 0.5 * s.skin / np.sqrt(3.0)
        moved, rad, _ = upload(scene.centers + step, scene.radii, grid, device)
        s.update(moved, rad)
        fresh.update(moved, rad)
        assert not s.diagnostics().skin_reset
        if not np.array_equal(s.fluid.numpy(), fresh.fluid.numpy()):
            return True
    return False


def dem_run(device, *, walls=None, steps=24, seed=3, jiggle=1.5e-3, packed=False):
    """A short DEM-like run: small jiggles, two far jumps, a shell sphere removed and one moved away (the sealed
    cavity opens); after every update the skinned surface equals a from-scratch one bitwise. Returns the kept
    counts per step."""
    scene, grid = cavity_scene()
    rng = np.random.default_rng(seed)
    c = scene.centers.copy()
    r = scene.radii
    active = np.ones(len(r), dtype=np.int32)
    centre = scene.cut["center"]
    # The shell between the cavity and the top face along z: removing it opens the cavity.
    above = np.flatnonzero((np.abs(c[:, 0] - centre[0]) < 0.5) & (np.abs(c[:, 1] - centre[1]) < 0.5) & (c[:, 2] > 0))
    above = above[np.argsort(c[above, 2])]
    above = above[c[above, 2] > centre[2] + 1.5]
    skinned = WettedSurface(grid, probe_radius=RHO, device=device, skin="auto", walls=walls)
    fresh = WettedSurface(grid, probe_radius=RHO, device=device, walls=walls)
    if packed:
        # CUDA's layout on any device: the exact tests queued (7 threads taking them in turn, as CUDA's threads
        # do), the crossings and thin chords listed one per thread (the crossings' owners kept by the skin there
        # too), 4 bits per classify thread.
        skinned._exact_queue(exact_queue_capacity(skinned.shape, None), 7)
        skinned._cross_list(cross_list_capacity(skinned._faces, None))
        skinned._thin_list(4096)
        skinned._bits = 4
    kept, witnessed, held, owned, resets, certified, opened = [], [], [], [], [], [], None
    for step in range(steps):
        if step in (6, 15):
            j = rng.integers(len(r))
            c[j] += rng.normal(scale=0.6, size=3)  # a jump of over a radius
        if step == 10:
            active[above[-1]] = 0  # the outermost shell sphere gone
        if step == 12:
            c[above[0]] += [0.0, 3.0, 0.0]  # the last one moved aside: the cavity is reachable
        c += rng.normal(scale=jiggle, size=c.shape)
        pos, rad, act = upload(c, r, grid, device, active)
        skinned.update(pos, rad, act)
        fresh.update(pos, rad, act)
        assert_same(state(skinned), state(fresh), step)
        kept.append(skinned.diagnostics().skin_kept)
        witnessed.append(skinned.diagnostics().skin_witnessed)
        held.append(skinned.diagnostics().skin_held)
        resets.append(skinned.diagnostics().skin_reset)
        certified.append(skinned.diagnostics().skin_certified)
        owned.append(skinned.diagnostics().skin_cross_kept)
        if step == 12:
            opened = skinned.diagnostics()
    fluid = opened.fluid
    ijk = np.floor(grid.to_frame(scene.cut["center"][None])[0] / H).astype(int)
    assert fluid[tuple(ijk)], "the cavity was opened"
    # Witnesses survive a new reference: every update after the first keeps wet decisions (unless the table is
    # wiped, which it is not in so short a run), except a new reference right after another, which runs as from
    # scratch (nothing re-checked, certified or measured).
    streak = [r and last for r, last in zip(resets[1:], resets[:-1], strict=True)]
    assert all(w > 0 for w, st in zip(witnessed[1:], streak, strict=True) if not st)
    assert all(w == 0 and c == 0 for w, c, st in zip(witnessed[1:], certified[1:], streak, strict=True) if st)
    # Most quiet steps hold most witnesses by their margins alone (none held at a new reference).
    assert max(held) > 0.5 * max(witnessed) and all(h <= w for h, w in zip(held, witnessed, strict=True))
    # Crossing owners are kept between references, and only without walls.
    assert (max(owned) > 0) == (walls is None)
    return kept


def test_skin_bitwise_over_a_dem_run(device):
    """Over jiggles, jumps and a pore opening, every update's fluid, counts and hits equal a from-scratch update's."""
    kept = dem_run(device)
    # Kept on the quiet steps (most of them), dropped where the reference was retaken.
    assert kept[0] == 0
    assert sum(k > 0 for k in kept) >= len(kept) // 2


def test_skin_bitwise_with_queued_tests(device):
    """The same run with the exact tests queued, the crossings listed and 4 bits per classify thread (CUDA's
    layout): still bitwise."""
    dem_run(device, steps=14, seed=5, packed=True)


def test_skin_bitwise_with_walls(device):
    """The same run with a floor through the block's lower layers and a side wall: still bitwise."""
    walls = [((0.0, 0.0, 1.2), (0.0, 0.0, 1.0)), ((6.4, 0.0, 0.0), (-1.0, 0.0, 0.0))]
    dem_run(device, walls=walls, steps=14, seed=4)


def test_skin_keeps_decisions(device):
    """At rest the second update keeps every certified voxel untested (a large share of the dry ones), nearly
    every wet one by its witness and most crossings' owners; a particle count change or a shift by one cell (a
    following grid) keeps no dry decision and no owner."""
    scene, grid = cavity_scene()
    s = WettedSurface(grid, probe_radius=RHO, device=device, skin="auto")
    pos, rad, _ = upload(scene.centers, scene.radii, grid, device)
    s.update(pos, rad)
    first = s.diagnostics()
    assert first.skin_reset and first.skin_kept == 0
    dry = first.uncertain - first.rescued
    # The lattice's interstitial holes are allowed pockets the probe cannot reach: the voxels near them are dry
    # without a certificate (28% certified here; 77% on the random SphereTest specimen).
    assert first.skin_certified > 0.2 * dry
    s.update(pos, rad)
    second = s.diagnostics()
    assert not second.skin_reset
    assert second.skin_kept == first.skin_certified
    assert second.skin_certified == 0
    assert first.skin_witnessed == 0 and second.skin_witnessed > 0.9 * first.rescued
    # At rest a witness is held by its margin unless some other ball comes within the skin of its candidate.
    assert first.skin_held == 0 and second.skin_held > 0.7 * second.skin_witnessed
    crossings = 2 * sum(int(c.sum()) for c in second.crossings.values())
    assert first.skin_cross_kept == 0 and second.skin_cross_kept > 0.5 * crossings
    shifted, rad, _ = upload(scene.centers + H, scene.radii, grid, device)
    s.update(shifted, rad)
    assert s.diagnostics().skin_kept == 0 and s.diagnostics().skin_reset and s.diagnostics().skin_cross_kept == 0
    c = np.vstack([scene.centers, [[100.0, 100.0, 100.0]]])
    more, rad, _ = upload(c, np.append(scene.radii, 0.45), grid, device)
    s.update(more, rad)
    assert s.diagnostics().skin_kept == 0 and s.diagnostics().skin_resets == 3


def test_skin_certificates_hold_geometrically(device):
    """Every certified voxel's rho-ball lies inside the union of balls of radius r + rho - skin: sampled points
    (and the voxel centre) checked by brute force in float64, independently of the kernels."""
    scene, grid = cavity_scene()
    s = WettedSurface(grid, probe_radius=RHO, device=device, skin="auto")
    pos, rad, _ = upload(scene.centers, scene.radii, grid, device)
    s.update(pos, rad)
    kept = unpack_bits(s.kept.numpy(), s.shape)
    ijk = np.argwhere(kept)
    assert len(ijk) > 100
    rng = np.random.default_rng(7)
    ijk = ijk[rng.choice(len(ijk), 150, replace=False)]
    x = (ijk + 0.5) * H
    c = pos.numpy().astype(np.float64)
    big = rad.numpy().astype(np.float64) + RHO - s.skin
    u = rng.normal(size=(len(x), 400, 3))
    u *= (RHO * rng.random((len(x), 400, 1)) ** (1 / 3)) / np.linalg.norm(u, axis=2, keepdims=True)
    pts = np.concatenate([x[:, None, :], x[:, None, :] + u], axis=1).reshape(-1, 3)
    covered = np.zeros(len(pts), dtype=bool)
    for k in range(len(c)):
        covered |= ((pts - c[k]) ** 2).sum(axis=1) < big[k] ** 2
    assert covered.all()


def test_skin_too_large_is_caught(device):
    """A skin that claims more than its certificates allow (certified with a tiny shrink, then trusted over larger
    moves) differs from a from-scratch update: the comparison above can fail."""
    scene, grid = cavity_scene()
    s = WettedSurface(grid, probe_radius=RHO, device=device, skin=1e-6)
    fresh = WettedSurface(grid, probe_radius=RHO, device=device)
    pos, rad, _ = upload(scene.centers, scene.radii, grid, device)
    s.update(pos, rad)
    s.skin = 0.25 * H  # the lie: moves up to half of this now count as within the certificates
    assert differs_within_skin(s, fresh, scene, grid, device, tries=4)


def test_skin_in_shining_lamp(device):
    """ShiningLamp keeps decisions by default (skin=True too; skin=False turns it off) with the same forces at every
    update."""
    scene, grid = cavity_scene()
    auto = wl.ShiningLamp(grid, surfaces="all", probe_radius=RHO, device=device)
    assert auto.estimator.surface.skin > 0.0
    on = wl.ShiningLamp(grid, surfaces="all", probe_radius=RHO, device=device, skin=True)
    off = wl.ShiningLamp(grid, surfaces="all", probe_radius=RHO, device=device, skin=False)
    assert on.estimator.surface.skin == pytest.approx(0.1 * H) and off.estimator.surface.skin == 0.0
    rng = np.random.default_rng(5)
    c = scene.centers.copy()
    for _ in range(3):
        c += rng.normal(scale=1e-4, size=c.shape)
        pos = wp.array(c.astype(np.float32), dtype=wp.vec3, device=device)
        rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
        for lamp in (on, off):
            lamp.update(pos, rad)
        np.testing.assert_array_equal(on.forces_numpy(1.0), off.forces_numpy(1.0))
    assert on.diagnostics().skin_kept > 0 and off.diagnostics().skin_kept == 0


def test_skin_argument_errors():
    """A bad skin is refused, naming the argument."""
    h = np.array([H] * 3)
    assert skin_distance(None, h, RHO) == 0.0
    assert skin_distance("auto", h, 0.0) == 0.0
    assert skin_distance("auto", h, RHO) == pytest.approx(0.1 * H)
    for bad in (-1.0, 0.0, 0.3 * H, float("nan"), "big"):
        with pytest.raises(ValueError, match="skin"):
            skin_distance(bad, h, RHO)
    with pytest.raises(ValueError, match="skin"):
        wl.ShiningLamp(wl.LampGrid([0] * 3, [1] * 3, 0.1), surfaces="all", probe_radius=0.1, skin="yes")


@pytest.mark.parametrize("scene_name", ["cavity", "polydisperse"])
def test_certificates_match_reference(device, scene_name):
    """The kernels certify exactly the dry-tested voxels that the float64 reference certifies (sampled: every
    certified voxel or not, on the cavity block and on strongly overlapping polydisperse spheres)."""
    if scene_name == "cavity":
        scene, grid = cavity_scene()
        rho = RHO
    else:
        scene = scene_overlapping_polydisperse(n=150, seed=2)
        rho = 0.5 * float(scene.radii.mean())
        grid = wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=4, probe_radius=rho)
    s = WettedSurface(grid, probe_radius=rho, device=device, skin="auto")
    pos, rad, _ = upload(scene.centers, scene.radii, grid, device)
    s.update(pos, rad)
    d = s.diagnostics()
    solid = unpack_bits(s.solid.numpy(), s.shape)
    dry_tested = d.band & ~d.fluid & ~solid
    kept = unpack_bits(s.kept.numpy(), s.shape)
    assert not (kept & ~dry_tested).any()
    rng = np.random.default_rng(1)
    yes, no = np.argwhere(kept), np.argwhere(dry_tested & ~kept)
    assert len(yes) > 20 and len(no) > 20
    sample = np.concatenate([yes[rng.choice(len(yes), 40, replace=False)], no[rng.choice(len(no), 40, replace=False)]])
    c = pos.numpy().astype(np.float64)
    r = rad.numpy().astype(np.float64)
    h = s.h
    for ijk in sample:
        x = (ijk + 0.5) * h
        assert dry_certificate(x, c, r, rho, s.skin) == bool(kept[tuple(ijk)]), tuple(ijk)


def voxel_of(v, shape):
    """Voxel (i, j, k) of a witness table key (word * 32 + bit; words along x, rows (j, k))."""
    nwx = -(-shape[0] // 32)
    word, bit = divmod(int(v), 32)
    row, w = divmod(word, nwx)
    k, j = divmod(row, shape[1])
    return np.array([32 * w + bit, j, k])


def test_witness_margins_match_reference(device):
    """Every stored witness margin equals a brute-force float64 clearance over all spheres (so the margin's walk
    misses no sphere), its candidate lies on its own inflated spheres within rho of the voxel, and its corner is a
    corner of the candidate's voxel-centre cube."""
    scene, grid = cavity_scene()
    s = WettedSurface(grid, probe_radius=RHO, device=device, skin="auto")
    pos, rad, _ = upload(scene.centers, scene.radii, grid, device)
    s.update(pos, rad)
    keys, wits, mg = s._wit_keys.numpy(), s._wits.numpy(), s._wit_margins.numpy()
    used = np.flatnonzero((keys >= 0) & (wits[:, 0] >= 0) & (mg["corner"] >= 0))
    assert len(used) > 0.8 * s.diagnostics().rescued
    c = pos.numpy().astype(np.float64)
    r = rad.numpy().astype(np.float64)
    h = np.asarray(s.h, dtype=np.float64)
    cap = 4.0 * s.skin
    rng = np.random.default_rng(2)
    for slot in rng.choice(used, 120, replace=False):
        own = [q for q in wits[slot, :3] if q >= 0]
        z = np.asarray(mg["z"][slot], dtype=np.float64)
        x = (voxel_of(keys[slot], s.shape) + 0.5) * h
        assert np.linalg.norm(x - z) <= RHO * (1 + 1e-9)
        for q in own:
            assert abs(np.linalg.norm(z - c[q]) - (r[q] + RHO)) < 1e-9
        lo = np.asarray(mg["lo"][slot])
        corner = int(mg["corner"][slot])
        np.testing.assert_array_equal(lo, np.floor(z / h - 0.5).astype(int))
        y = (lo + [(corner >> a) & 1 for a in range(3)] + 0.5) * h
        assert mg["epoch"][slot] == 1
        assert abs(mg["m"][slot] - witness_clearance(z, y, own, c, r, RHO, cap)) < 1e-9, slot


def test_witness_margin_lie_is_caught(device):
    """Margins that claim more clearance than measured, trusted over moves within the skin, make the skinned
    surface differ from a from-scratch one: the bitwise comparison can catch a wrong margin."""
    scene, grid = cavity_scene()
    s = WettedSurface(grid, probe_radius=RHO, device=device, skin="auto")
    fresh = WettedSurface(grid, probe_radius=RHO, device=device)
    pos, rad, _ = upload(scene.centers, scene.radii, grid, device)
    s.update(pos, rad)
    mg = s._wit_margins.numpy()
    mg["m"] = np.where(mg["corner"] >= 0, 1.0e3, mg["m"])  # the lie
    s._wit_margins.assign(mg)
    assert differs_within_skin(s, fresh, scene, grid, device, tries=6)


def test_forget_runs_the_next_update_cold(device):
    """After ``forget`` (benchmarks' cold start) the next update takes a new reference, keeps nothing and answers the
    same; the one after it keeps decisions again."""
    scene, grid = cavity_scene()
    lamp = wl.ShiningLamp(grid, surfaces="all", probe_radius=RHO, device=device)
    pos = wp.array(scene.centers.astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    lamp.update(pos, rad)
    first = lamp.forces_numpy(1.0)
    lamp.update(pos, rad)
    assert lamp.diagnostics().skin_held > 0
    lamp.forget()
    lamp.update(pos, rad)
    cold = lamp.diagnostics()
    assert cold.skin_reset and cold.skin_kept == 0 and cold.skin_witnessed == 0 and cold.skin_resets == 2
    np.testing.assert_array_equal(lamp.forces_numpy(1.0), first)
    lamp.update(pos, rad)
    assert lamp.diagnostics().skin_held > 0


def test_skin_bitwise_on_random_runs(device):
    """Random polydisperse and jittered-lattice bodies, probe radii from 0.1 to 0.8 diameters, a tilted wall in some,
    CUDA's queued layout in half: over random moves (drifts of 0.05 to 0.6 skins, jumps, spheres switched off and
    on, rests) every update equals a fresh one, and the skin's margins, certificates and owners are all used."""
    rng = np.random.default_rng(17)
    used = np.zeros(3, dtype=np.int64)
    for run in range(12):
        if run % 2:
            m = int(rng.integers(3, 5))
            c = np.stack(np.meshgrid(*[np.arange(m)] * 3, indexing="ij"), -1).reshape(-1, 3).astype(float)
            c += rng.uniform(-1, 1, c.shape) * 10.0 ** rng.uniform(-5, -1)
            r = np.full(len(c), 0.5)
        else:
            c = rng.uniform(0, 3, (int(rng.integers(30, 90)), 3))
            r = rng.uniform(0.25, 0.55, len(c))
        rho = float(rng.choice([0.1, 0.3, 0.5, 0.8]) * 2 * r.mean())
        grid = wl.LampGrid(c.min(0) - r.max() - 0.6, c.max(0) + r.max() + 0.6, rng.uniform(0.14, 0.26))
        walls = [(tuple(c.mean(0) + rng.uniform(-1, 1, 3)), tuple(rng.normal(size=3)))] if run % 3 == 2 else None
        skinned = WettedSurface(grid, probe_radius=rho, device=device, walls=walls, skin="auto")
        fresh = WettedSurface(grid, probe_radius=rho, device=device, walls=walls)
        if run % 4 >= 2:
            skinned._exact_queue(exact_queue_capacity(skinned.shape, None), 5)
            skinned._bits = 4
        active = np.ones(len(r), dtype=np.int32)
        for step in range(8):
            move = rng.integers(4) if step else 3
            if move == 0:
                c = c + rng.uniform(-1, 1, c.shape) * rng.uniform(0.05, 0.6) * skinned.skin / np.sqrt(3.0)
            elif move == 1:
                c[rng.integers(len(r))] += rng.normal(scale=r.mean(), size=3)
            elif move == 2:
                active[rng.integers(len(r))] ^= 1
            pos, rad, act = upload(c, r, grid, device, active)
            skinned.update(pos, rad, act)
            fresh.update(pos, rad, act)
            assert_same(state(skinned), state(fresh), (run, step))
            d = skinned.diagnostics()
            used += [d.skin_kept, d.skin_held, d.skin_cross_kept]
    assert (used > 0).all(), used
