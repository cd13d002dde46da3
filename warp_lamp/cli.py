"""The warp-lamp command: fluid pressure on a built-in body of spheres, and the benchmarks.

Commands: run (the default) loads the built-in SphereTest specimen with fluid pressure and reports the forces;
bench times the lamp (bench lamp) or the porosity methods (bench porosity) against their error and their peers.
Every mistake in the arguments is reported in one line, with the usage, before anything long starts.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import sys
import time

import numpy as np

__all__ = ["main"]

#: The install command for an extra, from a clone and from an installed package.
_INSTALL = "pip install '.[{0}]' in a clone of warp_lamp, or pip install 'warp-lamp[{0}]'"


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """The description kept as written, and each option's default shown where it has one."""

    def _get_help_string(self, action):
        text = action.help or ""
        if action.default not in (None, False, argparse.SUPPRESS) and action.option_strings and "default" not in text:
            text += " (default: %(default)s)"
        return text


class CliError(Exception):
    """A mistake in the command line, found after parsing (device, paths, extras): one line, then the usage."""


def _number(kind: str, *, positive: bool = True, allow_zero: bool = False):
    """An argparse type: a finite float (> 0, or >= 0 with ``allow_zero``), or an int >= 1 (``kind="int"``)."""

    def convert(text: str):
        try:
            value = int(text) if kind == "int" else float(text)
        except ValueError:
            what = "an integer" if kind == "int" else "a number"
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if kind != "int" and not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
        if positive and (value < 0 or (value == 0 and not allow_zero)):
            raise argparse.ArgumentTypeError(f"must be {'>= 0' if allow_zero else '> 0'}, got {text!r}")
        return value

    convert.__name__ = kind  # argparse names the type in its messages
    return convert


_FLOAT = _number("float")
_COUNT = _number("int")


def _version() -> str:
    import warp_lamp

    return f"warp-lamp {warp_lamp.__version__}"


def _parser() -> tuple[argparse.ArgumentParser, dict]:
    parser = argparse.ArgumentParser(prog="warp-lamp", description=__doc__, formatter_class=_Formatter)
    parser.add_argument("--version", action="version", version=_version())
    sub = parser.add_subparsers(dest="command", metavar="{run,bench}")
    run = sub.add_parser(
        "run",
        help="pressure on the built-in 100 mm SphereTest specimen of 5 mm particles (the default)",
        description="Load the built-in SphereTest specimen (4,628 particles, 100 mm) with fluid pressure, time the "
        "lamp's update and report the balance, the forces and the stress they imply.",
        formatter_class=_Formatter,
    )
    for p in (parser, run):
        p.add_argument("--device", default=None, help="Warp device, e.g. cpu or cuda:0 (default: Warp's default)")
        p.add_argument(
            "--cells-per-diameter",
            type=_FLOAT,
            default=4.0,
            metavar="K",
            help="lamp cells per mean particle diameter",
        )
        p.add_argument("--criterion", type=int, default=1, choices=(0, 1), help="1: cell-centre ray, 0: overlap")
        p.add_argument("--pressure", type=_FLOAT, default=10e6, metavar="PA", help="fluid pressure [Pa], > 0")
        p.add_argument("--repeats", type=_COUNT, default=5, metavar="N", help="timed updates")
        p.add_argument("--json", metavar="PATH", help="also write the report as JSON")
        p.add_argument(
            "--vtk", metavar="DIR", help="write per-particle forces and a porosity grid as VTK files (needs pyevtk)"
        )
    bench = sub.add_parser(
        "bench",
        help="speed against error, on every device present, with peers",
        description="Time the lamp (bench lamp) or the porosity methods (bench porosity) against their error.",
        formatter_class=_Formatter,
    )
    bench.add_argument("what", nargs="?", default="lamp", choices=("lamp", "porosity"), help="what to benchmark")
    bench.add_argument("--paper", action="store_true", help="porosity: also reproduce the paper's Table 1 and 3.2")
    bench.add_argument("--target", action="store_true", help="porosity: also time the 1 mm, 0.1 mm target scene")
    bench.add_argument("--histograms", metavar="PATH", help="porosity --paper: histograms as a PNG (needs matplotlib)")
    bench.add_argument("--quick", action="store_true", help="a CPU-sized subset, under a minute")
    bench.add_argument("--device", action="append", help="a Warp device to time (repeatable; default: all)")
    bench.add_argument("--json", metavar="PATH", help="write the results as JSON")
    bench.add_argument("--plot", metavar="PATH", help="lamp: time against error as a PNG (needs matplotlib)")
    bench.add_argument("--repeats", type=_COUNT, default=None, metavar="N", help="lamp: timed repeats per figure")
    bench.add_argument("--no-progress", action="store_true", help="no progress bar")
    bench.add_argument("--from-json", metavar="PATH", help="print and plot a saved result instead of measuring")
    return parser, {"run": run, "bench": bench}


def _check_device(name: str | None):
    """The Warp device called ``name``, or CliError saying which exist (and that there is no GPU, if so)."""
    import warp as wp

    try:
        return wp.get_device(name)
    except (ValueError, RuntimeError):
        present = ", ".join(d.alias for d in wp.get_devices())
        if str(name).startswith("cuda") and wp.get_cuda_device_count() == 0:
            raise CliError(
                f"--device {name}: this machine has no CUDA GPU that Warp can use; use --device cpu"
            ) from None
        raise CliError(f"--device {name}: no such Warp device; present: {present}") from None


def _check_output(flag: str, path: str, *, directory: bool = False) -> None:
    """An output path that can be written: its folder exists and is writable, and it is not a folder (or, for
    ``directory``, it is one or can be made)."""
    target = os.path.abspath(path)
    if directory:
        if os.path.isdir(target):
            if not os.access(target, os.W_OK):
                raise CliError(f"{flag} {path}: the folder is not writable")
            return
        if os.path.exists(target):
            raise CliError(f"{flag} {path}: exists and is not a folder")
    elif os.path.isdir(target):
        raise CliError(f"{flag} {path}: is a folder, expected a file name")
    parent = os.path.dirname(target)
    if not os.path.isdir(parent):
        raise CliError(f"{flag} {path}: the folder {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise CliError(f"{flag} {path}: the folder {parent} is not writable")


def _need_extra(flag: str, module: str, extra: str) -> None:
    if importlib.util.find_spec(module) is None:
        raise CliError(f"{flag} needs {module}, which is not installed: {_INSTALL.format(extra)}")


def _load_json(path: str) -> dict:
    try:
        with open(path) as f:
            data = json.load(f)
    except OSError as e:
        raise CliError(f"--from-json {path}: cannot read it ({e.strerror or e})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise CliError(f"--from-json {path}: not a JSON file ({e})") from None
    if not isinstance(data, dict):
        raise CliError(f"--from-json {path}: expected a JSON object of results, got {type(data).__name__}")
    return data


def _write_json(path: str, data: dict) -> None:
    with open(path, "w") as f:
        json.dump(data, f, indent=1)


def _check_args(parser, args) -> None:
    """Every check that can be made before the work starts: flags the command does not use, output paths,
    optional extras, devices, saved results."""
    if args.command == "bench":
        lamp_only = {"--plot": args.plot, "--repeats": args.repeats}
        porosity_only = {"--paper": args.paper, "--target": args.target, "--histograms": args.histograms}
        unused = lamp_only if args.what == "porosity" else porosity_only
        for flag, value in unused.items():
            if value not in (None, False):
                raise CliError(f"{flag} is not used by bench {args.what}")
        if args.from_json:
            measuring = {"--quick": args.quick, "--device": args.device, "--repeats": args.repeats}
            measuring["--target"] = args.target
            for flag, value in measuring.items():
                if value not in (None, False):
                    raise CliError(f"{flag} is not used with --from-json, which measures nothing")
            args.saved = _load_json(args.from_json)
            if args.histograms and not args.saved.get("paper"):
                raise CliError(f"--histograms: {args.from_json} holds no --paper results to draw")
        elif args.histograms and not args.paper:
            raise CliError("--histograms draws the --paper experiment: add --paper")
        for flag in ("--json", "--plot", "--histograms"):
            path = getattr(args, flag[2:])
            if path:
                _check_output(flag, path)
        if args.plot:
            _need_extra("--plot", "matplotlib", "plot")
        if args.histograms:
            _need_extra("--histograms", "matplotlib", "plot")
        if not args.from_json:
            args.devices = [_check_device(d) for d in args.device] if args.device else None
        return
    if args.json:
        _check_output("--json", args.json)
    if args.vtk:
        _check_output("--vtk", args.vtk, directory=True)
        _need_extra("--vtk", "pyevtk", "vtk")
    args.devices = [_check_device(args.device)]


def main(argv=None) -> int:
    """Run the command line ``argv`` (default: ``sys.argv[1:]``); returns the exit status."""
    parser, commands = _parser()
    args = parser.parse_args(argv)
    # Errors found after parsing are reported with the usage of the command that was given.
    usage = commands.get(args.command, parser)
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    wp.config.quiet = True
    try:
        wp.init()
        _check_args(parser, args)
        if args.command == "bench":
            return _bench_porosity(args) if args.what == "porosity" else _bench(args)
        return _run(args)
    except CliError as e:
        usage.error(str(e))
    except (ValueError, OSError) as e:
        # Input that passed the parser but not the library (a grid over its memory budget, say): one line too.
        usage.error(str(e))
    return 2


def _run(args) -> int:
    import warp as wp

    from warp_lamp import LampGrid, ShiningLamp, porosity
    from warp_lamp.lamp import pressure_area
    from warp_lamp.measures import envelope_stress
    from warp_lamp.scenes import scene_sphere_specimen

    device = args.devices[0]
    print(
        "warp-lamp: loading the SphereTest specimen and the kernels; the first run builds and compiles them "
        "(about 10 s, cached), later runs start in a second or two",
        file=sys.stderr,
        flush=True,
    )
    scene = scene_sphere_specimen()
    P, cpd = args.pressure, args.cells_per_diameter
    grid = LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=cpd)
    lamp = ShiningLamp(grid, criterion=args.criterion, device=device)
    pos = wp.array((scene.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    forces = wp.zeros(scene.n, dtype=wp.vec3, device=device)
    lamp.update(pos, rad, in_frame=True)  # the first call compiles or loads the kernels: not timed
    times = []
    for _ in range(args.repeats):
        wp.synchronize_device(device)
        t0 = time.perf_counter()
        lamp.update(pos, rad, in_frame=True)
        wp.synchronize_device(device)
        times.append(time.perf_counter() - t0)
    lamp.add_forces(forces, P)
    d = lamp.diagnostics(scene.centers, P, moment_origin=scene.center)
    f = d.counts * pressure_area(P, grid)
    mag = np.linalg.norm(f, axis=1)
    R = scene.radius
    sigma = envelope_stress(scene.centers, f, scene.center, 4.0 / 3.0 * np.pi * R**3)
    h = float(grid.cell[0, 0])
    nu, nv = (int(x) for x in grid.counts[0])
    report = {
        "scene": scene.name,
        "particles": int(scene.n),
        "body_diameter_m": 2 * R,
        "mean_particle_diameter_m": float(2 * scene.radii.mean()),
        "pressure_Pa": P,
        "cells_per_diameter": cpd,
        "criterion": args.criterion,
        "device": f"{device.alias} ({device.name})",
        "grid": {
            "cell_m": h,
            "cells_per_grid": [nu, nv],
            "cells": grid.n_cells,
            "bytes": grid.nbytes,
            "origin_m": grid.origin.tolist(),
        },
        "update_ms_median": float(np.median(times) * 1e3),
        "repeats": args.repeats,
        "lit_particles": int(d.surface.sum()),
        "lit_cells": d.lit,
        "force_sum_N": f.sum(axis=0).tolist(),
        "moment_over_PpiR3": float(np.linalg.norm(d.moment) / (P * np.pi * R**3)),
        "force_N": {
            "min_lit": float(mag[d.surface].min()),
            "mean_lit": float(mag[d.surface].mean()),
            "max": float(mag.max()),
            "total": float(mag.sum()),
        },
        "mean_stress_over_P": float(-np.trace(sigma) / 3 / P),
        "skipped": {"invalid": d.invalid, "outside": d.outside},
    }
    print(f"scene      {scene.name}: {scene.n:,} spheres, body diameter {2 * R * 1e3:.0f} mm")
    print(f"pressure   P = {P:.6g} Pa on all six lamps, criterion {args.criterion}")
    print(
        f"grid       cells of {h * 1e3:.4g} mm ({cpd:g} per mean particle diameter of "
        f"{2 * scene.radii.mean() * 1e3:.3g} mm); three grids of {nu} x {nv} cells, {grid.n_cells:,} cells, "
        f"{grid.nbytes:,} bytes"
    )
    print(f"device     {device.alias} ({device.name})")
    print(f"update     {report['update_ms_median']:.3f} ms (median of {args.repeats}, after a first untimed update)")
    print(f"surface    {report['lit_particles']:,} particles lit; cells lit per lamp {d.lit}")
    print(f"balance    sum of forces = {report['force_sum_N']} N (exact zero by construction)")
    print(f"moment     |M| / (P pi R^3) = {report['moment_over_PpiR3']:.3e}")
    fm = report["force_N"]
    print(
        f"forces     |F| on lit particles: min {fm['min_lit']:.4g}, mean {fm['mean_lit']:.4g}, max {fm['max']:.4g} N; "
        f"total |F| {fm['total']:.4g} N"
    )
    print(
        f"stress     mean -tr(sigma)/3P = {report['mean_stress_over_P']:.4f}  "
        "(forces act at particle centres, inside the envelope: expect a little under 1)"
    )
    print(f"skipped    invalid {d.invalid}, outside the grid {d.outside}")
    if args.json:
        _write_json(args.json, report)
        print(f"wrote      {args.json}")
    if args.vtk:
        from warp_lamp.export import write_vtk_particles, write_vtk_porosity

        os.makedirs(args.vtk, exist_ok=True)
        lo, hi = scene.center - R, scene.center + R
        shape = (10, 10, 10)
        eps = porosity(scene.centers, scene.radii, lo, hi, shape, method="voxel", subdivisions=8, device=device)
        a = write_vtk_particles(
            os.path.join(args.vtk, "specimen_forces"), scene.centers, scene.radii, force=f, lit=d.surface
        )
        b = write_vtk_porosity(os.path.join(args.vtk, "specimen_porosity"), eps, lo, hi)
        print(f"wrote      {a} (per-particle radius, force, lit) and {b} (voxel porosity, {shape} cells)")
    return 0


def _bench(args) -> int:
    from warp_lamp.bench import bench_lamp, format_tables, plot

    if args.from_json:
        result = args.saved
    else:
        result = bench_lamp(args.devices, quick=args.quick, progress=not args.no_progress, repeats=args.repeats)
    print(format_tables(result))
    if args.json:
        _write_json(args.json, result)
        print(f"\nwrote {args.json}")
    if args.plot:
        plot(result, args.plot)
        print(f"wrote {args.plot}")
    return 0


def _bench_porosity(args) -> int:
    from warp_lamp import bench_porosity as bp

    if args.from_json:
        result, paper = args.saved.get("bench"), args.saved.get("paper")
    else:
        devices = args.devices
        result = bp.bench_porosity(devices, quick=args.quick, progress=not args.no_progress, target=args.target)
        paper = bp.paper_experiment((devices or [None])[-1], quick=args.quick) if args.paper else None
    print(bp.format_porosity(result, paper))
    if args.json:
        _write_json(args.json, {"bench": result, "paper": paper})
        print(f"\nwrote {args.json}")
    if args.histograms:
        bp.plot_histograms(paper, args.histograms)
        print(f"wrote {args.histograms}")
    return 0
