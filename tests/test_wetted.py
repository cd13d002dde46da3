"""Wetted-surface mode: kernels against the float64 reference, the issue's cut blocks, limits and hard cases."""

import numpy as np
import pytest
import warp as wp
from helpers import DEVICES
from wetted_brute import brute_counts, brute_fluid

import warp_lamp as wl
from warp_lamp.bench.wetted import lone_sphere_convergence
from warp_lamp.kernels.walls import LampWalls
from warp_lamp.lamp import pressure_area
from warp_lamp.reference.wetted import dilation_table as reference_table
from warp_lamp.reference.wetted import wetted_reference
from warp_lamp.scenes import (
    scene_cavity_block,
    scene_overlapping_polydisperse,
    scene_slot_block,
    scene_tunnel_block,
)
from warp_lamp.validate import check_particles
from warp_lamp.wetted import (
    BYTES_PER_PARTICLE,
    CUDA_BYTES_PER_PARTICLE,
    WettedSurface,
    attribution_bound,
    dilation_table,
    voxel_box,
    voxel_diagonal,
    wetted_nbytes,
)


def wetted_solve(
    centers, radii, *, probe_radius, grid=None, cells_per_diameter=4, lamps="all", active=None, device=None, **kw
):
    """The engine on host data (as ShiningLamp drives it, with its options for tests: keep_owners, max_rounds)."""
    c, r = check_particles(centers, radii)
    if grid is None:
        grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=cells_per_diameter, probe_radius=probe_radius)
    surface = WettedSurface(grid, probe_radius=probe_radius, lamps=lamps, device=device, **kw)
    d = surface.device
    act = None if active is None else wp.array((np.asarray(active) != 0).astype(np.int32), device=d)
    pos = wp.array(grid.to_frame(c).astype(np.float32), dtype=wp.vec3, device=d)
    surface.update(pos, wp.array(r.astype(np.float32), device=d), act)
    return surface


def wetted_forces(centers, radii, pressure, *, probe_radius, **kw):
    """The public path: lamp_forces with surfaces='all'."""
    return wl.lamp_forces(centers, radii, pressure, surfaces="all", probe_radius=probe_radius, **kw)


P = 1.0e6


def exact_scene(rng, n=150, extent=5.0, rmin=0.2, rmax=0.6, *, h=0.2, margin=1.5):
    """Centres whose frame coordinates and radii float32 holds exactly, and a grid with a dyadic origin: the
    kernels then see the reference's inputs bit for bit."""
    lower = -margin
    frame = rng.uniform(margin, margin + extent, (n, 3)).astype(np.float32).astype(np.float64)
    radii = rng.uniform(rmin, rmax, n).astype(np.float32).astype(np.float64)
    grid = wl.LampGrid([lower] * 3, [extent + margin] * 3, h)
    return lower + frame, radii, grid


def assert_matches(surface, ref, *, lamps_mask=0b111111):
    """Every crossing's owner (sphere or wall), the thin chords per face, the maps and the counts (particles' and
    walls') equal the reference's."""
    d = surface.diagnostics()
    np.testing.assert_array_equal(d.allowed, ref.allowed)
    np.testing.assert_array_equal(d.reachable, ref.reachable)
    np.testing.assert_array_equal(d.band, ref.band)
    np.testing.assert_array_equal(d.fluid, ref.fluid)
    for a in range(3):
        np.testing.assert_array_equal(d.crossings[a], ref.ray_crossings[a])
        cr = ref.crossings[a]
        loaded = np.where(cr["enters"], lamps_mask >> (2 * a) & 1, lamps_mask >> (2 * a + 1) & 1).astype(bool)
        got = d.owners[a][cr["u"], cr["v"], cr["face"]]
        want = np.where(cr["wall"] >= 0, -3, cr["owner"])
        np.testing.assert_array_equal(got[loaded], want[loaded], err_msg=f"axis {a}")
        walls = d.wall_owners[a][cr["u"], cr["v"], cr["face"]]
        np.testing.assert_array_equal(walls[loaded], cr["wall"][loaded], err_msg=f"axis {a}")
        assert (d.owners[a] != -2).sum() == loaded.sum()
        np.testing.assert_array_equal(d.thin_faces[a], ref.thin_faces[a], err_msg=f"axis {a}")
    np.testing.assert_array_equal(d.counts, ref.counts)
    np.testing.assert_array_equal(d.hits, ref.hits)
    np.testing.assert_array_equal(d.wall_counts, ref.wall_counts)
    assert (d.invalid, d.outside, d.tight, d.unattributed) == (ref.invalid, ref.outside, ref.tight, 0)
    thin = sum(len(ref.thin[a]["u"]) for a in range(3))
    assert (d.uncertain, d.rescued, d.thin) == (ref.uncertain, ref.rescued, thin)
    return d


#: (threads per sphere, bits per thread, near list, prune from, exact-test queue, gather, crossing list, thin list,
#: reach masks from): the tests queued or not, the queue too small for the band (the rest tested by the classify
#: threads), each path of the exact test (its reach masks always, never or from 6 near spheres); the crossings and
#: thin chords listed for a thread each, none listed, or the lists too small (the rest loaded where found, or walked
#: by the sphere-axis threads from their first chord left out).
DECOMPOSITIONS = (
    (3, 8, 0, 0, 1 << 20, 128, 1 << 20, 1 << 20, 0),
    (8, 1, 2, 0, 300, 0, 0, 0, 1 << 20),
    (1, 32, 64, 65, 0, 5, 37, 3, 6),
    (1, 32, 64, 0, 1 << 20, 128, 0, 1 << 20, 0),
)


@pytest.mark.parametrize("rho", [0.0, 0.05, 0.1, 0.25, 0.7])
def test_crossings_match_reference_on_random_scenes(device, rng, rho):
    """Voxel maps, the exact test's verdicts, per-ray crossings, each crossing's sphere, the thin chords and the
    counts equal the float64 reference's (polydisperse overlapping spheres, cubic and anisotropic voxels)."""
    for h in (0.2, (0.17, 0.23, 0.2)):
        centers, radii, grid = exact_scene(rng, h=h)
        surface = wetted_solve(centers, radii, probe_radius=rho, grid=grid, keep_owners=True, device=device)
        ref = wetted_reference(centers, radii, grid, probe_radius=rho)
        d = assert_matches(surface, ref)
        assert d.surface.sum() > 20 and d.thin > 5
        assert rho == 0.0 or d.rescued > 500  # the exact test decided many voxels
        assert sum(len(ref.crossings[a]["face"]) for a in range(3)) > 1000
    # Every thread decomposition (threads per sphere, bits per crossing thread, the exact tests queued, with the
    # queue overflowing or not), every path of the exact test (its local list of near spheres cut to 0 or 2:
    # the second gather and the bin-walk search; no pruning of covered spheres; the spheres gathered once per point
    # for its candidates' searches, none or only 5 of them: the bins walked per candidate) and the crossings listed
    # or not (the list overflowing) give the same answer.
    for slices, bits, near, prune, capacity, gather, listed, thin_listed, masks in DECOMPOSITIONS:
        surface._slices, surface._bits = slices, bits
        surface._box.near_list, surface._box.prune_from, surface._box.gather = near, prune, gather
        surface._box.mask_from = masks
        surface._exact_queue(capacity)
        surface._cross_list(listed)
        surface._thin_list(thin_listed)
        surface.update(*device_arrays(centers - grid.origin, radii, device))
        d = assert_matches(surface, ref)
        # The list took what it could hold: all the sphere crossings (over 1000 here), or 37 of them.
        found = sum(len(ref.crossings[a]["face"]) for a in range(3))
        assert d.crossings_listed == (found if listed == 1 << 20 else min(listed, found))
        # Every thin chord with fluid on both sides is listed (at least one per loaded interval), or 3 of them.
        if thin_listed == 1 << 20:
            thin_all = d.thin_listed
            assert thin_all >= d.thin > 5
        assert d.thin_listed == min(thin_listed, thin_all)


def test_float64_inputs_differ_only_where_flagged(device, rng):
    """Centres float32 cannot hold, half of them with voxel centres on their probe shell: the allowed map differs
    from the float64 reference's only at flagged voxels, and on the float32 frame positions the kernels saw the
    reference agrees with them everywhere (maps, exact verdicts, owners, thin chords, counts)."""
    h = 0.25
    origin = 1e3 + 1.0 / 3.0
    grid = wl.LampGrid([origin] * 3, [origin + 7.0] * 3, h)
    flagged = 0
    for rho in (0.0, 0.15, 0.4):
        random = rng.uniform(1.5, 5.5, (100, 3))
        on_voxels = (rng.integers(6, 22, (100, 3)) + 0.5) * h
        centers = origin + np.vstack([random, on_voxels])
        radii = np.concatenate([rng.uniform(0.2, 0.6, 100), rng.integers(2, 4, 100) * h - rho])
        surface = wetted_solve(centers, radii, probe_radius=rho, grid=grid, keep_owners=True, device=device)
        d = surface.diagnostics()
        ref = wetted_reference(centers, radii, grid, probe_radius=rho)
        assert not ((d.allowed != ref.allowed) & ~ref.allowed_ambiguous).any()
        flagged += int(ref.allowed_ambiguous.sum())
        seen = grid.to_frame(centers).astype(np.float32).astype(np.float64)
        own = wetted_reference(seen, radii.astype(np.float32), grid, probe_radius=rho, in_frame=True)
        assert_matches(surface, own)
    assert flagged > 100  # the check above had something to tolerate


def face_crossings(fluid, grid, a):
    """Points (frame coordinates) and (u, v, face) indices of every fluid/dry change along axis a of a fluid map,
    with virtual fluid beyond both ends (the mode's crossings, without the thin chords)."""
    h = voxel_box(grid)[1]
    u, v = (a + 1) % 3, (a + 2) % 3
    f = np.pad(np.transpose(fluid, (u, v, a)), ((0, 0), (0, 0), (1, 1)), constant_values=True)
    iu, iv, face = np.nonzero(f[..., :-1] != f[..., 1:])
    pts = np.empty((len(face), 3))
    pts[:, a], pts[:, u], pts[:, v] = face * h[a], (iu + 0.5) * h[u], (iv + 0.5) * h[v]
    return pts, (iu, iv, face)


def test_attribution_bound_holds_and_search_never_misses(device, rng):
    """Brute force over all spheres: the nearest sphere of every crossing lies within the proven bound and is the
    one the kernels chose, on dense, sparse, mixed-size and quantised scenes; no crossing goes unattributed."""
    worst = 0.0
    for trial in range(6):
        n = int(rng.integers(5, 120))
        centers, radii, grid = exact_scene(rng, n=n, rmin=0.05, rmax=0.9, h=0.25)
        if trial % 2:
            centers = np.round(centers * 4) / 4  # spheres on voxel faces and corners: ties
        local = grid.to_frame(centers)
        for rho in (0.0, 0.3, 1.2):
            d = wetted_solve(centers, radii, probe_radius=rho, grid=grid, keep_owners=True, device=device)
            d = d.diagnostics()
            assert d.unattributed == 0
            bound = attribution_bound(voxel_box(grid)[1], rho)
            for a in range(3):
                pts, where = face_crossings(d.fluid, grid, a)
                diff = pts[:, None, :] - local[None, :, :]
                dist = np.sqrt((diff[..., 0] ** 2 + diff[..., 1] ** 2) + diff[..., 2] ** 2) - radii[None, :]
                best = dist.min(axis=1)
                assert np.all(best <= bound[a])
                owner = d.owners[a][where]
                np.testing.assert_array_equal(dist[np.arange(len(best)), owner], best)
                worst = max(worst, float(best.max() / bound[a]))
    assert 0.3 < worst <= 1.0
    g = voxel_diagonal((0.25, 0.25, 0.25))
    assert attribution_bound((0.25, 0.25, 0.25), 0.0)[0] == pytest.approx(np.hypot(0.125 + g, 0.125))
    h = np.array([0.25, 0.2, 0.3])
    assert np.all(attribution_bound(h, 1.0) <= 2 * 1.0 + h + voxel_diagonal(h))


def test_exact_balance_polyaxial(device, rng):
    """All six lamps: forces sum to exactly zero on every axis, also polyaxially, in any summation order."""
    centers, radii, grid = exact_scene(rng, n=300)
    for rho in (0.0, 0.3):
        for pressure in (P, (3.0e6, 1.1e7, 7.7e5)):
            f = wetted_forces(centers, radii, pressure, probe_radius=rho, grid=grid, device=device)
            assert np.abs(f).sum() > 0
            np.testing.assert_array_equal(f.sum(axis=0), np.zeros(3))
            np.testing.assert_array_equal(f[::-1].sum(axis=0), np.zeros(3))


def test_dilation_table_is_the_euclidean_ball(rng):
    """The offset table holds exactly the offsets within rho (away from float64 ties), on anisotropic cells."""
    for _ in range(20):
        h = rng.uniform(0.1, 0.3, 3)
        rho = float(rng.uniform(0.0, 1.5))
        table = dilation_table(h, rho)
        w = [int(np.ceil(rho / h[a])) + 1 for a in range(3)]
        for j in range(w[1] + 1):
            for k in range(w[2] + 1):
                i = np.arange(w[0] + 1)
                d = np.sqrt((i * h[0]) ** 2 + (j * h[1]) ** 2 + (k * h[2]) ** 2)
                inside = i[d <= rho]
                expect = inside.max() if len(inside) else -1
                got = table[j, k] if j < table.shape[0] and k < table.shape[1] else -1
                assert got == expect
    assert dilation_table((0.25, 0.25, 0.25), 0.0).tolist() == [[0]]
    for _ in range(20):  # the reference's own table agrees
        h, rho = rng.uniform(0.1, 0.3, 3), float(rng.uniform(0.0, 1.5))
        np.testing.assert_array_equal(dilation_table(h, rho), reference_table(h, rho))


# --- accuracy: what the exact classification and the thin chords buy ------------------------------------------


def _offset_grid(rng, lo, hi, h):
    """A box grid with a dyadic corner moved by a random dyadic fraction of a cell (frame coordinates exact)."""
    shift = np.round(rng.random(3) * 1024) / 1024 * h
    return wl.LampGrid(np.asarray(lo, float) - shift, np.asarray(hi, float) - shift, h)


def _silhouette_rows(grid, center, radius, a, tol=1e-6):
    """Rows along axis a whose centre line passes within float rounding of the sphere's silhouette."""
    n, h = voxel_box(grid)
    u, v = (a + 1) % 3, (a + 2) % 3
    c = grid.to_frame(np.asarray(center, float)[None])[0]
    du = (np.arange(n[u]) + 0.5) * h[u] - c[u]
    dv = (np.arange(n[v]) + 0.5) * h[v] - c[v]
    t2 = du[:, None] ** 2 + dv[None, :] ** 2
    return int((np.abs(t2 - radius * radius) <= tol * radius * radius).sum())


def test_lone_sphere_takes_exactly_criterion_1s_cells_for_every_rho(device, rng):
    """A lone sphere's low-lamp counts on each axis equal criterion 1's exactly, for every probe radius from 0 to
    4 cells and at random grid offsets (the fluid is exactly the outside of the sphere at the voxel centres, and
    every row that meets the sphere without holding a voxel centre inside is a thin chord), apart from rows within
    float rounding of the silhouette."""
    r = 0.5
    low = ["-x", "-y", "-z"]
    for cpd in (4, 8):
        h = 2 * r / cpd
        for k in (0.0, 0.25, 0.5, 1.0, 2.0, 4.0):
            rho = k * h
            for _ in range(4):
                grid = _offset_grid(rng, [-1.5 - rho] * 3, [1.5 + rho] * 3, h)
                center = np.round(rng.uniform(-0.1, 0.1, (1, 3)) * 4096) / 4096
                s = wetted_solve(center, [r], probe_radius=rho, grid=grid, lamps=low, device=device)
                wet = s.counts_numpy()[0]
                first = wl.lamp_forces(center, [r], 1.0, grid=grid, criterion=1, lamps=low, device=device)[0]
                first = np.rint(first / pressure_area(1.0, grid)).astype(np.int64)
                for a in range(3):
                    assert abs(int(wet[a]) - int(first[a])) <= _silhouette_rows(grid, center[0], r, a), (cpd, k, a)
                assert np.all(wet > 0.8 * np.pi * r * r / (h * h))


def test_lone_sphere_load_converges_for_every_rho(device):
    """The lone sphere's -x load over P pi r^2, for every probe radius (0 to 4 cells), equals criterion 1's on the
    same grid bitwise at every random grid offset (the fluid is the sphere's whole outside: the same cells), and
    criterion 1's converges to 1 as the cells shrink (RMS 9.3%, 2.0%, 0.82% at 4, 8, 16 cells per diameter)."""
    result = lone_sphere_convergence(cells=(4, 8, 16), offsets=12, seed=7, device=device)
    first = {r["cells_per_diameter"]: r for r in result["rows"] if r["rho_cells"] is None}
    for row in result["rows"]:
        assert row["loads"] == first[row["cells_per_diameter"]]["loads"], row
    assert len(result["rows"]) == 3 * 7
    rms = [first[k]["rms"] for k in (4, 8, 16)]
    assert rms[0] > rms[1] > rms[2] and rms[2] < 0.01, rms


def test_separated_spheres_each_take_criterion_1s_cells_alone(device, rng):
    """Spheres farther apart than the probe's diameter plus a few cells: each takes on every low lamp exactly the
    cells criterion 1 gives it alone (the probe goes around each; nothing bridges them)."""
    h = 0.125
    centers = np.array([[0.0, 0.0, 0.0], [2.0, 0.25, 0.0], [0.25, 2.5, 0.5], [2.25, 2.0, 2.0], [0.0, 0.5, 2.5]])
    radii = np.array([0.5, 0.375, 0.625, 0.3125, 0.4375])
    low = ["-x", "-y", "-z"]
    for rho in (0.5 * h, 2 * h, 0.3):
        grid = _offset_grid(rng, [-1.5] * 3, [4.0] * 3, h)
        wet = wetted_solve(centers, radii, probe_radius=rho, grid=grid, lamps=low, device=device).counts_numpy()
        for i in range(len(radii)):
            alone = wl.lamp_forces(centers[i : i + 1], radii[i : i + 1], 1.0, grid=grid, lamps=low, device=device)
            alone = np.rint(alone[0] / pressure_area(1.0, grid)).astype(np.int64)
            slack = sum(_silhouette_rows(grid, centers[i], radii[i], a) for a in range(3))
            assert np.abs(wet[i] - alone).sum() <= slack, (rho, i, wet[i], alone)


def block_face_scene(n=6, spacing=1.0, radius=0.75):
    """A cubic block of overlapping spheres (radius 0.75 spacing: no channel along any axis, every pore sealed),
    and its -x face's interior particles (not on an edge of the face)."""
    idx = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    centers = idx * spacing
    face = (idx[:, 0] == 0) & np.all((idx[:, 1:] > 0) & (idx[:, 1:] < n - 1), axis=1)
    return centers.astype(float), np.full(len(centers), radius), face


def test_block_face_interior_particles_take_their_square(device, rng):
    """The flat face of a block: every interior face particle takes, on the -x lamp, exactly the cells criterion 1
    gives it (its square of side one spacing in projection), for every probe radius; so the face's load per
    particle converges to P s^2 as the cells shrink (criterion 1's rate: the RMS error halves with the cell), and
    no particle behind the face is loaded from -x (the pores are sealed)."""
    centers, radii, face = block_face_scene()
    inner = np.all((centers[:, 1:] > 0.5) & (centers[:, 1:] < 4.5), axis=1)
    behind = inner & (centers[:, 0] > 0.5)  # not on the face, nor on a side face (its scallops take -x loads)
    rms = []
    for cpd in (4, 8):
        h = 1.5 / cpd
        errs = []
        for k in (0.0, 0.5, 1.0, 4.0):
            rho = k * h
            for _ in range(2):
                grid = _offset_grid(rng, [-2.0 - rho] * 3, [7.0 + rho] * 3, h)
                s = wetted_solve(centers, radii, probe_radius=rho, grid=grid, lamps=["-x"], device=device)
                wet = s.counts_numpy()[:, 0]
                first = wl.lamp_forces(centers, radii, 1.0, grid=grid, criterion=1, lamps=["-x"], device=device)
                first = np.rint(first[:, 0] / pressure_area(1.0, grid)[0]).astype(np.int64)
                np.testing.assert_array_equal(wet[face], first[face])
                assert not wet[behind].any()
                errs.append(wet[face] * h * h - 1.0)
        errs = np.concatenate(errs)
        assert abs(errs.mean()) < 0.05, (cpd, errs.mean())  # a few grid offsets: the mean is criterion 1's noise
        rms.append(float(np.sqrt(np.mean(errs * errs))))
    assert rms[1] < 0.7 * rms[0] and rms[1] < 0.15, rms


def test_thin_chords_merge_where_the_gap_between_them_is_dry(device):
    """Two small spheres whose chords lie between the same two voxel centres of a row: a probe that fits between
    them (rho = 0, 0.05) sees two dry intervals, a larger one (0.1) one, entered at the first sphere and left at the
    second; kernels and reference agree on each."""
    h = 0.25
    grid = wl.LampGrid([0.0] * 3, [2.0] * 3, h)
    row = 0.125 + 3 * h
    centers = np.array([[0.171875 + 3 * h, row, row], [0.3046875 + 3 * h, row, row]])
    radii = np.array([0.03125, 0.03125])
    for rho, merged in ((0.0, False), (0.05, False), (0.1, True), (0.2, True)):
        surface = wetted_solve(centers, radii, probe_radius=rho, grid=grid, keep_owners=True, device=device)
        d = assert_matches(surface, wetted_reference(centers, radii, grid, probe_radius=rho))
        assert d.thin == (1 if merged else 2) and d.gap_tests >= 1
        assert d.counts[:, 1:].sum() == 0
        np.testing.assert_array_equal(d.counts[:, 0], [1, -1] if merged else [0, 0])
        np.testing.assert_array_equal(d.hits, [1, 1] if merged else [2, 2])


# --- the scenes -------------------------------------------------------------------------------------


def slot_ratios(scene, forces):
    cut, idx = scene.cut, scene.index
    top = idx[:, 2] >= cut["k0"]
    lo = (idx[:, 1] == cut["wall_lo"]) & top
    hi = (idx[:, 1] == cut["wall_hi"]) & top
    floor = (idx[:, 2] == cut["floor"]) & (idx[:, 1] >= cut["j0"]) & (idx[:, 1] < cut["j1"])
    side = P * cut["length"] * cut["depth"]
    return (
        -forces[lo, 1].sum() / side,
        forces[hi, 1].sum() / side,
        -forces[floor, 2].sum() / (P * cut["length"] * cut["width"]),
    )


def test_slot_block_walls_and_floor_loaded(device):
    """Issue 10's slot at 4 cells per diameter, rho = one mean radius: both walls get >= 0.93 of P L D laterally
    and the floor >= 0.95 of P L w (the values this geometry converges to: 0.94 and 0.97 at 4, 6 and 8 cells per
    diameter, bench/experiments/WETTED.md), where the first-surface lamp gives the walls nothing."""
    scene = scene_slot_block()
    rho = float(scene.radii.mean())
    f = wetted_forces(scene.centers, scene.radii, P, probe_radius=rho, cells_per_diameter=4, device=device)
    lo, hi, floor = slot_ratios(scene, f)
    assert lo >= 0.93 and hi >= 0.93 and floor >= 0.95, (lo, hi, floor)
    np.testing.assert_array_equal(f.sum(axis=0), 0.0)
    first = wl.lamp_forces(scene.centers, scene.radii, P, cells_per_diameter=4, device=device)
    lo1, hi1, floor1 = slot_ratios(scene, first)
    assert abs(lo1) < 0.05 and abs(hi1) < 0.05 and floor1 < 0.7


def specimen_mean_pressure(scene, forces):
    """-tr(sigma) / 3 / P, sigma = sum x (x) F over the envelope sphere's volume (forces at particle centres)."""
    x = scene.centers - scene.center
    sigma = np.einsum("ni,nj->ij", x, forces) / (4.0 / 3.0 * np.pi * scene.radius**3)
    return -np.trace(sigma) / 3.0 / P


def test_specimen_mean_pressure_does_not_depend_on_the_cells(device):
    """The SphereTest specimen's mean pressure (forces at particle centres) is the same at 4 and 6 cells per
    diameter to 0.3%, for rho = d/2 and d (before issue 19 it fell by 0.7% and 1.0%: the dry region was
    inflated by up to a voxel), and lies near 1 - r/R less the deeper particles' share (0.88 to 0.93)."""
    from warp_lamp.scenes import scene_sphere_specimen

    scene = scene_sphere_specimen()
    d = 2.0 * float(scene.radii.mean())
    for k in (0.5, 1.0):
        p = []
        for cpd in (4, 6):
            grid = wl.LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=cpd, margin=d + k * d)
            f = wetted_forces(scene.centers, scene.radii, P, probe_radius=k * d, grid=grid, device=device)
            np.testing.assert_array_equal(f.sum(axis=0), 0.0)
            p.append(specimen_mean_pressure(scene, f))
        assert abs(p[1] - p[0]) < 0.003 * p[0] and 0.88 < p[0] < 0.93, (k, p)


def test_sealed_cavity_gets_the_forces_of_the_solid_block(device):
    """A sealed spherical cavity changes no force; a probe small enough to pass the lattice's windows (not
    sealed) does load it, so the check can fail."""
    scene = scene_cavity_block()
    full = scene.full()
    grid = wl.LampGrid.enclosing(full.centers, full.radii, cells_per_diameter=4, margin=2.0)
    f_full = wetted_forces(full.centers, full.radii, P, probe_radius=0.45, grid=grid, device=device)
    f_cut = wetted_forces(scene.centers, scene.radii, P, probe_radius=0.45, grid=grid, device=device)
    removed = np.setdiff1d(np.arange(full.n), scene.kept)
    assert not f_full[removed].any()
    np.testing.assert_array_equal(f_cut, f_full[scene.kept])
    s = wetted_solve(scene.centers, scene.radii, probe_radius=0.1, grid=grid, device=device)
    f_small = s.counts_numpy() * pressure_area(P, grid)
    f_small_full = wetted_forces(full.centers, full.radii, P, probe_radius=0.1, grid=grid, device=device)
    assert (f_small != f_small_full[scene.kept]).any(axis=1).sum() > 50


def test_tunnel_wall_loaded_by_its_projected_width(device):
    """A tunnel bored through a block: the z-resultant on the particles above its axis rises by P w L, w the
    tunnel's width to within one particle diameter, and its wall particles are loaded."""
    scene = scene_tunnel_block()
    full = scene.full()
    rho = float(full.radii.mean())
    grid = wl.LampGrid.enclosing(full.centers, full.radii, cells_per_diameter=4, margin=2.0 + rho)
    f_full = wetted_forces(full.centers, full.radii, P, probe_radius=rho, grid=grid, device=device)
    s = wetted_solve(scene.centers, scene.radii, probe_radius=rho, grid=grid, device=device)
    f_cut = s.counts_numpy() * pressure_area(P, grid)
    above = full.centers[:, 2] > scene.cut["axis"][1]
    delta = f_cut[above[scene.kept], 2].sum() - f_full[above, 2].sum()
    width = delta / (P * scene.cut["length"])
    assert abs(width - scene.cut["width"]) <= 2.0 * rho, (width, scene.cut["width"])
    ring = np.hypot(*(scene.index[:, 1:] - (np.array(scene.block["n_per_axis"][1:]) - 1) / 2.0).T) < 4.0
    assert s.diagnostics().surface[ring].mean() > 0.5


# --- limits -----------------------------------------------------------------------------------------------


def test_large_probe_closes_to_the_convex_hull(device):
    """rho several times the body: the fluid boundary is the convex hull of the spheres, bridging a notch."""
    from scipy.spatial import ConvexHull

    # A U of spheres: the notch between the arms is open to a small probe and bridged by a large one.
    pts = [(x, 0.0, 0.0) for x in np.arange(0.0, 3.1, 0.5)]
    pts += [(0.0, y, 0.0) for y in np.arange(0.5, 2.6, 0.5)] + [(3.0, y, 0.0) for y in np.arange(0.5, 2.6, 0.5)]
    centers = np.array(pts, dtype=np.float64)
    radii = np.full(len(centers), 0.375)
    rho, h = 8.0, 0.25
    lower = centers.min(axis=0) - radii[0] - rho - 2 * h
    upper = centers.max(axis=0) + radii[0] + rho + 2 * h
    grid = wl.LampGrid(lower, upper, h)
    d = wetted_solve(centers, radii, probe_radius=rho, grid=grid, device=device).diagnostics()
    assert d.tight == 0
    sphere = np.random.default_rng(0).normal(size=(200, 3))
    sphere /= np.linalg.norm(sphere, axis=1)[:, None]
    hull = ConvexHull((centers[:, None, :] + radii[0] * sphere[None]).reshape(-1, 3))
    n, hh = voxel_box(grid)
    xs = [grid.origin[a] + (np.arange(n[a]) + 0.5) * hh[a] for a in range(3)]
    x = np.stack(np.meshgrid(*xs, indexing="ij"), axis=-1)
    signed = (x @ hull.equations[:, :3].T + hull.equations[:, 3]).max(axis=-1)  # > 0 outside the hull
    sag = 3.0**2 / (8 * rho) + np.sqrt(3) * h  # chord 3 under a ball of radius rho, plus a voxel diagonal
    assert not d.fluid[signed < -sag].any()
    assert d.fluid[signed > np.sqrt(3) * h].all()
    notch = (np.abs(x[..., 0] - 1.5) < 0.5) & (x[..., 1] > 1.0) & (x[..., 1] < 2.0) & (np.abs(x[..., 2]) < 0.2)
    assert notch.any() and not d.fluid[notch].any()
    small = wetted_solve(centers, radii, probe_radius=0.1, grid=grid, device=device).diagnostics()
    assert small.fluid[notch].all()


def test_zero_probe_immersed_spheres_cancel(device, rng):
    """rho = 0: the fluid reaches every gap; a sphere clear of its neighbours takes both crossings of every ray
    it meets (its loads cancel exactly), and in a dense packing the net loads nearly cancel."""
    centers = np.stack(np.meshgrid(*[np.arange(4) * 1.5] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    centers = centers + rng.uniform(-0.1, 0.1, centers.shape)
    radii = rng.uniform(0.4, 0.5, len(centers))  # gaps >= 0.3, more than a voxel
    d = wetted_solve(centers, radii, probe_radius=0.0, cells_per_diameter=6, device=device).diagnostics()
    assert d.surface.all()
    np.testing.assert_array_equal(d.counts, 0)
    # A jittered cubic packing whose neighbours touch or nearly: the fluid still enters every pore.
    block = wl.scenes.scene_lattice_box(8)
    d = wetted_solve(block.centers, block.radii, probe_radius=0.0, cells_per_diameter=4, device=device).diagnostics()
    inner = np.all((block.centers > 0.5) & (block.centers < 6.5), axis=1)
    assert d.surface[inner].all()
    net = np.abs(d.counts[inner]).sum(axis=1)
    assert net.sum() < 0.1 * d.hits[inner].sum(), (net.sum(), d.hits[inner].sum())


def test_exact_tests_queued_in_voxel_order(device, rng):
    """The queued exact tests take the uncertain voxels in increasing voxel order (a prefix sum places them), the
    same voxels as the atomics' order, with the same answer; with the queue too small, its first voxels in order."""
    centers, radii, grid = exact_scene(rng)
    surface = wetted_solve(centers, radii, probe_radius=0.25, grid=grid, device=device)
    seen = {}
    for capacity, ordered in ((1 << 20, True), (1 << 20, False), (300, True)):
        surface._exact_queue(capacity)
        surface._queue_in_order(ordered)
        surface.update(*device_arrays(centers - grid.origin, radii, device))
        d = surface.diagnostics()
        n = min(int(surface.queued.numpy()[0]), capacity)
        q = surface.queue.numpy()[:n]
        assert int(surface.queued.numpy()[0]) == d.uncertain > 300
        if ordered:
            assert np.all(np.diff(q) > 0)
        seen[(capacity, ordered)] = (np.sort(q), d.fluid.copy(), d.counts.copy())
    np.testing.assert_array_equal(seen[(1 << 20, True)][0], seen[(1 << 20, False)][0])
    np.testing.assert_array_equal(seen[(300, True)][0], seen[(1 << 20, True)][0][:300])
    for k in ((1 << 20, False), (300, True)):
        np.testing.assert_array_equal(seen[k][1], seen[(1 << 20, True)][1])
        np.testing.assert_array_equal(seen[k][2], seen[(1 << 20, True)][2])


def test_queued_tests_share_threads(device, rng):
    """The queued exact tests give the reference's answer however many threads take them in turn, each with its
    own interleaved row of gathered spheres: 1, 7 and 64 threads, twice as many threads as tests (each test a first
    slot, not spread) and 32768 (spread: every stride-th thread takes one)."""
    centers, radii, grid = exact_scene(rng)
    ref = wetted_reference(centers, radii, grid, probe_radius=0.25)
    surface = wetted_solve(centers, radii, probe_radius=0.25, grid=grid, keep_owners=True, device=device)
    tests = surface.diagnostics().uncertain
    assert 300 < tests < 4096
    for threads in (1, 7, 64, 2 * tests, 32768):
        surface._exact_queue(1 << 20, threads)
        surface.update(*device_arrays(centers - grid.origin, radii, device))
        d = assert_matches(surface, ref)
        assert d.uncertain == tests
        assert surface._gathered.shape[0] == wl.wetted.KB.GATHER * threads
        # The kernel's rule: spread once the threads are QUEUE_SPREAD_FROM times the tests; only 32768 is.
        assert (threads >= wl.wetted.KB.QUEUE_SPREAD_FROM * tests) == (threads == 32768)
        assert (int(surface.queued.numpy()[1]) == 0) == (threads >= tests)


def test_reach_masks_on_nearly_collinear_triples(device, rng):
    """The exact test's reach masks skip no valid candidate where triples are ill-conditioned: a cubic lattice of
    touching spheres jittered by ~1e-4 of the spacing (rows of nearly collinear centres), masks always and never,
    against the reference."""
    idx = np.stack(np.meshgrid(*[np.arange(5)] * 3, indexing="ij"), axis=-1).reshape(-1, 3).astype(np.float64)
    jitter = np.round(rng.uniform(-1.0, 1.0, idx.shape) * 16.0) / 2.0**17  # dyadic: float32 holds it exactly
    centers = 1.0 + idx + jitter
    radii = np.full(len(centers), 0.5)
    grid = wl.LampGrid([-0.5] * 3, [6.5] * 3, 0.25)
    ref = wetted_reference(centers, radii, grid, probe_radius=0.45)
    surface = wetted_solve(centers, radii, probe_radius=0.45, grid=grid, keep_owners=True, device=device)
    for masks in (0, 1 << 20):
        surface._box.mask_from = masks
        surface.update(*device_arrays(centers - grid.origin, radii, device))
        d = assert_matches(surface, ref)
        assert d.rescued > 100  # the exact test decided many voxels


# --- hard cases and bad input -----------------------------------------------------------------------------


def test_lamp_subsets_load_only_their_crossings(device, rng):
    """With -z off (a platen), x and y balance, z is pushed down only, and owners match the reference."""
    centers, radii, grid = exact_scene(rng)
    lamps = ["-x", "+x", "-y", "+y", "+z"]
    surface = wetted_solve(centers, radii, probe_radius=0.2, grid=grid, lamps=lamps, keep_owners=True, device=device)
    ref = wetted_reference(centers, radii, grid, probe_radius=0.2, lamps=lamps)
    d = assert_matches(surface, ref, lamps_mask=wl.lamp.lamp_mask(lamps))
    total = d.counts.sum(axis=0)
    assert total[0] == 0 and total[1] == 0 and total[2] < 0
    assert np.all(d.counts[:, 2] <= 0)
    assert d.loaded["-z"] == 0 and d.loaded["+z"] > 0


def test_active_mask_and_invalid_particles(device, rng):
    """Inactive particles are absent; NaN positions and radii <= 0 are skipped and counted on the device, and
    the rest get bitwise the forces of the scene without them."""
    centers, radii, grid = exact_scene(rng, n=120)
    active = rng.random(len(radii)) > 0.3
    masked = wetted_forces(centers, radii, P, probe_radius=0.2, grid=grid, active=active, device=device)
    subset = wetted_forces(centers[active], radii[active], P, probe_radius=0.2, grid=grid, device=device)
    assert not masked[~active].any()
    np.testing.assert_array_equal(masked[active], subset)
    pos = (centers - grid.origin).astype(np.float32)
    rad = radii.astype(np.float32)
    pos[3] = np.nan
    rad[7], rad[8], rad[9] = 0.0, -1.0, np.inf
    surface = WettedSurface(grid, probe_radius=0.2, device=device)
    surface.update(wp.array(pos, dtype=wp.vec3, device=device), wp.array(rad, device=device))
    d = surface.diagnostics()
    assert d.invalid == 4
    valid = np.ones(len(radii), dtype=bool)
    valid[[3, 7, 8, 9]] = False
    expected = wetted_forces(centers, radii, P, probe_radius=0.2, grid=grid, active=valid, device=device)
    np.testing.assert_array_equal(d.counts * pressure_area(P, grid), expected)


def test_particles_outside_the_box_are_counted_and_balance(device, rng):
    """A box cutting through the body: outside and tight particles are counted as the reference counts them,
    every crossing still matches, and the forces still balance exactly."""
    centers, radii, _ = exact_scene(rng, n=150)
    grid = wl.LampGrid([0.0] * 3, [4.0] * 3, 0.125)
    surface = wetted_solve(centers, radii, probe_radius=0.3, grid=grid, keep_owners=True, device=device)
    ref = wetted_reference(centers, radii, grid, probe_radius=0.3)
    d = assert_matches(surface, ref)
    assert d.outside > 20 and d.tight > d.outside
    np.testing.assert_array_equal(d.counts.sum(axis=0), 0)


def hard_cases(rng):
    """(label, centres, radii, grid, rho) of the hard cases; every frame coordinate and radius is dyadic, so the
    kernels see the reference's inputs bit for bit."""
    h = 0.25
    cases = []
    lone = wl.LampGrid([-2.0] * 3, [2.0] * 3, h)
    for k in (0.0, 0.25, 0.5, 1.0, 2.0, 4.0):
        for _ in range(3):
            cases.append(("lone", np.round(rng.random((1, 3)) * 1024) / 1024 * h, [0.5], lone, k * h))
    box = wl.LampGrid([-2.0] * 3, [3.0] * 3, h)
    touching = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.75, 0.0], [0.5, 0.25, 0.75]]
    for rho in (0.0, 0.0625, 0.25, 1.0):
        cases.append(("touching", touching, [0.5, 0.5, 0.4, 0.3], box, rho))
    copies = [[0.125, 0.125, 0.125]] * 3 + [[0.125, 0.125, 0.625], [0.1, 0.2, 0.3], [0.1, 0.2, 0.3]]
    for rho in (0.0, 0.0625, 0.25, 0.5):
        cases.append(("copies and concentric", copies, [0.5, 0.5, 0.25, 0.5, 0.1, 0.1], box, rho))
    for rho in (0.0, 0.125, 0.25, 0.375):
        cases.append(("on voxel centres", [[0.125, 0.125, 0.125], [0.625, 0.375, 0.125]], [0.5, 0.375], box, rho))
    for rho in (2.0**-20, 2.0**-10):
        cases.append(("tiny probe", [[0.1, 0.2, 0.3], [0.9, 0.2, 0.3]], [0.5, 0.3], box, rho))
    far = wl.LampGrid([-6.0] * 3, [7.0] * 3, h)
    cases.append(
        ("huge probe", np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.5]]) * 0.75, [0.4, 0.3, 0.5, 0.35], far, 4.0)
    )
    small = wl.LampGrid([-1.0] * 3, [2.0] * 3, h)
    for rho in (0.0, 0.03125, 0.0625, 0.125):
        c = np.round(rng.uniform(0, 1, (60, 3)) * 256) / 256
        cases.append(("smaller than a voxel", c, np.round(rng.uniform(0.05, 0.15, 60) * 256) / 256, small, rho))
    return cases


def test_reference_agrees_on_hard_cases(device, rng):
    """Kernels equal the reference on the hard cases: a lone sphere at random offsets with rho from 0 to 4 cells,
    touching spheres, exact copies and concentric spheres, centres on voxel centres, a tiny and a huge probe, and
    spheres smaller than a voxel (overlapping thin chords, gaps tested)."""
    totals = np.zeros(4, dtype=np.int64)
    for label, centers, radii, grid, rho in hard_cases(rng):
        centers, radii = np.asarray(centers, dtype=np.float64), np.asarray(radii, dtype=np.float64)
        surface = wetted_solve(centers, radii, probe_radius=rho, grid=grid, keep_owners=True, device=device)
        try:
            d = assert_matches(surface, wetted_reference(centers, radii, grid, probe_radius=rho))
        except AssertionError as err:
            raise AssertionError(f"{label}, rho = {rho}") from err
        totals += (d.uncertain, d.rescued, d.thin, d.gap_tests)
    assert np.all(totals > (500, 400, 100, 0)), totals


def test_no_particles_after_some(device, rng):
    """N = 0 works on a surface that held particles before: nothing is loaded and the whole box is fluid."""
    centers, radii, grid = exact_scene(rng, n=50)
    surface = wetted_solve(centers, radii, probe_radius=0.2, grid=grid, device=device)
    assert surface.diagnostics().surface.any()
    surface.update(wp.zeros(0, dtype=wp.vec3, device=device), wp.zeros(0, dtype=wp.float32, device=device))
    d = surface.diagnostics()
    assert d.fluid.all() and d.counts.shape == (0, 3) and d.thin == 0 and d.uncertain == 0
    assert all(c.sum() == 0 for c in d.crossings.values())


def test_no_particles_and_memo_form_grids(device):
    """N = 0 loads nothing; the memo's 18-number form is refused unless its grids are one voxel grid."""
    grid = wl.LampGrid([0, 0, 0], [1, 1, 1], 0.25)
    surface = WettedSurface(grid, probe_radius=0.1, device=device)
    surface.update(wp.zeros(0, dtype=wp.vec3, device=device), wp.zeros(0, dtype=wp.float32, device=device))
    d = surface.diagnostics()
    assert d.fluid.all() and d.counts.shape == (0, 3) and all(c.sum() == 0 for c in d.crossings.values())
    same = wl.LampGrid.from_grids(
        corners=[[0, 0], [0, 0], [0, 0]], lengths=[[1, 1], [1, 1], [1, 1]], counts=[[4, 4], [4, 4], [4, 4]]
    )
    assert voxel_box(same)[0].tolist() == [4, 4, 4]
    memo = wl.LampGrid.from_grids(
        corners=[[0, 0], [0, 0], [0, 0]], lengths=[[1, 1], [1, 1], [1, 1]], counts=[[4, 4], [5, 4], [4, 4]]
    )
    with pytest.raises(ValueError, match="grid: the wetted-surface mode needs one voxel grid"):
        WettedSurface(memo, probe_radius=0.1, device=device)


def test_bad_arguments_raise_clear_errors(device):
    """Bad probe radius, bounds, arrays and budgets name the argument."""
    grid = wl.LampGrid([0, 0, 0], [2, 2, 2], 0.25)
    for bad in (-0.1, np.nan, np.inf, "x"):
        with pytest.raises(ValueError, match="probe_radius"):
            WettedSurface(grid, probe_radius=bad, device=device)
    with pytest.raises(ValueError, match="max_rounds"):
        WettedSurface(grid, probe_radius=0.1, max_rounds=0, device=device)
    with pytest.raises(ValueError, match="lamps"):
        WettedSurface(grid, probe_radius=0.1, lamps=["-w"], device=device)
    tight = wl.LampGrid([0, 0, 0], [2, 2, 2], 0.05)
    budget = wetted_nbytes(tight, 0.1, device=device) + 1000  # the exact test's queue on CUDA: the device's bytes
    assert wetted_nbytes(tight, 1.0, device=device) > budget
    WettedSurface(tight, probe_radius=0.1, device=device, max_bytes=budget)
    with pytest.raises(ValueError, match="budget"):
        WettedSurface(tight, probe_radius=1.0, device=device, max_bytes=budget)
    with pytest.raises(ValueError, match="budget"):
        wl.ShiningLamp(tight, surfaces="all", probe_radius=1.0, device=device, max_bytes=budget)
    with pytest.raises(ValueError, match=r"probe_radius: surfaces='all' needs"):
        wl.ShiningLamp(grid, surfaces="all", device=device)
    with pytest.raises(ValueError, match=r"probe_radius: only with surfaces='all'"):
        wl.ShiningLamp(grid, probe_radius=0.1, device=device)
    with pytest.raises(ValueError, match=r"criterion: surfaces='all'"):
        wl.ShiningLamp(grid, surfaces="all", probe_radius=0.1, criterion="area", device=device)
    surface = WettedSurface(grid, probe_radius=0.1, device=device)
    pos = wp.zeros(4, dtype=wp.vec3, device=device)
    with pytest.raises(TypeError, match="positions"):
        surface.update(wp.zeros(4, dtype=wp.vec4, device=device), wp.zeros(4, dtype=wp.float32, device=device))
    with pytest.raises(ValueError, match="radii"):
        surface.update(pos, wp.zeros(3, dtype=wp.float32, device=device))
    with pytest.raises(TypeError, match="active"):
        surface.update(pos, wp.zeros(4, dtype=wp.float32, device=device), wp.zeros(4, dtype=wp.float32, device=device))


def test_memory_is_known_before_allocation(device):
    """wetted_nbytes equals the bytes the surface allocates for its grid-sized buffers."""
    grid = wl.LampGrid([0, 0, 0], [3.1, 2.2, 1.7], 0.1)
    for rho, keep, skin in ((0.0, False, None), (0.35, True, None), (0.35, False, "auto")):
        surface = WettedSurface(grid, probe_radius=rho, keep_owners=keep, device=device, skin=skin)
        arrays = [v for v in vars(surface).values() if isinstance(v, wp.array)]
        per_particle = {id(surface.counts), id(surface.hits), id(surface.next_in_bin), id(surface._no_active)}
        per_particle |= {id(surface.thin_list), id(surface.thin_from)}  # sized with the particles
        allocated = sum(a.capacity for a in arrays if id(a) not in per_particle)
        assert wetted_nbytes(grid, rho, keep_owners=keep, device=device, skin=skin) == surface.nbytes
        assert allocated == surface.nbytes
    # Per particle: the stated bytes (past the thin list's minimum size on CUDA).
    n = 16_000
    surface = WettedSurface(grid, probe_radius=0.35, device=device)
    surface.reserve(n)
    sized = [surface.counts, surface.hits, surface.next_in_bin, surface.exposed, surface.thin_list, surface.thin_from]
    extra = CUDA_BYTES_PER_PARTICLE if wp.get_device(device).is_cuda else 0
    assert sum(a.capacity for a in sized) == n * (BYTES_PER_PARTICLE + extra)


def test_connectivity_bound_is_counted_and_balance_holds(device):
    """A zigzag channel needs several rounds; capped at one round, the solve is counted as cut short, the fluid
    is a subset of the converged one, and the forces still balance."""
    # Walls of spheres with staggered gaps: the probe must zigzag in y and x to reach the back chamber.
    cells = []
    for wall, gap_x in enumerate((0.0, 4.0, 0.0)):
        y = 1.0 + 1.5 * wall
        cells += [(x, y, z) for x in np.arange(-4.0, 4.1, 0.5) for z in np.arange(-2.0, 2.1, 0.5) if x != gap_x]
    outer = [(x, y, z) for x in (-4.5, 4.5) for y in np.arange(0.5, 5.6, 0.5) for z in np.arange(-2.0, 2.1, 0.5)]
    centers = np.array(cells + outer)
    radii = np.full(len(centers), 0.3)
    full = wetted_solve(centers, radii, probe_radius=0.05, cells_per_diameter=4, device=device)
    short = wetted_solve(centers, radii, probe_radius=0.05, grid=full.grid, max_rounds=1, device=device)
    df, ds = full.diagnostics(), short.diagnostics()
    assert df.rounds >= 2 and not df.nonconverged
    assert ds.rounds == 1 and ds.nonconverged and ds.nonconverged_total == 1
    assert np.all(ds.fluid <= df.fluid) and (ds.fluid != df.fluid).any()
    np.testing.assert_array_equal(ds.counts.sum(axis=0), 0)
    short.update(*device_arrays(centers - full.grid.origin, radii, device))
    assert short.diagnostics().nonconverged_total == 2


def device_arrays(frame, radii, device):
    pos = wp.array(np.asarray(frame, dtype=np.float32), dtype=wp.vec3, device=device)
    return pos, wp.array(np.asarray(radii, dtype=np.float32), dtype=wp.float32, device=device)


def test_capture_and_replay_equal_eager(device, rng):
    """update() recorded with wp.ScopedCapture and replayed equals an eager update, also after the particles
    move in place (the graph reads the arrays when it runs)."""
    centers, radii, grid = exact_scene(rng, n=200)
    moved = centers + rng.normal(scale=0.2, size=centers.shape)
    pos, rad = device_arrays(centers - grid.origin, radii, device)
    surface = WettedSurface(grid, probe_radius=0.25, device=device)
    surface.reserve(len(radii))
    with wp.ScopedCapture(device=device) as capture:
        surface.update(pos, rad)
    for scene in (centers, moved):
        pos.assign(wp.array(np.asarray(scene - grid.origin, dtype=np.float32), dtype=wp.vec3, device=device))
        for arr in (surface.fluid, surface.reach, surface.blocked, surface.solid, surface.band):
            arr.fill_(0x5A5A5A5A)  # garbage the replay must clear or overwrite
        surface.counts.fill_(7)
        wp.capture_launch(capture.graph)
        replay = surface.diagnostics()
        eager = wetted_solve(scene, radii, probe_radius=0.25, grid=grid, device=device).diagnostics()
        np.testing.assert_array_equal(replay.counts, eager.counts)
        np.testing.assert_array_equal(replay.fluid, eager.fluid)
        assert replay.rounds == eager.rounds and replay.invalid == 0
        assert (replay.uncertain, replay.rescued, replay.thin) == (eager.uncertain, eager.rescued, eager.thin)
        assert replay.rescued > 0 and replay.thin > 0


# --- walls that bound the fluid (issue 19, part 2) -------------------------------------------------------------

#: Two tilted walls that cut exact_scene's box (each cuts every axis).
TILTED = [((2.5, 2.5, 1.5), (0.2, -0.1, 1.0)), ((4.0, 1.0, 2.0), (-1.0, 0.3, 0.2))]


def walls_reference(centers, radii, grid, rho, walls, **kw):
    return wetted_reference(centers, radii, grid, probe_radius=rho, walls=wl.validate.check_walls(walls), **kw)


@pytest.mark.parametrize("rho", [0.0, 0.1, 0.4])
def test_walls_match_reference_on_random_scenes(device, rng, rho):
    """Two tilted walls cutting a random scene: the maps, the exact test's verdicts, each crossing's sphere or wall,
    the thin chords and the particles' and walls' counts equal the float64 reference's (cubic and anisotropic
    voxels), along every path of the kernels; the walls' planes in the frame are the reference's."""
    for h in (0.2, (0.17, 0.23, 0.2)):
        centers, radii, grid = exact_scene(rng, n=120, h=h)
        surface = wetted_solve(
            centers, radii, probe_radius=rho, grid=grid, keep_owners=True, device=device, walls=TILTED
        )
        ref = walls_reference(centers, radii, grid, rho, TILTED)
        np.testing.assert_array_equal(surface.walls_frame.numpy(), ref.walls)
        d = assert_matches(surface, ref)
        assert (d.wall_counts != 0).all()  # both walls take crossings on every axis
        assert d.surface.sum() > 20 and (rho == 0.0 or d.rescued > 300)
        free = wetted_solve(centers, radii, probe_radius=rho, grid=grid, device=device).diagnostics()
        assert (free.fluid & ~d.fluid).sum() > 1000  # the walls cut the fluid
    for slices, bits, near, prune, capacity, gather, listed, thin_listed, masks in DECOMPOSITIONS:
        surface._slices, surface._bits = slices, bits
        surface._box.near_list, surface._box.prune_from, surface._box.gather = near, prune, gather
        surface._box.mask_from = masks
        surface._exact_queue(capacity)
        surface._cross_list(listed)
        surface._thin_list(thin_listed)
        surface.update(*device_arrays(centers - grid.origin, radii, device))
        assert_matches(surface, ref)


def wall_cases(rng):
    """(label, centres, radii, grid, rho, walls) of the hard cases with walls; frame coordinates and radii dyadic."""
    h = 0.25
    box = wl.LampGrid([-2.0] * 3, [3.0] * 3, h)
    touching = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.75, 0.0], [0.5, 0.25, 0.75]]
    tr = [0.5, 0.5, 0.4, 0.3]
    up = (0.0, 0.0, 1.0)
    small = np.round(rng.uniform(-0.5, 1.5, (40, 3)) * 256) / 256
    small_r = np.round(rng.uniform(0.05, 0.15, 40) * 256) / 256
    cases = []
    for rho in (0.0, 0.0625, 0.25, 0.5):
        cases += [
            ("through spheres", touching, tr, box, rho, [((0, 0, 0.1), up), ((0.3, 0, 0), (1.0, 0.5, 0.25))]),
            ("on a voxel centre plane", touching, tr, box, rho, [((0, 0, 0.125), up)]),
            ("offset plane on voxel centres", touching, tr, box, rho, [((0, 0, 0.125 - rho), up)]),
            ("edge", touching, tr, box, rho, [((0, 0, -0.4), up), ((-0.6, 0, 0), (1, 0, 0))]),
            (
                "tilted edges and a corner",
                touching,
                tr,
                box,
                rho,
                [((0, 0, -0.45), (1, 0, 1)), ((0, -0.55, 0), (0, 1, 1)), ((-0.6, 0, 0), (1, 1, 0.5))],
            ),
            ("under the whole body", touching, tr, box, rho, [((0, 0, -1.5), up)]),
            ("a slab at mid-height", touching, tr, box, rho, [((0, 0, 0.25), up), ((0, 0, 0.875), (0, 0, -1))]),
            ("resting on a platen", [[0.125, 0.25, 0.5]], [0.5], box, rho, [((0, 0, 0), up)]),
            ("buried just under a wall", touching, tr, box, rho, [((0, 0, 0.5625), up)]),
            ("small spheres on a wall", small, small_r, box, rho, [((0, 0, 0.3), (0.25, 0.5, 1))]),
            (
                "an empty corner",
                [[2.0, 2.0, 2.0]],
                [0.125],
                box,
                rho,
                [((-1, 0, 0), (1, 0, 0)), ((0, -1, 0), (0, 1, 0)), ((0, 0, -1), (0.5, 0.25, 1))],
            ),
        ]
    return cases


def test_walls_agree_with_reference_on_hard_cases(device, rng):
    """Kernels equal the reference with walls through spheres, a wall exactly on a voxel-centre plane (and its
    offset plane there), two walls meeting at an edge, three at a corner (with spheres and without: the fillets of
    walls alone), a wall under the whole body, a slab at mid-height, a sphere resting on a platen, spheres buried just
    under a wall (never owners), small spheres on a tilted wall; and on every axis, particles and walls together take
    exactly the rows with one virtual end in the fluid and the other in a wall."""
    totals = np.zeros(4, dtype=np.int64)
    took = 0
    for label, centers, radii, grid, rho, walls in wall_cases(rng):
        centers, radii = np.asarray(centers, dtype=np.float64), np.asarray(radii, dtype=np.float64)
        surface = wetted_solve(
            centers, radii, probe_radius=rho, grid=grid, keep_owners=True, device=device, walls=walls
        )
        ref = walls_reference(centers, radii, grid, rho, walls)
        try:
            d = assert_matches(surface, ref)
        except AssertionError as err:
            raise AssertionError(f"{label}, rho = {rho}") from err
        np.testing.assert_array_equal(d.counts.sum(axis=0) + d.wall_counts.sum(axis=0), facing_rows(ref))
        totals += (d.uncertain, d.rescued, d.thin, np.abs(d.wall_counts).sum())
        took += int(label == "an empty corner" and rho > 0 and (d.wall_counts != 0).any(axis=0).all())
        if label == "buried just under a wall":
            assert d.hits[:3].sum() == 0 and d.hits[3] > 0
    assert np.all(totals > (500, 400, 20, 1000)), totals
    assert took == 3  # the corner's fillet, no sphere near, goes to the walls on every axis (none unattributed)


def facing_rows(ref):
    """Per axis, the rows whose virtual sample before the box is fluid less those whose sample after it is (the
    reference's virtual fluid): what particles and walls together take, with both lamps on."""
    return np.array([int(ref.virtual[a][..., 0].sum()) - int(ref.virtual[a][..., 1].sum()) for a in range(3)])


def test_walls_placed_on_the_device_and_bad_views(device, rng):
    """update() reads the walls the caller placed (a LampWalls view, as ShiningLamp passes it): the surface's own
    static planes give the same answer as a view of them, moving the view's plane changes it, and a view with another
    wall count is refused naming ``walls``."""
    centers, radii, grid = exact_scene(rng, n=80)
    surface = wetted_solve(centers, radii, probe_radius=0.2, grid=grid, device=device, walls=TILTED[:1])
    first = surface.diagnostics()
    first.counts = first.counts.copy()  # on the CPU a view of the device array, which the next update overwrites
    view = LampWalls()
    view.frame = wp.array(surface.walls_frame.numpy(), dtype=wp.vec4, device=device)
    view.n = 1
    pos, rad = device_arrays(centers - grid.origin, radii, device)
    surface.update(pos, rad, walls=view)
    np.testing.assert_array_equal(surface.counts_numpy(), first.counts)
    np.testing.assert_array_equal(surface.wall_counts_numpy(), first.wall_counts)
    view.frame.assign(surface.walls_frame.numpy() + np.array([[0, 0, 0, 0.5]], dtype=np.float32))
    surface.update(pos, rad, walls=view)
    assert (surface.counts_numpy() != first.counts).any()
    view.n = 0
    with pytest.raises(ValueError, match="walls: the surface was built for 1 walls"):
        surface.update(pos, rad, walls=view)


@pytest.mark.skipif(len(DEVICES) < 2, reason="needs a CUDA device")
def test_cpu_and_cuda_bitwise_equal(rng):
    """Maps, the exact test's verdicts, per-face owners, thin chords and counts on CUDA are bitwise those of the
    CPU (every decision is float64 arithmetic and sqrt with fuse_fp off)."""
    scene = scene_slot_block((14, 14, 10), width=4, depth=4)
    for rho in (0.1, 0.45):
        cpu = wetted_solve(scene.centers, scene.radii, probe_radius=rho, keep_owners=True, device="cpu")
        dc = cpu.diagnostics()
        for dev in DEVICES[1:]:
            dg = wetted_solve(scene.centers, scene.radii, probe_radius=rho, keep_owners=True, device=dev).diagnostics()
            np.testing.assert_array_equal(dc.band, dg.band)
            np.testing.assert_array_equal(dc.fluid, dg.fluid)
            np.testing.assert_array_equal(dc.counts, dg.counts)
            assert (dc.uncertain, dc.rescued, dc.thin, dc.gap_tests) == (
                dg.uncertain,
                dg.rescued,
                dg.thin,
                dg.gap_tests,
            )
            for a in range(3):
                np.testing.assert_array_equal(dc.owners[a], dg.owners[a])
                np.testing.assert_array_equal(dc.thin_faces[a], dg.thin_faces[a])


@pytest.mark.skipif(len(DEVICES) < 2, reason="needs a CUDA device")
def test_walls_cpu_and_cuda_bitwise_equal():
    """With a tilted platen and a side wall: maps, owners (spheres and walls), thin chords and the particles' and
    walls' counts on CUDA are bitwise those of the CPU."""
    scene = scene_slot_block((14, 14, 10), width=4, depth=4)
    c, r = scene.centers, scene.radii
    walls = [((0.0, 0.0, float((c[:, 2] - r).min()) + 0.3), (0.05, -0.1, 1.0)), ((1.7, 0.0, 0.0), (1.0, 0.2, 0.0))]
    for rho in (0.1, 0.45):
        cpu = wetted_solve(c, r, probe_radius=rho, keep_owners=True, device="cpu", walls=walls).diagnostics()
        assert (cpu.wall_counts != 0).any()
        for dev in DEVICES[1:]:
            gpu = wetted_solve(c, r, probe_radius=rho, keep_owners=True, device=dev, walls=walls).diagnostics()
            np.testing.assert_array_equal(cpu.fluid, gpu.fluid)
            np.testing.assert_array_equal(cpu.band, gpu.band)
            np.testing.assert_array_equal(cpu.counts, gpu.counts)
            np.testing.assert_array_equal(cpu.wall_counts, gpu.wall_counts)
            assert (cpu.uncertain, cpu.rescued, cpu.thin) == (gpu.uncertain, gpu.rescued, gpu.thin)
            for a in range(3):
                np.testing.assert_array_equal(cpu.owners[a], gpu.owners[a])
                np.testing.assert_array_equal(cpu.wall_owners[a], gpu.wall_owners[a])
                np.testing.assert_array_equal(cpu.thin_faces[a], gpu.thin_faces[a])


@pytest.mark.parametrize("scale", [1000.0, 7.0, 1e-3])
def test_wetted_forces_do_not_depend_on_the_unit_of_length(device, scale):
    """A lattice ball with rho exactly two voxels (ties everywhere) in metres and rescaled, with P rescaled to
    match: the same forces (a tie decided the other way moves a particle by a whole cell's P A, 7% here) and the
    same enclosing grid, in every mode."""
    from warp_lamp.scenes import scene_lattice_ball

    ball = scene_lattice_ball(diameter=0.03, particle_diameter=0.005)
    c, r = ball.centers, ball.radii
    rho = float(r.mean())  # = 2 h at 4 cells per diameter
    for kw in ({"surfaces": "all", "probe_radius": rho}, {}):
        base = wl.lamp_forces(c, r, 1e6, device=device, **kw)
        kws = {k: (v * scale if k == "probe_radius" else v) for k, v in kw.items()}
        f = wl.lamp_forces(c * scale, r * scale, 1e6 / scale**2, device=device, **kws)
        np.testing.assert_allclose(f, base, rtol=1e-12, atol=1e-12 * np.abs(base).max())
        g1 = wl.LampGrid.enclosing(c, r, probe_radius=kw.get("probe_radius", 0.0))
        gs = wl.LampGrid.enclosing(c * scale, r * scale, probe_radius=kws.get("probe_radius", 0.0))
        np.testing.assert_array_equal(gs.counts, g1.counts)


@pytest.fixture(scope="module")
def brute_packing():
    """40 overlapping polydisperse spheres (radii 0.25-0.75, mean 0.5, overlaps up to 30%), rho = 0.25, a box on
    whole quarter cells around them, and the brute-force fluid on a 1/32 lattice, without and with a wall through
    the packing's middle (z at the median centre, the fluid above)."""
    s = scene_overlapping_polydisperse(40, solid_fraction=0.4)
    c, r, rho = s.centers, s.radii, 0.25
    lo = np.floor(((c - r[:, None]).min(axis=0) - rho - 0.5) / 0.25) * 0.25
    hi = np.ceil(((c + r[:, None]).max(axis=0) + rho + 0.5) / 0.25) * 0.25
    walls = [((0.0, 0.0, float(np.median(c[:, 2]))), (0.0, 0.0, 1.0))]
    fluids = {w: brute_fluid(c, r, rho, lo, hi, walls=walls if w else (), g=1 / 32) for w in (False, True)}
    return c, r, rho, lo, hi, walls, fluids


@pytest.mark.parametrize("wall", [False, True], ids=["spheres", "wall"])
def test_wetted_loads_converge_to_a_brute_force_fluid(device, brute_packing, wall):
    """Independent accuracy of surfaces="all": each particle's count on each low and high lamp against a brute
    force (tests/wetted_brute.py: probe centres on a 1/32 lattice flood-filled from outside, the fluid within rho of
    them by an exact distance transform, each lamp ray walked in 1/32 steps; nothing of the mode's voxel rules).
    The mode decides reach on the voxel centres, so a throat narrower than about a voxel is closed to it: it finds
    fewer crossings than the continuum (never more, beyond the lattice's own rounding), and the gap closes as the
    cells shrink. Per particle and lamp axis, |count difference| x h^2 / (pi r^2), RMS: at 4 and 8 cells per mean
    diameter measured 25.7% and 17.2% (spheres), 15.7% and 7.9% (with the wall), bounded by 30% and 21%, 19% and
    10%; the total crossings 80% and 87% of the brute force's (spheres), 77-89% and 96-98% (with the wall; the
    brute force itself finds more as its lattice is refined: 1,096 crossings at 1/16, 1,187 at 1/32)."""
    c, r, rho, lo, hi, walls, fluids = brute_packing
    bound = {False: (0.30, 0.21), True: (0.19, 0.10)}[wall]
    share = {False: (0.75, 0.83), True: (0.72, 0.92)}[wall]
    rms = []
    for k, h in enumerate((0.25, 0.125)):
        grid = wl.LampGrid(lo, hi, h)
        counts = np.round((hi - lo) / h).astype(int)
        brute = brute_counts(fluids[wall], lo, counts, h)
        for lamps, want in zip((["-x", "-y", "-z"], ["+x", "+y", "+z"]), brute, strict=True):
            f = wetted_forces(c, r, 1.0, probe_radius=rho, grid=grid, lamps=lamps, walls=walls if wall else None,
                              device=device)  # fmt: skip
            got = np.rint(f / (h * h)).astype(np.int64)
            err = np.abs(got - want) * h * h / (np.pi * r[:, None] ** 2)
            rms.append(float(np.sqrt(np.mean(err**2))))
            assert rms[-1] < bound[k], (h, lamps, rms[-1])
            assert share[k] * np.abs(want).sum() < np.abs(got).sum() <= 1.01 * np.abs(want).sum(), (h, lamps)
    assert max(rms[2:]) < 0.8 * min(rms[:2]), rms
