"""Porosity kernels against the `overlap` oracle, the float64 references, and the paper.

The midpoint method's inputs: which sub-cell a centre goes to, and how a radius rounds to whole sub-cells.

The paper's algorithms take integer centres and radii. ``warp_lamp.porosity`` rounds them (centre: the sub-cell
that holds it, floor; radius: nearest whole number of sub-cell edges, ties to even, at least 1). Here the rounding
is done by hand on dyadic sub-cells (so that the ties are exact), and the reference is checked not to borrow the
library's rounding."""

import ast
import importlib
import inspect
import itertools
import time
import warnings

import numpy as np
import pytest

import warp_lamp as wl
from warp_lamp.bench.peers import overlap_hexahedron
from warp_lamp.porosity import kozeny_carman, midpoint_choice, porosity
from warp_lamp.reference import PAPER_TABLE_1, midpoint_sphere_offsets, porosity_reference


def oracle_solid(centers, radii, lower, upper, shape):
    """Per-cell sum over spheres of overlap's exact sphere-hexahedron volume.

    overlap 0.2.0 returns the volume with its sign flipped when a sphere's centre lies exactly on a face plane of
    the hexahedron (centre (4, 1.5, 1), r = 1.5, cell [2,3]x[2,3]x[1,2]: -0.0854016342; shifted by 1e-9 in z:
    +0.0854016344). A volume cannot be negative, so the oracle takes its magnitude. It also reports a volume
    (0.1708 for r = 1.5 and cell [2,3]^3) for a sphere that touches the box at a single point, where the volume is
    0; the scenes here avoid exact tangency.
    """
    overlap = pytest.importorskip("overlap")
    lower = np.asarray(lower, dtype=float)
    h = (np.asarray(upper, dtype=float) - lower) / np.asarray(shape)
    solid = np.zeros(shape)
    for idx in np.ndindex(*shape):
        lo = lower + np.asarray(idx) * h
        hi = lo + h
        verts = overlap_hexahedron(lo, hi)
        hexa = overlap.Hexahedron(verts)
        for c, r in zip(centers, radii, strict=True):
            if np.all(c + r > lo) and np.all(c - r < hi):
                solid[idx] += abs(overlap.overlap_volume(overlap.Sphere(tuple(c), float(r)), hexa))
    return solid


def test_exact_matches_overlap_from_tiny_to_huge_spheres(device):
    """Exact per-cell solid volume is within 1e-9 of a cell of overlap's, for r/h from 0.05 to 50, with spheres
    centred on cell corners and edges and spheres far larger than a cell."""
    rng = np.random.default_rng(3)
    shape, lower, upper = (5, 4, 6), np.zeros(3), np.array([5.0, 4.0, 6.0])
    centers = [rng.uniform(-0.5, 6.0, (25, 3)), rng.uniform(-1.0, 6.0, (6, 3))]
    radii = [0.05 * 10 ** rng.uniform(0, 1, 25), rng.uniform(1.0, 5.0, 6)]
    centers.append(np.array([[2.0, 2.0, 3.0], [1.0, 3.0, 2.5], [4.0, 1.5, 1.0], [-30.0, 2.0, 3.0], [2.5, -48.0, 3.1]]))
    radii.append(np.array([0.7, 1.0, 1.45, 31.3, 50.0]))  # on a corner, on an edge, on a face; huge
    centers, radii = np.vstack(centers), np.concatenate(radii)
    got = (1.0 - porosity(centers, radii, lower, upper, shape, method="exact", device=device)) * 1.0
    want = oracle_solid(centers, radii, lower, upper, shape)
    assert np.abs(got - want).max() <= 1e-9
    assert want.max() > 0.99 and (want > 1.0).any()  # full cells, and overlapping sums above one cell


def test_exact_is_independent_of_where_the_box_is(device, rng):
    """A box 1e4 m from the origin gives the porosity it gives at the origin (the shift is done in float64)."""
    centers = rng.uniform(0, 0.1, (40, 3))
    radii = rng.uniform(0.002, 0.02, 40)
    near = porosity(centers, radii, [0, 0, 0], [0.1] * 3, (4, 4, 4), method="exact", device=device)
    far = porosity(centers + 1e4, radii, [1e4] * 3, [1e4 + 0.1] * 3, (4, 4, 4), method="exact", device=device)
    np.testing.assert_allclose(near, far, atol=1e-9)


@pytest.mark.parametrize(
    ("method", "algorithm"),
    [("centroid", None), ("polyhedron", None), ("exact", None), ("voxel", None), ("midpoint", 1), ("midpoint", 2)],
)
def test_kernels_match_float64_reference(device, rng, method, algorithm):
    """Each method equals its plain float64 NumPy reference on a random polydisperse scene poking out of the box
    (union methods bitwise, sums to rounding); cells are not cubes (midpoint: 1 x 2 x 1, cubic sub-cells)."""
    centers = rng.uniform(-0.1, 1.1, (60, 3))
    radii = rng.uniform(0.02, 0.25, 60)
    upper = [1.0, 1.5, 0.5] if method == "midpoint" else [1.0, 1.2, 0.9]
    args = (centers, radii, [0, 0, 0], upper, (4, 3, 2) if method == "midpoint" else (4, 3, 5))
    got = porosity(*args, method=method, subdivisions=7, midpoint_algorithm=algorithm, device=device)
    want = porosity_reference(*args, method=method, subdivisions=7, midpoint_algorithm=algorithm)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def nonoverlapping(rng, n, box, rmin, rmax):
    centers, radii = [], []
    while len(radii) < n:
        r = rng.uniform(rmin, rmax)
        c = rng.uniform(0, box, 3)
        if all(np.linalg.norm(c - d) > r + e for d, e in zip(centers, radii, strict=True)):
            centers.append(c)
            radii.append(r)
    return np.array(centers), np.array(radii)


def test_voxel_error_falls_with_subdivisions_on_nonoverlapping_packing(device):
    """Where union equals sum, voxel's error against overlap's exact volumes falls at order 2 in subdivisions, as
    the README says: sampling sub-cell centres is the midpoint rule, whose errors over a sphere's surface largely
    cancel (measured here: order 2.07, error ratios 3.9, 4.6 and 3.9 per doubling). Asserted: order above 1.7 and
    every ratio above 3, where sampling sub-cell corners (a half-cell shift) would give order 1 and ratios near 2."""
    rng = np.random.default_rng(11)
    centers, radii = nonoverlapping(rng, 40, 3.0, 0.15, 0.45)
    args = (centers, radii, [0, 0, 0], [3.0] * 3, (3, 3, 3))
    exact = 1.0 - oracle_solid(*args)
    errors = [np.sqrt(np.mean((porosity(*args, subdivisions=s, device=device) - exact) ** 2)) for s in (4, 8, 16, 32)]
    assert all(b < a / 3 for a, b in itertools.pairwise(errors)), errors
    order = -np.polyfit(np.log([4, 8, 16, 32]), np.log(errors), 1)[0]
    assert order > 1.7, (order, errors)


def test_voxel_union_on_overlapping_packing(device):
    """Overlapping spheres: the union (voxel) never has less porosity than the exact sum beyond its resolution,
    converges as subdivisions grow, and for two spheres tends to the analytic union volume."""
    rng = np.random.default_rng(5)
    centers = rng.uniform(0, 2, (120, 3))
    radii = rng.uniform(0.15, 0.35, 120)
    args = (centers, radii, [0, 0, 0], [2.0] * 3, (2, 2, 2))
    exact = porosity(*args, method="exact", device=device)
    vox = {s: porosity(*args, subdivisions=s, device=device) for s in (4, 8, 16, 32)}
    assert np.all(vox[32] >= exact - 0.01)
    assert np.mean(vox[32] - exact) > 0.05  # the overlaps the sum counts twice
    steps = [np.abs(vox[b] - vox[a]).max() for a, b in ((4, 8), (8, 16), (16, 32))]
    assert steps[2] < steps[0], steps
    # Two spheres of radius 1, centres 1 apart, in one cell: union = 2 V - lens.
    d, r = 1.0, 1.0
    lens = np.pi * (4 * r + d) * (2 * r - d) ** 2 / 12
    union = 2 * 4 / 3 * np.pi - lens
    p = porosity(
        [[2.0, 2.0, 2.0], [3.0, 2.0, 2.0]], [r, r], [0, 0, 0], [5, 4, 4], (1, 1, 1), subdivisions=64, device=device
    )
    assert abs((1 - p[0, 0, 0]) * 80 - union) < 0.01 * union  # r is 13-16 sub-cells: about 0.5% off


@pytest.mark.filterwarnings("ignore:subdivisions. with")  # r = 1 sub-cell: the rounding warning is the point
def test_midpoint_algorithm_1_reproduces_paper_table_1(device):
    """Sub-cells marked for radius 1 ... 25 equal the paper's Table 1, in the reference and in the kernel."""
    counts = [len(midpoint_sphere_offsets(r)) for r in range(1, 26)]
    assert counts == PAPER_TABLE_1
    for r in (1, 7, 10, 25):
        n = 2 * r + 3
        p = porosity(
            [[r + 1.5, r + 1.5, r + 1.5]],
            [float(r)],
            [0, 0, 0],
            [n, n, n],
            (1, 1, 1),
            method="midpoint",
            subdivisions=n,
            midpoint_algorithm=1,
            device=device,
        )
        assert round((1 - p[0, 0, 0]) * n**3) == PAPER_TABLE_1[r - 1]


def test_midpoint_discriminant_picks_the_cheaper_algorithm():
    """Section 2.3: Algorithm 2 only when the spheres' summed sub-cell volume exceeds 8 K R^3."""
    assert midpoint_choice(np.full(100, 10), 10**9) == 1
    assert midpoint_choice(np.full(100, 3), 50) == 2  # 100 * 4/3 pi 27 = 11310 > 8 * 50 * 27 = 10800


def test_sum_methods_return_unclamped_negative_porosity(device, rng):
    """Dense overlapping packing: centroid and polyhedron give porosity <= 0 in places, returned as is."""
    centers = rng.uniform(0, 1, (400, 3))
    radii = np.full(400, 0.08)
    for method in ("centroid", "polyhedron"):
        p = porosity(centers, radii, [0, 0, 0], [1, 1, 1], (5, 5, 5), method=method, device=device)
        assert p.min() < 0
    assert porosity(centers, radii, [0, 0, 0], [1, 1, 1], (5, 5, 5), device=device).min() > 0


def test_kozeny_carman():
    """The paper's form, constant above 0.7, and a clear error at porosity <= 0."""
    r = 0.001
    k = kozeny_carman([0.3, 0.7, 0.9], r)
    np.testing.assert_allclose(k[0], 0.3**3 / 0.7**2 * (2 * r) ** 2 / 180)
    assert k[2] == k[1]
    with pytest.raises(ValueError, match=r"porosity: must be in \(0, 1\]; index \(1,\) is"):
        kozeny_carman([0.3, 0.0, 0.5], r)
    with pytest.raises(ValueError, match=r"porosity: must be in \(0, 1\]; index \(0, 1\)"):
        kozeny_carman([[0.3, np.nan]], r)
    with pytest.raises(ValueError, match=r"particle_radius"):
        kozeny_carman(0.3, -1.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"centers": [[0, 0, 0], [np.nan, 0, 0]]}, r"centers: non-finite value at index 1"),
        ({"radii": [0.1, np.inf]}, r"radii: must be finite and > 0; index 1"),
        ({"radii": [0.1, 0.0]}, r"radii: must be finite and > 0; index 1"),
        ({"shape": (2, 0, 2)}, r"shape: every entry must be >= 1; index 1 is 0"),
        ({"lower": [0, 0, 1]}, r"upper: must exceed lower on every axis; axis 2"),
        ({"method": "magic"}, r"method: unknown 'magic'"),
        ({"subdivisions": 0}, r"subdivisions: expected an integer >= 1"),
        ({"subdivisions": 2.5}, r"subdivisions: expected an integer >= 1"),
        (
            {"subdivisions": 4000},
            r"subdivisions: \(4000, 4000, 4000\) on shape \(2, 2, 2\) gives .* sub-cells and a .* bitmap, .* over the "
            r"budget of max_bytes = 2,147,483,648 bytes",
        ),
    ],
)
def test_bad_input(kwargs, match):
    """Bad input names the argument and, for data, the first bad index; nothing is computed."""
    args = {
        "centers": [[0.1, 0.1, 0.1], [0.5, 0.5, 0.5]],
        "radii": [0.1, 0.2],
        "lower": [0, 0, 0],
        "upper": [1, 1, 1],
        "shape": (2, 2, 2),
        **kwargs,
    }
    with pytest.raises(ValueError, match=match):
        porosity(
            args.pop("centers"), args.pop("radii"), args.pop("lower"), args.pop("upper"), args.pop("shape"), **args
        )


porosity_module = importlib.import_module("warp_lamp.porosity")

reference_module = importlib.import_module("warp_lamp.reference.porosity")

HS = np.array([0.25, 0.25, 0.25])

SHAPE = (24, 16, 20)

CASES = [
    ((3.0, 2.0, 2.5), 0.625, (12, 8, 10), 2),  # r/h = 2.5: ties to even, 2
    ((3.0, 2.0, 2.5), 0.875, (12, 8, 10), 4),  # 3.5: to even, 4
    ((3.0, 2.0, 2.5), 0.7, (12, 8, 10), 3),  # 2.8
    ((2.99, 1.99, 2.49), 0.6, (11, 7, 9), 2),  # just below a sub-cell corner: floor, not nearest
    ((0.249, 0.249, 0.249), 0.25, (0, 0, 0), 1),
    ((3.2, 2.3, 2.6), 0.05, (12, 9, 10), 1),  # r/h = 0.2 rounds to 0: at least 1
    ((-0.1, 2.0, 2.5), 1.0, (-1, 8, 10), 4),  # centre outside the box: floor, -1, not 0
]


def marked(centre, radius, algorithm, device):
    """Solid sub-cells of one sphere on the grid (one sub-cell per cell), by the library."""
    upper = HS * SHAPE
    eps = porosity(
        [centre],
        [radius],
        [0, 0, 0],
        upper,
        SHAPE,
        method="midpoint",
        subdivisions=1,
        midpoint_algorithm=algorithm,
        device=device,
    )
    return {tuple(int(x) for x in p) for p in np.argwhere(eps == 0.0)}


def expected(cell, rad, algorithm):
    """Algorithm 1: the paper's traversal pattern of radius rad around cell; Algorithm 2: the sub-cells with
    |p - c|^2 - r^2 < 0. Clipped to the grid."""
    if algorithm == 1:
        pts = midpoint_sphere_offsets(rad) + np.asarray(cell)
    else:
        r = range(-rad, rad + 1)
        pts = np.array([(i, j, k) for i in r for j in r for k in r if i * i + j * j + k * k < rad * rad]) + cell
    inside = np.all((pts >= 0) & (pts < np.asarray(SHAPE)), axis=1)
    return {tuple(int(x) for x in p) for p in pts[inside]}


@pytest.mark.filterwarnings("ignore:subdivisions. with")  # radii of 1 sub-cell on purpose: the rounding warns
@pytest.mark.parametrize("algorithm", [1, 2])
@pytest.mark.parametrize(("centre", "radius", "cell", "rad"), CASES)
def test_midpoint_rounds_centres_down_and_radii_to_nearest_even(device, centre, radius, cell, rad, algorithm):
    """The sub-cells the midpoint method marks for one sphere are the pattern of the hand-rounded centre and
    radius, for both of the paper's algorithms; the float64 reference marks the same."""
    got = marked(centre, radius, algorithm, device)
    want = expected(cell, rad, algorithm)
    assert got == want
    ref = porosity_reference(
        [centre],
        [radius],
        [0, 0, 0],
        HS * SHAPE,
        SHAPE,
        method="midpoint",
        subdivisions=1,
        midpoint_algorithm=algorithm,
    )
    assert {tuple(int(x) for x in p) for p in np.argwhere(ref == 0.0)} == want


def test_reference_does_not_borrow_the_library_rounding(monkeypatch):
    """The reference's midpoint inputs are its own: it imports nothing from ``warp_lamp.porosity``, and breaking
    the library's rounding does not change the reference's answer."""
    tree = ast.parse(inspect.getsource(reference_module))
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            assert node.module != "warp_lamp.porosity", ast.dump(node)
        if isinstance(node, ast.Import):
            assert all(a.name != "warp_lamp.porosity" for a in node.names)
    args = ([[3.0, 2.0, 2.5], [1.3, 2.2, 4.4]], [0.875, 0.6], [0, 0, 0], HS * SHAPE, SHAPE)
    before = porosity_reference(*args, method="midpoint", subdivisions=1)
    monkeypatch.setattr(porosity_module, "_midpoint_spheres", lambda local, radii, hs: (None, None))
    np.testing.assert_array_equal(porosity_reference(*args, method="midpoint", subdivisions=1), before)


C3 = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

R3 = np.array([0.5, 0.5, 0.5])


def test_midpoint_on_tall_cells_measures_a_sphere_not_an_ellipsoid(device):
    """A sphere in a cell twice as tall as wide: midpoint (cubic sub-cells) agrees with the exact volume to its
    resolution, as voxel does; stretched sub-cells used to count the sphere as an ellipsoid (0.800 vs 0.866)."""
    args = ([[0.5, 0.5, 1.0]], [0.4], [0, 0, 0], [1, 1, 2], (1, 1, 1))
    exact = wl.porosity(*args, method="exact", device=device)[0, 0, 0]
    mid = wl.porosity(*args, method="midpoint", subdivisions=32, device=device)[0, 0, 0]
    vox = wl.porosity(*args, method="voxel", subdivisions=32, device=device)[0, 0, 0]
    assert abs(vox - exact) < 2e-3
    assert abs(mid - exact) < 5e-3, (mid, exact)
    # The same call with the cubic sub-cells spelled out, and the reference, agree bitwise.
    per_axis = wl.porosity(*args, method="midpoint", subdivisions=(32, 32, 64), device=device)[0, 0, 0]
    assert per_axis == mid == porosity_reference(*args, method="midpoint", subdivisions=32)[0, 0, 0]


def test_midpoint_refuses_cells_that_cannot_be_cut_into_cubes():
    """Cells whose edges are not whole multiples of one sub-cell, and non-cubic per-axis counts, are refused."""
    with pytest.raises(ValueError, match=r"subdivisions: midpoint needs cubic sub-cells.*method='voxel'"):
        wl.porosity([[0.5, 0.5, 0.5]], [0.3], [0, 0, 0], [1.0, 1.0, 1.37], (1, 1, 1), method="midpoint")
    with pytest.raises(ValueError, match=r"subdivisions: midpoint needs cubic sub-cells, but \(8, 8, 8\)"):
        wl.porosity([[0.5, 0.5, 0.5]], [0.3], [0, 0, 0], [1, 1, 2], (1, 1, 1), method="midpoint", subdivisions=(8,) * 3)
    from warp_lamp.porosity import midpoint_subdivisions

    assert midpoint_subdivisions([1.0, 1.0, 2.0], 8, per_axis=False) == (8, 8, 16)
    assert midpoint_subdivisions([0.3, 0.1, 0.2], 5, per_axis=False) == (15, 5, 10)


@pytest.mark.filterwarnings("ignore:porosity. all 1 spheres")  # r <= 2: the clipped sphere misses the box
@pytest.mark.filterwarnings("ignore:subdivisions. with")  # r = 1 sub-cell: rounding warns, Table 1 is still exact
@pytest.mark.parametrize("r", [1, 2, 3, 9, 10, 17, 24])
def test_midpoint_kernel_marks_exactly_the_paper_recurrence(r):
    """The kernel's closed-form rows equal the literal midpoint recurrence, sub-cell by sub-cell, for a whole
    sphere and for one clipped by the box (centre outside it)."""
    n = 2 * r + 3
    for centre, box in (((r + 1.5,) * 3, (n, n, n)), ((-2.5, r / 2 + 0.5, r + 1.5), (r + 2, r + 1, n))):
        p = wl.porosity([centre], [float(r)], [0, 0, 0], box, box, method="midpoint", subdivisions=1, device="cpu")
        got = {tuple(int(x) for x in ijk) for ijk in np.argwhere(p == 0.0)}
        c = np.floor(centre).astype(int)
        want = {
            tuple(int(x) for x in o + c)
            for o in midpoint_sphere_offsets(r)
            if np.all(o + c >= 0) and np.all(o + c < np.asarray(box))
        }
        assert got == want


def test_midpoint_work_is_clipped_to_the_box():
    """A sphere of radius 10 km around a 1 m box takes the box's rows, not r^2 of them; radius 1e9 m is refused
    by name, not passed to an overflowing hash grid."""
    t0 = time.perf_counter()
    p = wl.porosity([[0.5, 0.5, 0.5]], [1e4], [0, 0, 0], [1, 1, 1], (1, 1, 1), method="midpoint", device="cpu")
    assert p[0, 0, 0] == 0.0
    assert time.perf_counter() - t0 < 2.0
    with pytest.raises(ValueError, match=r"radii: sphere 0 is 8e\+09 sub-cells in radius"):
        wl.porosity([[0.5, 0.5, 0.5]], [1e9], [0, 0, 0], [1, 1, 1], (1, 1, 1), method="midpoint", device="cpu")
    # A huge sphere that does not reach the box is dropped, whatever its size.
    with pytest.warns(RuntimeWarning, match="wholly outside"):
        far = wl.porosity([[0.5, 0.5, -3e9]], [1e9], [0, 0, 0], [1, 1, 1], (1, 1, 1), method="midpoint", device="cpu")
    assert far[0, 0, 0] == 1.0


def test_voxel_counts_do_not_overflow_in_a_cell_of_more_than_2_31_sub_cells():
    """One full cell of 1291^3 > 2^31 sub-cells has porosity 0, not 1.955 from a wrapped int32 count."""
    p = wl.porosity([[0.5, 0.5, 0.5]], [1.0], [0, 0, 0], [1, 1, 1], (1, 1, 1), subdivisions=1291, device="cpu")
    assert p[0, 0, 0] == 0.0


def test_porosity_sum_methods_check_their_memory_first():
    """A 10^15-cell exact or centroid request names the shape, the bytes and max_bytes, before any allocation."""
    for method in ("exact", "centroid", "polyhedron"):
        with pytest.raises(
            ValueError,
            match=r"shape: \(100000, 100000, 100000\) cells and 3 spheres need 8,000,000,000,000,096 bytes .*"
            r"over the budget of max_bytes = 2,147,483,648 bytes",
        ):
            wl.porosity(C3, R3, [-1] * 3, [2] * 3, (100000,) * 3, method=method)


def test_union_budget_covers_the_per_cell_counts():
    """The union methods' budget counts the int64 per-cell counts as well as the bitmap."""
    from warp_lamp.porosity import porosity_nbytes

    shape = (100, 100, 100)
    bitmap = 4 * 4 * 100 * 100
    assert porosity_nbytes(shape, method="voxel", subdivisions=1, n_spheres=3) == bitmap + 8 * 10**6 + 96
    with pytest.raises(ValueError, match=r"subdivisions: \(1, 1, 1\) on shape \(100, 100, 100\) .* max_bytes = "):
        wl.porosity(C3, R3, [-1] * 3, [2] * 3, shape, subdivisions=1, max_bytes=10**6)
    assert wl.porosity(C3, R3, [-1] * 3, [2] * 3, shape, subdivisions=1, max_bytes=9 * 10**6).shape == shape


def test_midpoint_warns_exactly_when_rounding_doubles_the_volume():
    """The midpoint method's warning follows its rule: it rounds a radius below a sub-cell up to one whole sub-cell
    (volume 1), so spheres of radius 0.48 sub-cells get 1 / (4/3 pi 0.48^3) = 2.16 times their volume (warns,
    over :data:`MIDPOINT_VOLUME_FACTOR` = 2) and spheres of 0.52 get 1.70 (silent)."""
    centers = np.array([[2.5, 2.5, 2.5], [5.5, 5.5, 5.5]])
    for radius, warns in ((0.48, True), (0.52, False)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            wl.porosity(centers, radius, [0] * 3, [8] * 3, (2, 2, 2), method="midpoint", subdivisions=4)
        said = [str(w.message) for w in caught if "subdivisions: with" in str(w.message)]
        assert bool(said) == warns, (radius, said)
        if warns:
            assert "gives them 2 times their true volume" in said[0]


def test_porosity_warns_when_the_box_and_the_spheres_cannot_match():
    """Spheres in metres against a box in millimetres (none reaches the box, or they fill under 1e-9 of it) warn."""
    centers = np.random.default_rng(1).uniform(0, 0.1, (50, 3))
    with pytest.warns(RuntimeWarning, match=r"all 50 spheres lie wholly outside the box"):
        wl.porosity(centers, 0.0025, [100] * 3, [200] * 3, (2, 2, 2), method="exact")
    with pytest.warns(RuntimeWarning, match=r"share one unit"):
        wl.porosity(centers, 0.0025, [0] * 3, [100] * 3, (2, 2, 2), method="exact")
