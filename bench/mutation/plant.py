"""Before/after evidence for the tests/test_catch_*.py files: plant each class of bug in a copy, run the tests.

    python bench/mutation/plant.py                       # every bug: new tests on the real code, then on the bug
    python bench/mutation/plant.py --old-suite 9e86fd1   # also the whole suite of that revision on each bug
    python bench/mutation/plant.py span_pad cell_area_kernel   # only these

Each bug is a textual edit of one file (it must match exactly once) in a temporary copy of warp_lamp/, examples/ and
tests/ (from this working tree); the copy's tests run with PYTHONPATH at the copy. The output is a Markdown table
(``--out`` to keep it: bench/mutation/PLANTED.md).
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


@dataclass
class Bug:
    name: str
    issue_class: str
    path: str
    old: str
    new: str
    tests: tuple[str, ...]


NONDYADIC = ("tests/test_lamp.py",)
ANISO = ("tests/test_lamp.py",)
PARTIAL = ("tests/test_lamp.py",)
MIDPOINT = ("tests/test_porosity.py",)
MEASURES = ("tests/test_measures.py",)
CLI = ("tests/test_cli.py",)
SPHERE = ("tests/test_examples.py::test_sphere_test_reaches_equilibrium_at_the_applied_pressure",)
TIGHT = ("tests/test_lamp.py::test_lone_sphere_force_converges_to_disk_area",)
VOXEL_ORDER = ("tests/test_porosity.py::test_voxel_error_falls_with_subdivisions_on_nonoverlapping_packing",)

BUGS = [
    Bug(
        "span_pad",
        "exact cell boundaries, non-dyadic cells",
        "warp_lamp/kernels/footprint.py",
        "tol = type(lo)(0.0009765625) + (wp.abs(x) + wp.abs(y)) * type(lo)(9.5367431640625e-07)",
        "tol = type(lo)(0.0)",
        NONDYADIC,
    ),
    Bug(
        "cell_area_kernel",
        "non-cubic cells",
        "warp_lamp/kernels/lamp.py",
        "x = (p[a] * area[a]) * wp.float64(rotation[j, a])",
        "x = (p[a] * area[0]) * wp.float64(rotation[j, a])",
        ANISO,
    ),
    Bug(
        "cell_area_host",
        "non-cubic cells",
        "warp_lamp/lamp.py",
        "return self.grid.cell_area / (self.estimator.unit / self._weight)",
        "return np.full(3, self.grid.cell_area[0]) / (self.estimator.unit / self._weight)",
        ANISO,
    ),
    Bug(
        "cell_area_grid",
        "non-cubic cells",
        "warp_lamp/grid.py",
        "return self.cell[:, 0] * self.cell[:, 1]",
        "return self.cell[:, 0] * self.cell[:, 0]",
        ANISO,
    ),
    Bug(
        "voxel_axis",
        "non-cubic cells (porosity)",
        "warp_lamp/kernels/porosity.py",
        "ks = cell_span(c[2] - ry, c[2] + ry, hs[2], sub[2], RAY_CENTRE)",
        "ks = cell_span(c[2] - ry, c[2] + ry, hs[1], sub[2], RAY_CENTRE)",
        ANISO,
    ),
    Bug(
        "frames_cubic_check",
        "non-cubic cells (frame averaging; a mutation-run survivor)",
        "warp_lamp/grid.py",
        "if not self.is_box or np.ptp(h) > 0:",
        "if not self.is_box and np.ptp(h) > 0:",
        ANISO,
    ),
    Bug(
        "frames_pressure_check",
        "non-cubic cells (frame averaging; a mutation-run survivor)",
        "warp_lamp/lamp.py",
        "if frames > 1 and np.ptp(p) > 0:",
        "if frames > 2 and np.ptp(p) > 0:",
        ANISO,
    ),
    Bug(
        "bvh_corner_sign",
        "non-cubic cells (memo-form grids, the BVH peer; a mutation-run survivor)",
        "warp_lamp/kernels/peers.py",
        "dv = v - (p[(a + 2) % 3] - corner_v)",
        "dv = v - (p[(a + 2) % 3] + corner_v)",
        ANISO,
    ),
    Bug(
        "floor_counts",
        "a box that is not a whole number of cells",
        "warp_lamp/grid.py",
        "n = np.maximum(np.ceil((upper - lower) / h), 1.0)",
        "n = np.maximum(np.floor((upper - lower) / h), 1.0)",
        PARTIAL,
    ),
    Bug(
        "midpoint_radius",
        "the midpoint rasteriser's inputs",
        "warp_lamp/porosity.py",
        "rad = np.maximum(np.rint(radii / h), 1.0)",
        "rad = np.maximum(np.floor(radii / h), 1.0)",
        MIDPOINT,
    ),
    Bug(
        "midpoint_centre",
        "the midpoint rasteriser's inputs",
        "warp_lamp/porosity.py",
        "centers = np.floor(local / hs)",
        "centers = np.rint(local / hs)",
        MIDPOINT,
    ),
    Bug(
        "deviator_sign",
        "the bench's error measures",
        "warp_lamp/measures.py",
        "deviator = sigma + mean * np.eye(3)",
        "deviator = sigma - mean * np.eye(3)",
        MEASURES,
    ),
    Bug(
        "rms_as_mean_abs",
        "the bench's error measures",
        "warp_lamp/measures.py",
        "return float(np.sqrt(np.mean(np.square(errs))))",
        "return float(np.mean(np.abs(errs)))",
        MEASURES,
    ),
    Bug(
        "stress_transpose",
        "the bench's error measures",
        "warp_lamp/measures.py",
        'return np.einsum("ni,nj->ij", x, np.asarray(forces, dtype=np.float64)) / float(volume)',
        'return np.einsum("ni,nj->ji", x, np.asarray(forces, dtype=np.float64)) / float(volume)',
        MEASURES,
    ),
    Bug(
        "cli_force_sign",
        "the main job (warp-lamp run)",
        "warp_lamp/cli.py",
        "f = d.counts * pressure_area(P, grid)",
        "f = -d.counts * pressure_area(P, grid)",
        CLI,
    ),
    Bug(
        "cli_stress_volume",
        "the main job (warp-lamp run)",
        "warp_lamp/cli.py",
        "sigma = envelope_stress(scene.centers, f, scene.center, 4.0 / 3.0 * np.pi * R**3)",
        "sigma = envelope_stress(scene.centers, f, scene.center, 4.0 / 3.0 * np.pi * (2 * R) ** 3)",
        CLI,
    ),
    Bug(
        "cli_surface_count",
        "the main job (warp-lamp run)",
        "warp_lamp/cli.py",
        "mag = np.linalg.norm(f, axis=1)",
        "mag = np.abs(f).sum(axis=1)",
        CLI,
    ),
    Bug(
        "cli_pressure",
        "the main job (warp-lamp run)",
        "warp_lamp/cli.py",
        "lamp.add_forces(forces, P)\n    d = lamp.diagnostics(scene.centers, P,",
        "lamp.add_forces(forces, P)\n    d = lamp.diagnostics(scene.centers, 0.5 * P,",
        CLI,
    ),
    Bug(
        "sphere_test_1.05P",
        "the SphereTest tolerance",
        "examples/sphere_test.py",
        "self.lamp.add_forces(self.lamp_force, self.pressure)",
        "self.lamp.add_forces(self.lamp_force, 1.05 * self.pressure)",
        SPHERE,
    ),
    Bug(
        "sphere_test_0.95P",
        "the SphereTest tolerance",
        "examples/sphere_test.py",
        "self.lamp.add_forces(self.lamp_force, self.pressure)",
        "self.lamp.add_forces(self.lamp_force, 0.95 * self.pressure)",
        SPHERE,
    ),
    Bug(
        "lone_sphere_area_1%",
        "loose tolerance: lone-sphere convergence",
        "warp_lamp/measures.py",
        "errs.extend(lit[name] * h * h / (np.pi * r * r) - 1.0 for name in LAMPS)",
        "errs.extend(lit[name] * h * h * 1.01 / (np.pi * r * r) - 1.0 for name in LAMPS)",
        TIGHT,
    ),
    Bug(
        "voxel_half_subcell_shift",
        "loose tolerance: voxel convergence order",
        "warp_lamp/porosity.py",
        "cen = local if isinstance(local, wp.array) else wp.array(local, dtype=wp.vec3d, device=device)",
        "cen = local if isinstance(local, wp.array) else wp.array(local + 0.5 * np.asarray(hs), dtype=wp.vec3d, "
        "device=device)",
        VOXEL_ORDER,
    ),
]


def _copy(dest: Path) -> None:
    for name in ("warp_lamp", "examples", "tests"):
        shutil.copytree(ROOT / name, dest / name, ignore=shutil.ignore_patterns("__pycache__", ".hypothesis"))
    shutil.copy(ROOT / "pyproject.toml", dest / "pyproject.toml")


def _pytest(code: Path, tests, timeout=900) -> tuple[str, float]:
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *tests],
        cwd=code,
        env={**__import__("os").environ, "PYTHONPATH": str(code), "PYTHONDONTWRITEBYTECODE": "1"},
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    tail = [x for x in proc.stdout.strip().splitlines() if re.search(r"\d+ (passed|failed|error)", x)]
    return (tail[-1].strip("= ") if tail else f"exit {proc.returncode}"), time.perf_counter() - t0


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("bugs", nargs="*", help="names of bugs to plant (default: all)")
    parser.add_argument("--old-suite", metavar="REV", help="also run that revision's whole tests/ on each bug")
    parser.add_argument("--out", help="write the Markdown table there")
    args = parser.parse_args(argv)
    bugs = [b for b in BUGS if not args.bugs or b.name in args.bugs]
    lines = [
        "| bug | class | file | new tests, real code | new tests, bug planted |"
        + (f" suite of {args.old_suite}, bug planted |" if args.old_suite else ""),
        "| --- | --- | --- | --- | --- |" + (" --- |" if args.old_suite else ""),
    ]
    with tempfile.TemporaryDirectory(prefix="warp_lamp_plant_") as tmp:
        clean = Path(tmp) / "clean"
        _copy(clean)
        clean_result = {}
        for b in bugs:
            if b.tests not in clean_result:
                clean_result[b.tests] = _pytest(clean, b.tests)[0]
        for b in bugs:
            code = Path(tmp) / b.name
            _copy(code)
            path = code / b.path
            text = path.read_text()
            if text.count(b.old) != 1:
                sys.exit(f"{b.name}: the edit must match {b.path} exactly once, found {text.count(b.old)}")
            path.write_text(text.replace(b.old, b.new))
            planted, _ = _pytest(code, b.tests)
            row = f"| `{b.name}` | {b.issue_class} | `{b.path}` | {clean_result[b.tests]} | {planted} |"
            if args.old_suite:
                old = Path(tmp) / f"{b.name}-old"
                shutil.copytree(code, old)
                shutil.rmtree(old / "tests")
                archive = subprocess.run(
                    ["git", "-C", str(ROOT), "archive", args.old_suite, "tests"], check=True, capture_output=True
                )
                subprocess.run(["tar", "x", "-C", str(old)], input=archive.stdout, check=True)
                row += f" {_pytest(old, ['tests'])[0]} |"
            print(row, flush=True)
            lines.append(row)
    table = "\n".join(lines) + "\n"
    if args.out:
        Path(args.out).write_text(table)
    print(table)


if __name__ == "__main__":
    main()
