"""The exact visible-area references: the planar core on degenerate configurations, and the per-lamp areas."""

import numpy as np
import pytest
from helpers import first_surface_raster, raster_tolerance, raster_visible_areas

import warp_lamp as wl
from warp_lamp.reference.area import (
    area_depth_slots,
    area_estimate_reference,
    visible_area_reference,
    visible_disk_areas,
    visible_sphere_areas,
)
from warp_lamp.scenes import scene_overlapping_polydisperse

PI = np.pi


def column_quadrature(centers, radii, rect, columns=20000):
    """Visible areas by another route: in each of ``columns`` vertical lines (midpoint rule across x), the exact
    length of every disk's chord not covered by an earlier disk's chord, by a 1-D sweep."""
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    r = np.asarray(radii, dtype=np.float64)
    x0, y0, x1, y1 = rect
    k = len(r)
    dx = (x1 - x0) / columns
    xs = x0 + (np.arange(columns) + 0.5) * dx
    s2 = r[None, :] ** 2 - (xs[:, None] - c[None, :, 0]) ** 2
    has = s2 > 0
    s = np.sqrt(np.where(has, s2, 0.0))
    lo = np.where(has, np.clip(c[None, :, 1] - s, y0, y1), y1)
    hi = np.where(has, np.clip(c[None, :, 1] + s, y0, y1), y0)
    cuts = np.sort(np.concatenate([np.full((columns, 1), y0), lo, hi, np.full((columns, 1), y1)], axis=1), axis=1)
    mid = 0.5 * (cuts[:, 1:] + cuts[:, :-1])
    inside = (mid[:, :, None] >= lo[:, None, :]) & (mid[:, :, None] <= hi[:, None, :])
    first = np.where(inside.any(axis=2), inside.argmax(axis=2), k)
    length = cuts[:, 1:] - cuts[:, :-1]
    out = np.zeros(k + 1)
    np.add.at(out, first.ravel(), length.ravel())
    return out[:k] * dx


def disjoint_spheres(rng, n, extent, rmin, rmax):
    """Random spheres in a cube, greedily thinned to a disjoint set."""
    c = rng.uniform(0, extent, (n, 3))
    r = rng.uniform(rmin, rmax, n)
    keep = np.ones(n, dtype=bool)
    for i in range(n):
        d = np.linalg.norm(c[:i] - c[i], axis=1)
        if np.any(keep[:i] & (d < r[:i] + r[i])):
            keep[i] = False
    return c[keep], r[keep]


def lens_area(r1, r2, d):
    """Area of the intersection of two disks, closed form."""
    if d >= r1 + r2:
        return 0.0
    if d <= abs(r1 - r2):
        return PI * min(r1, r2) ** 2
    a1 = np.arccos((d * d + r1 * r1 - r2 * r2) / (2 * d * r1))
    a2 = np.arccos((d * d + r2 * r2 - r1 * r1) / (2 * d * r2))
    return r1 * r1 * (a1 - 0.5 * np.sin(2 * a1)) + r2 * r2 * (a2 - 0.5 * np.sin(2 * a2))


# --- the planar core --------------------------------------------------------------------------------------


def test_identical_disks_give_everything_to_the_first():
    """Two or five identical disks: the first takes the whole area, the others exactly zero."""
    for k in (2, 5):
        a = visible_disk_areas(np.tile([[0.3, -0.2]], (k, 1)), np.full(k, 0.7), (-2, -2, 2, 2))
        assert a[0] == pytest.approx(PI * 0.49, rel=1e-15)
        assert np.all(a[1:] == 0.0)


def test_tangent_disks_externally_and_internally():
    """External tangency: both disks whole. Internal tangency: the small one hidden behind the big one, or
    the big one an exact crescent behind the small one."""
    rect = (-6, -6, 6, 6)
    np.testing.assert_allclose(visible_disk_areas([[0, 0], [2, 0]], [1, 1], rect), [PI, PI], rtol=1e-15)
    np.testing.assert_allclose(visible_disk_areas([[0, 0], [0, 3]], [1, 2], rect), [PI, 4 * PI], rtol=1e-15)
    a = visible_disk_areas([[0.0, 0.0], [0.5, 0.0]], [1.0, 0.5], rect)
    assert a[0] == pytest.approx(PI, rel=1e-15) and abs(a[1]) < 1e-15
    a = visible_disk_areas([[0.5, 0.0], [0.0, 0.0]], [0.5, 1.0], rect)
    np.testing.assert_allclose(a, [0.25 * PI, 0.75 * PI], rtol=1e-14)


def test_nearly_tangent_and_nearly_coincident_pairs():
    """Pairs 1e-12 (relative) away from tangency or coincidence get the closed-form lens and crescent areas."""
    rect = (-4, -4, 4, 4)
    eps = 1e-12
    for d in (2 * (1 - eps), 2 * (1 + eps)):  # externally, nearly tangent
        a = visible_disk_areas([[0, 0], [d, 0]], [1, 1], rect)
        assert a[0] == pytest.approx(PI, rel=1e-14)
        assert a[1] == pytest.approx(PI - lens_area(1, 1, d), rel=1e-14)
    for d in (0.5 * (1 - eps), 0.5 * (1 + eps)):  # internally, nearly tangent
        a = visible_disk_areas([[0, 0], [d, 0]], [0.5, 1], rect)
        assert a[1] == pytest.approx(PI - lens_area(0.5, 1, d), rel=1e-14)
        a = visible_disk_areas([[d, 0], [0, 0]], [1, 0.5], rect)
        assert abs(a[1] - (0.25 * PI - lens_area(1, 0.5, d))) < 1e-14
    # Nearly coincident: the second disk shows a crescent of about 2 r d, or an annulus of 2 pi r dr.
    d = eps
    a = visible_disk_areas([[0, 0], [d, 0]], [1, 1], rect)
    assert a[0] == pytest.approx(PI, rel=1e-15)
    assert a[1] == pytest.approx(2 * d, rel=1e-3)
    a = visible_disk_areas([[0, 0], [0, 0]], [1, 1 + eps], rect)
    assert a[1] == pytest.approx(2 * PI * eps, rel=1e-3)
    a = visible_disk_areas([[0, 0], [0, 0]], [1 + eps, 1], rect)
    assert a[1] == 0.0


def test_disks_meeting_the_rectangle_in_corners_and_edges():
    """Inscribed and circumscribed disks, disks centred on a corner or an edge, tangent to an edge."""
    sq = (-1, -1, 1, 1)
    assert visible_disk_areas([[0, 0]], [1], sq)[0] == pytest.approx(PI, rel=1e-15)  # inscribed: touches 4 edges
    assert visible_disk_areas([[0, 0]], [2**0.5], sq)[0] == pytest.approx(4.0, rel=1e-15)  # through all 4 corners
    assert visible_disk_areas([[1, 1]], [0.6], sq)[0] == pytest.approx(0.09 * PI, rel=1e-15)  # on a corner
    assert visible_disk_areas([[0, -1]], [0.6], sq)[0] == pytest.approx(0.18 * PI, rel=1e-15)  # on an edge
    assert visible_disk_areas([[0, -2]], [1], sq)[0] == 0.0  # tangent from outside
    assert visible_disk_areas([[0, -0.5]], [0.5], sq)[0] == pytest.approx(0.25 * PI, rel=1e-15)  # from inside
    # Through two corners exactly: the disk centred on an edge's midpoint reaching the far corners.
    a = visible_disk_areas([[0, -1]], [5**0.5], sq)[0]
    assert a == pytest.approx(4.0, rel=1e-15)
    # The corner (1, 1) lies exactly on this circle: (0.5)^2 + (1.5)^2 + ... checked against quadrature.
    c, r = [[0.5, -0.5]], [np.hypot(0.5, 1.5)]
    assert visible_disk_areas(c, r, sq)[0] == pytest.approx(column_quadrature(c, r, sq)[0], abs=2e-6)


def test_touching_square_lattice_of_columns():
    """Four columns of three coincident disks, touching each other and the rectangle edges: each column's
    front disk gets pi r^2, everything behind it zero (a naive arc clip gets this wrong)."""
    r = 0.5
    centres = np.array([[0.5, 0.5], [1.5, 0.5], [0.5, 1.5], [1.5, 1.5]])
    disks = np.concatenate([centres] * 3)
    a = visible_disk_areas(disks, np.full(12, r), (0, 0, 2, 2))
    np.testing.assert_allclose(a[:4], PI * r * r, rtol=1e-14)
    assert np.all(np.abs(a[4:]) <= 1e-15)
    # Cut into cells of a third of a diameter (as a lamp cell would see them): the pieces add up to pi r^2.
    total = np.zeros(12)
    h = 1.0 / 3.0
    for i in range(6):
        for j in range(6):
            total += visible_disk_areas(disks, np.full(12, r), (i * h, j * h, (i + 1) * h, (j + 1) * h))
    np.testing.assert_allclose(total[:4], PI * r * r, rtol=1e-13)
    assert np.all(np.abs(total[4:]) <= 1e-14)


def test_symmetric_configurations():
    """Two equal overlapping disks in either order; four disks in a square: exact lens arithmetic."""
    rect = (-5, -5, 5, 5)
    lens = lens_area(1, 1, 1.2)
    for order in ([0, 1], [1, 0]):
        c = np.array([[-0.6, 0.0], [0.6, 0.0]])[order]
        np.testing.assert_allclose(visible_disk_areas(c, [1, 1], rect), [PI, PI - lens], rtol=1e-14)
    # Four unit disks at (+-0.8, +-0.8): neighbours at 1.6 overlap, diagonals at 2.26 do not.
    c = np.array([[-0.8, -0.8], [0.8, -0.8], [0.8, 0.8], [-0.8, 0.8]])
    lens = lens_area(1, 1, 1.6)
    np.testing.assert_allclose(
        visible_disk_areas(c, np.ones(4), rect), [PI, PI - lens, PI - lens, PI - 2 * lens], rtol=1e-14
    )


@pytest.mark.parametrize("quantized", [False, True])
def test_random_disks_match_column_quadrature_and_union(rng, quantized):
    """Random disks (some snapped to a coarse lattice, so that tangencies and coincidences abound) match the
    column quadrature disk by disk, and their sum matches a Monte Carlo estimate of the union."""
    rect = (0.0, 0.0, 1.0, 0.75)
    for _ in range(8):
        k = int(rng.integers(1, 9))
        c = rng.uniform(-0.4, 1.4, (k, 2))
        r = rng.uniform(0.1, 0.8, k)
        if quantized:
            c = np.round(c * 4) / 4
            r = np.round(r * 4 + 0.5) / 4
            c[k // 2 :] = c[: k - k // 2]  # coincident centres
        a = visible_disk_areas(c, r, rect)
        q = column_quadrature(c, r, rect)
        np.testing.assert_allclose(a, q, atol=2e-6)
        assert np.all(a >= -1e-15)
        pts = rng.uniform((rect[0], rect[1]), (rect[2], rect[3]), (200000, 2))
        hit = (((pts[:, None, :] - c[None]) ** 2).sum(axis=2) <= r**2).any(axis=1)
        union = hit.mean() * 0.75
        sigma = np.sqrt(max(hit.mean() * (1 - hit.mean()), 1e-12) / len(pts)) * 0.75
        assert abs(a.sum() - union) <= 5 * sigma + 1e-12


def test_visible_disk_areas_rejects_bad_input():
    """Bad radii, centres and rectangles raise, naming the argument and the first bad disk."""
    with pytest.raises(ValueError, match="disk 1"):
        visible_disk_areas([[0, 0], [1, 1]], [1, 0], (0, 0, 1, 1))
    with pytest.raises(ValueError, match="disk 0"):
        visible_disk_areas([[np.nan, 0]], [1], (0, 0, 1, 1))
    with pytest.raises(ValueError, match="rect"):
        visible_disk_areas([[0, 0]], [1], (0, 0, -1, 1))
    with pytest.raises(ValueError, match="radii"):
        visible_disk_areas([[0, 0]], [1, 2], (0, 0, 1, 1))


# --- per-lamp visible areas -------------------------------------------------------------------------------


def test_lone_sphere_and_hidden_pairs():
    """A lone sphere shows pi r^2 to every lamp; a sphere behind another along x shows nothing to one x lamp."""
    a = visible_area_reference([[0.1, 0.2, 0.3]], [0.7])
    np.testing.assert_allclose(a, PI * 0.49, rtol=1e-13)
    a = visible_area_reference([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]], [0.5, 0.5])
    np.testing.assert_allclose(a[:, 0], [PI / 4, 0.0], atol=1e-15)  # -x sees sphere 0
    np.testing.assert_allclose(a[:, 1], [0.0, PI / 4], atol=1e-15)  # +x sees sphere 1
    np.testing.assert_allclose(a[:, 2:], PI / 4, rtol=1e-13)


@pytest.mark.parametrize("n", [2, 4])
def test_touching_cubic_lattice_loads_n2_pi_r2_per_lamp(n):
    """r = spacing / 2: columns project to one disk and neighbouring disks touch; every lamp sees exactly
    n^2 pi r^2, all of it on the lattice's outer layer on that side."""
    g = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), axis=-1).reshape(-1, 3) * 1.0
    a = visible_area_reference(g + 0.123, np.full(len(g), 0.5))
    np.testing.assert_allclose(a.sum(axis=0), n * n * PI / 4, rtol=1e-13)
    for lamp in range(6):
        ax, side = divmod(lamp, 2)
        face = g[:, ax] == (0 if side == 0 else n - 1)
        np.testing.assert_allclose(a[face, lamp], PI / 4, rtol=1e-12)
        assert np.all(np.abs(a[~face, lamp]) < 1e-14)


def test_random_disjoint_spheres_match_planar_quadrature(rng):
    """Random disjoint spheres: each lamp's areas match column quadrature of the disks sorted by depth."""
    c, r = disjoint_spheres(rng, 60, 3.0, 0.1, 0.45)
    a = visible_area_reference(c, r)
    for lamp in range(6):
        ax, side = divmod(lamp, 2)
        u, v = (ax + 1) % 3, (ax + 2) % 3
        order = np.lexsort((np.arange(len(r)), c[:, ax] if side == 0 else -c[:, ax]))
        q = column_quadrature(c[order][:, [u, v]], r[order], (-1, -1, 4, 4), columns=40000)
        np.testing.assert_allclose(a[order, lamp], q, atol=5e-6)


def test_active_mask_and_lamp_subset():
    """Inactive spheres cast no shadow and get zero; lamps that are off get zero columns."""
    c = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    a = visible_area_reference(c, [0.5, 0.5], active=[0, 1])
    np.testing.assert_allclose(a[1], PI / 4, rtol=1e-13)
    assert np.all(a[0] == 0)
    a = visible_area_reference(c, [0.5, 0.5], lamps=["+z"])
    assert np.all(a[:, [0, 1, 2, 3, 4]] == 0) and np.all(a[:, 5] > 0)
    with pytest.raises(ValueError, match="radii"):
        visible_area_reference(c, [0.5, -1.0])
    with pytest.raises(ValueError, match="active"):
        visible_area_reference(c, 0.5, active=[1])
    with pytest.raises(ValueError, match="lamps"):
        visible_area_reference(c, 0.5, lamps=["up"])


def test_lamp_at_fine_resolution_converges_to_the_reference(rng):
    """Cross-check with the lamp kernel itself: criterion 1 at 16 cells per diameter is within 2% (RMS per
    particle, against P pi rbar^2) of the exact areas on a body of disjoint spheres, and 4x closer than at 2."""
    c, r = disjoint_spheres(rng, 400, 3.0, 0.2, 0.35)
    assert len(r) > 80
    exact = visible_area_reference(c, r)
    net = exact[:, 0::2] - exact[:, 1::2]
    scale = PI * np.mean(r) ** 2
    errs = []
    for cpd in (2, 16):
        f = wl.lamp_forces(c, r, 1.0, cells_per_diameter=cpd, device="cpu")
        errs.append(np.sqrt(np.mean(np.sum((f - net) ** 2, axis=1))) / scale)
    assert errs[1] < 0.02 and errs[1] < errs[0] / 4


# --- the estimator reference ------------------------------------------------------------------------------


def test_depth_slots_hold_the_d_nearest_spheres_of_each_ray(rng):
    """D-slot keys: per sample ray and lamp, the ids of the D first spheres along the ray (entry depth for the
    low lamp, exit depth for the high one), checked against float64 brute force where depths are not near-tied."""
    c, r = disjoint_spheres(rng, 200, 3.0, 0.15, 0.4)
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3)
    d = 3
    keys, offsets = area_depth_slots(c, r, grid, depth_slots=d)
    checked = 0
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        (cu, cv), (hu, hv), (nu, nv) = grid.corner[a], grid.cell[a], grid.counts[a]
        for i, j in rng.integers(0, [nu + 1, nv + 1], (200, 2)):
            du = cu + i * hu - c[:, u]
            dv = cv + j * hv - c[:, v]
            rem = r * r - du * du - dv * dv
            hit = np.flatnonzero(rem >= 0)
            s = np.sqrt(np.maximum(rem[hit], 0))
            for side, depth in ((0, c[hit, a] - s), (1, -(c[hit, a] + s))):
                order = hit[np.argsort(depth)][:d]
                gaps = np.diff(np.sort(depth)[: d + 1])
                if np.any(gaps < 1e-5) or np.any(np.abs(rem[order]) < 1e-5):
                    continue
                base = (2 * (offsets[a] + j * (nu + 1) + i) + side) * d
                k = keys[base : base + d]
                got = [int(x & 0xFFFFFFFF) for x in k if x != 0xFFFFFFFFFFFFFFFF]
                assert got == order.tolist()
                checked += 1
    assert checked > 300


@pytest.mark.parametrize("resolver", ["exact", "subpoints"])
def test_estimator_balances_exactly(rng, resolver):
    """Units sum to exactly zero per axis on random overlapping, tied (snapped) and one-lamp-off scenes."""
    c = rng.uniform(0, 4, (200, 3))
    r = rng.uniform(0.2, 0.6, 200)
    for cc, rr in ((c, r), (np.round(c * 4) / 4, np.round(r * 8 + 1) / 8)):
        for cpd in (2, 3.5):
            grid = wl.LampGrid.enclosing(cc, rr, cells_per_diameter=cpd)
            est = area_estimate_reference(cc, rr, grid, resolver=resolver)
            np.testing.assert_array_equal(est.units.sum(axis=0), [0, 0, 0])
            assert np.abs(est.units).sum() > 0
    est = area_estimate_reference(c, r, grid, resolver=resolver, lamps=["-x", "+x", "-y", "+y", "+z"])
    assert est.units[:, :2].sum() == 0 and np.all(est.units[:, 2] <= 0)


def test_estimator_lone_sphere_exact_to_the_unit():
    """Exact resolver on a lone sphere at random offsets: per lamp, pi r^2 / A * UNIT to within half a unit
    per cell (the per-cell rounding), on every lamp; the sub-point resolver counts the sub-points in the disk."""
    rng = np.random.default_rng(3)
    for cpd in (2, 3, 4):
        h = 1.0 / cpd
        grid = wl.LampGrid([-1.0] * 3, [1.0] * 3, h)
        for off in rng.uniform(0, h, (6, 3)):
            est = area_estimate_reference(off[None, :], [0.5], grid, details=True)
            target = np.pi * 0.25 / (h * h) * est.unit
            for d in est.cells.values():
                assert abs(d["units"].sum() - target) <= 0.5 * len(d["cell"])
                assert np.all(np.abs(d["units"].sum(axis=1) - d["share"].sum(axis=1)) <= 0.5 + 1e-9)


def test_estimator_converges_to_the_exact_areas(rng):
    """On a body of disjoint spheres the estimator's per-particle force error against the exact visible areas,
    RMS / (P pi rbar^2), is below 0.5% (exact resolver, D = 4, 3 cells per diameter) and 2% (sub-points), and
    criterion 1 at 16 cells per diameter, a cross-check of both, lies within 2% of the estimator."""
    c, r = disjoint_spheres(rng, 3000, 4.0, 0.2, 0.33)
    assert len(r) > 200
    exact = visible_area_reference(c, r)
    net = exact[:, 0::2] - exact[:, 1::2]
    scale = np.pi * np.mean(r) ** 2
    grid = wl.LampGrid.enclosing(c, r, cells_per_diameter=3)
    forces = {}
    for resolver in ("exact", "subpoints"):
        est = area_estimate_reference(c, r, grid, depth_slots=4, resolver=resolver)
        forces[resolver] = est.units * grid.cell_area / est.unit
    forces["c1"] = wl.lamp_forces(c, r, 1.0, cells_per_diameter=16, device="cpu")
    rms = {k: np.sqrt(np.mean(np.sum((f - net) ** 2, axis=1))) / scale for k, f in forces.items()}
    assert rms["exact"] < 0.005 and rms["subpoints"] < 0.02, rms
    cross = np.sqrt(np.mean(np.sum((forces["c1"] - forces["exact"]) ** 2, axis=1))) / scale
    assert cross < 0.02, cross


def test_estimator_rejects_bad_arguments():
    """Bad resolver, sub-point count, depth slots and seed bound raise, naming the argument."""
    grid = wl.LampGrid([-1.0] * 3, [1.0] * 3, 0.25)
    c = np.zeros((1, 3))
    for kw, name in (
        (dict(resolver="fast"), "resolver"),
        (dict(subpoints=0), "subpoints"),
        (dict(depth_slots=0), "depth_slots"),
        (dict(max_seeds=0), "max_seeds"),
    ):
        with pytest.raises(ValueError, match=name):
            area_estimate_reference(c, [0.5], grid, **kw)


# --- visibility by surface depth (issue 19) -----------------------------------------------------------------


def two_sphere_views():
    """The issue's two overlapping unequal spheres (centres (0, 0, 0), (0.45, 0.05, 0), radii 0.5, 0.15) seen
    from the -y and +y lamps: centres as (z, x, +-y), the -y lamp's plane being (z, x)."""
    c = np.array([[0.0, 0.0, 0.0], [0.45, 0.05, 0.0]])
    r = np.array([0.5, 0.15])
    return {sign: (np.stack([c[:, 2], c[:, 0], sign * c[:, 1]], axis=1), r) for sign in (1, -1)}


def test_two_overlapping_spheres_match_a_fine_raster():
    """The issue's example: the small sphere's visible area from -y and +y by the reference equals a 2048 x 2048
    brute-force raster of its bounding box to 1e-5 (0.02416 and 0.03176; measured 3e-6); ordering the disks by
    centre depth, as before issue 19, is off by more than 1e-3 (0.02267, and from +y the whole disk, 0.0707)."""
    for sign, (c, r) in two_sphere_views().items():
        ras, _ = first_surface_raster(c, r, (-0.15, 0.3, 0.15, 0.6), 2048)  # the small disk's bounding box
        ref = visible_sphere_areas(c, r, (-1, -1, 1, 1))
        assert abs(ref[1] - ras[1]) < 1e-5, (sign, ref[1], ras[1])
        order = np.argsort(c[:, 2])
        by_centre = np.empty(2)
        by_centre[order] = visible_disk_areas(c[order, :2], r[order], (-1, -1, 1, 1))
        assert abs(by_centre[1] - ras[1]) > 1e-3


def test_nested_sphere_is_hidden():
    """A sphere wholly inside another takes nothing from either side, wherever its centre is nearer the lamp."""
    rect = (-1, -1, 1, 1)
    for depth in (-0.2, 0.2, -0.39):
        a = visible_sphere_areas([[0.0, 0.0, 0.0], [0.05, -0.02, depth]], [0.5, 0.1], rect)
        assert a[1] == 0.0 and a[0] == pytest.approx(0.25 * PI, rel=1e-12)
    a = visible_area_reference([[0.0, 0.0, 0.0], [0.2, 0.0, 0.0]], [0.5, 0.1])
    assert np.all(a[1] == 0.0)
    np.testing.assert_allclose(a[0], 0.25 * PI, rtol=1e-12)


@pytest.mark.parametrize("kind", ["random", "equal depths", "nested and coincident"])
def test_visible_sphere_areas_match_a_brute_force_raster(rng, kind):
    """Random overlapping spheres in a rectangle (intersecting, some at equal depths, nested, coincident): each
    sphere's visible area is the 2048 x 2048 first-surface raster's to within the raster's error bound, and the
    areas add up to the union's."""
    rect = (0.0, 0.0, 1.0, 0.75)
    for _ in range(6):
        k = int(rng.integers(2, 7))
        c = np.column_stack([rng.uniform(-0.2, 1.2, (k, 2)), rng.uniform(-0.5, 0.5, k)])
        r = rng.uniform(0.15, 0.6, k)
        if kind == "equal depths":
            c[:, 2] = np.round(c[:, 2] * 2) / 2
        elif kind == "nested and coincident":
            c[1] = c[0] + [0.05, 0.0, 0.1]
            r[1] = 0.5 * r[0]
            c[-1], r[-1] = c[0], r[0]
        a = visible_sphere_areas(c, r, rect)
        ras, pixel = first_surface_raster(c, r, rect, 2048)
        assert np.all(np.abs(a - ras) <= raster_tolerance(r, pixel)), (a, ras)
        assert a.sum() == pytest.approx(ras.sum(), abs=raster_tolerance(r, pixel).sum())
        if kind == "nested and coincident":
            assert a[1] == 0.0 and a[-1] == 0.0


def test_visible_area_reference_on_an_overlapping_packing_matches_a_raster():
    """An overlapping polydisperse ball (radius ratio 3, overlaps up to 30% of the smaller radius): every sphere's
    visible area from every lamp is a 384-rays-per-diameter first-surface raster's to within its error bound,
    and the RMS difference is below 1.5e-4 of a mean disk (measured 5e-5, mostly the raster's); by centre depth
    (the reference before issue 19) the RMS difference is over 20 times that."""
    s = scene_overlapping_polydisperse(100)
    c, r = s.centers, s.radii
    a = visible_area_reference(c, r)
    ras, pixel = raster_visible_areas(c, r, 384)
    by_centre, _ = raster_visible_areas(c, r, 384, by_centre=True)
    disk = PI * r.mean() ** 2
    assert np.all(np.abs(a - ras) <= raster_tolerance(r, pixel)[:, None])
    rms = np.sqrt(np.mean((a - ras) ** 2)) / disk
    assert rms < 1.5e-4, rms
    assert np.sqrt(np.mean((by_centre - ras) ** 2)) / disk > 20 * rms
