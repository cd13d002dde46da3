"""The warp-lamp command: fluid pressure on a body of spheres (the built-in specimen, or yours), and the benchmarks.

Commands: run (the default) loads the built-in SphereTest specimen, or your particles (--particles FILE: CSV,
NumPy, VTK points, a LAMMPS/LIGGGHTS dump or YADE's text export), with fluid pressure and reports the forces;
bench times the lamp (bench lamp) or the porosity methods (bench porosity) against their error and their peers.
The options of run may come before the word run or after it (warp-lamp --pressure 5e6 run --json r.json); one
given in both places must agree. bench takes its options after its name.
Every mistake in the arguments is reported in one line, with the usage, before anything long starts.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import json
import math
import os
import re
import sys
import tempfile
import time

import numpy as np

__all__ = ["main"]

#: The install command for an extra, from a clone and from an installed package.
_INSTALL = "pip install '.[{0}]' in a clone of warp_lamp, or pip install 'warp-lamp[{0}]'"

#: The VTK field data's code for each criterion (VTK field data holds numbers).
CRITERION_CODE = {0: 0, 1: 1, "area": 2}


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """The description kept as written, and each option's default shown where it has one."""

    def _get_help_string(self, action):
        text = action.help or ""
        if action.default not in (None, False, argparse.SUPPRESS) and action.option_strings and "default" not in text:
            text += " (default: %(default)s)"
        return text


class CliError(Exception):
    """A mistake in the command line, found after parsing (device, paths, extras): one line, then the usage."""


def _number(kind: str, *, positive: bool = True, allow_zero: bool = False, finite_only: bool = False):
    """An argparse type: a finite float (> 0, or >= 0 with ``allow_zero``; any sign with ``finite_only``), or an
    int >= 1 (``kind="int"``; >= 0 with ``allow_zero``)."""

    def convert(text: str):
        try:
            value = int(text) if kind == "int" else float(text)
        except ValueError:
            what = "an integer" if kind == "int" else "a number"
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if kind != "int" and not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
        if finite_only:
            return value
        if positive and (value < 0 or (value == 0 and not allow_zero)):
            raise argparse.ArgumentTypeError(f"must be {'>= 0' if allow_zero else '> 0'}, got {text!r}")
        return value

    convert.__name__ = kind  # argparse names the type in its messages
    return convert


_FLOAT = _number("float")
_COUNT = _number("int")


def _criterion(text: str):
    if text in ("0", "1"):
        return int(text)
    if text == "area":
        return "area"
    raise argparse.ArgumentTypeError(f"expected 0, 1 or area, got {text!r}")


_criterion.__name__ = "criterion"


def _lamp_list(text: str):
    from warp_lamp.validate import LAMPS

    names = [t for t in re.split(r"[,\s]+", text.strip()) if t]
    if names == ["all"]:
        return "all"
    for name in names:
        if name not in LAMPS:
            raise argparse.ArgumentTypeError(f"unknown lamp {name!r}; expected all, or names from {' '.join(LAMPS)}")
    if not names:
        raise argparse.ArgumentTypeError("expected all, or names such as -x,+x,-y,+y,+z")
    return tuple(dict.fromkeys(names))


_lamp_list.__name__ = "lamps"


def _version() -> str:
    import warp_lamp

    return f"warp-lamp {warp_lamp.__version__}"


#: The options of run: (flags, dest, default, argparse keywords). They may be given before the word run or
#: after it; the parser keeps the two places apart (dests ``top_*`` and ``*``) and :func:`_merge_run_options`
#: joins them, refusing a flag given twice with two values.
_RUN_OPTIONS = [
    # what to load
    (
        ("--particles",),
        "particles",
        None,
        dict(
            metavar="FILE",
            help="your particles instead of the built-in "
            "specimen: CSV with a header (x, y, z, radius or diameter, id), .npy (N x 4) / .npz, VTK points (.vtu/.vtp "
            "with a radius array), a LAMMPS/LIGGGHTS dump, or YADE's text export",
        ),
    ),
    (
        ("--format",),
        "format",
        None,
        dict(
            choices=("csv", "npy", "npz", "vtk", "lammps", "yade"),
            help="--particles: the file's format (default: from its extension, else its content)",
        ),
    ),
    (
        ("--timestep",),
        "timestep",
        None,
        dict(
            type=_number("int", allow_zero=True),
            metavar="N",
            help="--particles: the LAMMPS dump's timestep to read (default: the last)",
        ),
    ),
    (
        ("--scale",),
        "scale",
        None,
        dict(
            type=_FLOAT, metavar="S", help="--particles: multiply every length by S (0.001 for a file in millimetres)"
        ),
    ),
    # the lamp
    (
        ("--device",),
        "device",
        None,
        dict(metavar="NAME", help="Warp device, e.g. cpu or cuda:0 (default: Warp's default)"),
    ),
    (
        ("--cells-per-diameter",),
        "cells_per_diameter",
        4.0,
        dict(type=_FLOAT, metavar="K", help="lamp cells per mean particle diameter"),
    ),
    (
        ("--criterion",),
        "criterion",
        1,
        dict(
            type=_criterion,
            metavar="{0,1,area}",
            help="1: cell-centre ray; 0: overlap; area: each cell's area split among the spheres visible in it",
        ),
    ),
    (
        ("--resolver",),
        "resolver",
        None,
        dict(choices=("subpoints", "exact"), help="--criterion area: how a cell's area is split (default: subpoints)"),
    ),
    (
        ("--subpoints",),
        "subpoints",
        None,
        dict(
            type=_COUNT,
            metavar="N",
            help="--criterion area, --resolver subpoints: N x N points per cell, 1 to 16 (default: 8)",
        ),
    ),
    (
        ("--depth-slots",),
        "depth_slots",
        None,
        dict(type=_COUNT, metavar="D", help="--criterion area: spheres kept per corner ray, 1 to 6 (default: 3)"),
    ),
    (
        ("--surfaces",),
        "surfaces",
        "first",
        dict(
            choices=("first", "all"),
            help="first: what each lamp sees first (the memo's lamp); all: every wetted surface (needs --probe-radius)",
        ),
    ),
    (
        ("--probe-radius",),
        "probe_radius",
        None,
        dict(
            type=_number("float", allow_zero=True),
            metavar="RHO",
            help="--surfaces all: the fluid's probe radius, in the particles' length unit",
        ),
    ),
    (
        ("--lamps",),
        "lamps",
        "all",
        dict(
            type=_lamp_list,
            metavar="LIST",
            help="the lamps that are on: all, or names such as --lamps=-x,+x,-y,+y,+z (-x pushes toward +x)",
        ),
    ),
    (
        ("--frames",),
        "frames",
        1,
        dict(type=_COUNT, metavar="K", help="average the forces over K fixed lamp frames (isotropic pressure only)"),
    ),
    (
        ("--wall",),
        "walls",
        None,
        dict(
            type=_number("float", finite_only=True),
            nargs=6,
            action="append",
            metavar=("X", "Y", "Z", "NX", "NY", "NZ"),
            help="a wall that bounds the fluid: a point on it and its normal, pointing into the fluid, in the "
            "particles' units; repeat for more walls (a platen under the body: --wall 0 0 0 0 0 1)",
        ),
    ),
    (
        ("--tolerance",),
        "tolerance",
        None,
        dict(
            type=_number("float"),
            metavar="TOL",
            help="ask for accuracy instead of settings: the largest RMS per-particle force error as a fraction "
            "(0.01 = 1%%); chooses --criterion and --cells-per-diameter and prints the choice",
        ),
    ),
    # the load
    (("--pressure",), "pressure", 10e6, dict(type=_FLOAT, metavar="PA", help="fluid pressure [Pa], > 0")),
    (
        ("--pressures",),
        "pressures",
        None,
        dict(
            type=_FLOAT,
            nargs=3,
            metavar=("PX", "PY", "PZ"),
            help="one pressure per lamp axis [Pa], > 0, instead of --pressure (polyaxial loading)",
        ),
    ),
    (
        ("--stress",),
        "stress",
        None,
        dict(
            type=_number("float", finite_only=True),
            nargs=6,
            metavar=("SXX", "SYY", "SZZ", "SXY", "SYZ", "SXZ"),
            help="a stress tensor [Pa], compression positive, instead of --pressure: applied in its principal frame",
        ),
    ),
    (("--repeats",), "repeats", 5, dict(type=_COUNT, metavar="N", help="timed updates")),
    # the porosity grid
    (
        ("--grid",),
        "grid",
        None,
        dict(
            type=_COUNT,
            nargs=3,
            metavar=("NX", "NY", "NZ"),
            help="porosity on NX x NY x NZ cells (default with --vtk: 10 10 10)",
        ),
    ),
    (
        ("--box",),
        "box",
        None,
        dict(
            type=_number("float", finite_only=True),
            nargs=6,
            metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"),
            help="the porosity grid's box (default: the particles' bounding box)",
        ),
    ),
    (
        ("--method",),
        "method",
        None,
        dict(choices=("centroid", "polyhedron", "exact", "voxel", "midpoint"), help="porosity method (default: voxel)"),
    ),
    (
        ("--subdivisions",),
        "subdivisions",
        None,
        dict(type=_COUNT, metavar="S", help="porosity: sub-cells per cell edge, union methods (default: 8)"),
    ),
    # what to write
    (
        ("--json",),
        "json",
        None,
        dict(
            metavar="PATH",
            help="also write the report, inputs included, as JSON "
            "(- for standard output, the text report then going to standard error)",
        ),
    ),
    (
        ("--forces",),
        "forces",
        None,
        dict(
            metavar="FILE",
            help="write each particle's force, in the particles' order, for an engine to read back: CSV "
            "(id,fx,fy,fz) or, for .dump/.lammpstrj, one LAMMPS dump timestep (ITEM: ATOMS id fx fy fz; read_dump "
            "FILE STEP fx fy fz box no); ids are the file's, else 1 .. N; the header gives the unit",
        ),
    ),
    (
        ("--forces-format",),
        "forces_format",
        None,
        dict(choices=("csv", "lammps"), help="--forces: the file's format (default: from its extension)"),
    ),
    (
        ("--vtk",),
        "vtk",
        None,
        dict(
            metavar="DIR",
            help="write per-particle forces and a porosity grid as VTK files, "
            "the run's inputs as field data (needs pyevtk)",
        ),
    ),
]

#: Library argument names, as they start its error messages, and the flags that set them.
_LIBRARY_FLAGS = {
    "cells_per_diameter": "--cells-per-diameter",
    "walls": "--wall",
    "tolerance": "--tolerance",
    "pressure": "--pressure",
    "probe_radius": "--probe-radius",
    "depth_slots": "--depth-slots",
    "subpoints": "--subpoints",
    "resolver": "--resolver",
    "frames": "--frames",
    "lamps": "--lamps",
    "device": "--device",
    "subdivisions": "--subdivisions",
    "shape": "--grid",
    "lower": "--box",
    "upper": "--box",
    "method": "--method",
    "centers": "--particles",
    "radii": "--particles",
    "surfaces": "--surfaces",
}


def _add_run_options(parser, prefix: str) -> None:
    groups = {}
    for flags, dest, default, kw in _RUN_OPTIONS:
        kw = dict(kw)
        help_text = kw.pop("help")
        if default is not None and "default" not in help_text:
            shown = f"{default:g}" if isinstance(default, float) and default >= 1e4 else default
            help_text += f" (default: {shown})"
        group = groups.setdefault(_group_of(dest), parser.add_argument_group(_group_of(dest)))
        group.add_argument(*flags, dest=prefix + dest, default=None, help=help_text, **kw)


def _group_of(dest: str) -> str:
    if dest in ("particles", "format", "timestep", "scale"):
        return "particles (default: the built-in SphereTest specimen)"
    if dest in ("grid", "box", "method", "subdivisions"):
        return "porosity grid"
    if dest in ("json", "vtk", "repeats", "forces", "forces_format"):
        return "output"
    if dest in ("pressure", "pressures", "stress"):
        return "load"
    return "lamp"


#: A negative number as a command-line word, exponents included (-1, -.5, -1e-3, -2.5E+6).
_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def _parser() -> tuple[argparse.ArgumentParser, dict]:
    parser = argparse.ArgumentParser(prog="warp-lamp", description=__doc__, formatter_class=_Formatter)
    parser.add_argument("--version", action="version", version=_version())
    _add_run_options(parser, "top_")
    sub = parser.add_subparsers(dest="command", metavar="{run,bench}")
    run = sub.add_parser(
        "run",
        help="pressure on the built-in 100 mm SphereTest specimen of 5 mm particles, or on yours (the default)",
        description="Load the built-in SphereTest specimen (4,628 particles, 100 mm), or your particles "
        "(--particles), with fluid pressure, time the lamp's update and report the balance, the forces and the "
        "stress they imply. The options may also come before the word run.",
        formatter_class=_Formatter,
    )
    _add_run_options(run, "")
    bench = sub.add_parser(
        "bench",
        help="speed against error, on every device present, with peers (bench lamp, porosity, tolerance, engines)",
        description="Time the lamp (bench lamp) or the porosity methods (bench porosity) against their error; "
        "check tolerance='s choices (bench tolerance); time other engines' pressure boundaries (bench engines). "
        "bench lamp --quick takes about 40 s of CPU (a minute the first time, compiling) and about 10 minutes on "
        "a GPU; bench porosity "
        "--paper about 4 minutes on 2 CPU cores.",
        formatter_class=_Formatter,
    )
    for p in (parser, run, bench):
        # argparse takes "-1e-3" for a flag (its pattern knows -1 and -.5 only); DEM inputs write exponents.
        p._negative_number_matcher = _NEGATIVE_NUMBER
    bench.add_argument(
        "what",
        nargs="?",
        default="lamp",
        choices=("lamp", "porosity", "tolerance", "engines"),
        help="what to benchmark: the lamp's speed against error; the porosity methods; tolerance=, its "
        "speed-error table and whether its choices meet their tolerance (about 5 minutes on a CPU); other engines' "
        "pressure boundaries as peers (YADE's alpha caps, where YADE is installed)",
    )
    bench.add_argument("--sweep", action="store_true", help="engines: sweep YADE's alpha")
    bench.add_argument("--paper", action="store_true", help="porosity: also reproduce the paper's Table 1 and 3.2")
    bench.add_argument("--target", action="store_true", help="porosity: also time the 1 mm, 0.1 mm target scene")
    bench.add_argument("--histograms", metavar="PATH", help="porosity --paper: histograms as a PNG (needs matplotlib)")
    bench.add_argument("--quick", action="store_true", help="a CPU-sized subset (about 40 s of CPU)")
    bench.add_argument("--device", action="append", help="a Warp device to time (repeatable; default: all)")
    bench.add_argument("--json", metavar="PATH", help="write the results as JSON (- for standard output)")
    bench.add_argument("--plot", metavar="PATH", help="lamp: time against error as a PNG (needs matplotlib)")
    bench.add_argument("--repeats", type=_COUNT, default=None, metavar="N", help="lamp: timed repeats per figure")
    bench.add_argument("--no-progress", action="store_true", help="no progress bar")
    bench.add_argument("--from-json", metavar="PATH", help="print and plot a saved result instead of measuring")
    return parser, {"run": run, "bench": bench}


def _flag(dest: str) -> str:
    return next(flags[0] for flags, d, _, _ in _RUN_OPTIONS if d == dest)


def _shown(value) -> str:
    if isinstance(value, (list, tuple)):
        return " ".join(_shown(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def _merge_run_options(args) -> None:
    """Join the run options given before the word run and after it, never dropping either: one given in both
    places must agree; before bench they are refused (bench takes its own options after its name)."""
    args.given = set()
    args.chosen = set()  # what --tolerance chose
    for _, dest, default, _ in _RUN_OPTIONS:
        top = getattr(args, "top_" + dest)
        after = getattr(args, dest, None) if args.command == "run" else None
        if args.command == "bench" and top is not None:
            raise CliError(
                f"{_flag(dest)} before bench: it is an option of run; bench takes its options after its name "
                f"(warp-lamp bench {_flag(dest)} ...)"
            )
        if top is not None and after is not None and top != after:
            raise CliError(
                f"{_flag(dest)} given twice, {_shown(top)} before run and {_shown(after)} after it; give it once"
            )
        value = after if after is not None else top
        if value is not None:
            args.given.add(dest)
        if args.command != "bench":
            setattr(args, dest, default if value is None else value)


def _check_device(name: str | None):
    """The Warp device called ``name``, or CliError saying which exist (and that there is no GPU, if so)."""
    import warp as wp

    from warp_lamp.validate import resolve_device

    if name is not None and str(name).startswith("cuda") and wp.get_cuda_device_count() == 0:
        raise CliError(f"--device {name}: this machine has no CUDA GPU that Warp can use; use --device cpu")
    try:
        return resolve_device(name)
    except (ValueError, TypeError):
        present = ", ".join(d.alias for d in wp.get_devices())
        raise CliError(f"--device {name}: no such Warp device; present: {present}") from None


def _check_output(flag: str, path: str, *, directory: bool = False) -> None:
    """An output path that can be written: its folder exists and a file can be made in it (tried, not guessed
    from permission bits, which a root user or a read-only mount defeat), and it is not a folder (or, for
    ``directory``, it is one or can be made)."""
    target = os.path.abspath(path)
    if directory:
        if os.path.isdir(target):
            if not _can_write_in(target):
                raise CliError(f"{flag} {path}: the folder is not writable")
            return
        if os.path.exists(target):
            raise CliError(f"{flag} {path}: exists and is not a folder")
    elif os.path.isdir(target):
        raise CliError(f"{flag} {path}: is a folder, expected a file name")
    parent = os.path.dirname(target)
    if not os.path.isdir(parent):
        raise CliError(f"{flag} {path}: the folder {parent} does not exist")
    if not _can_write_in(parent):
        raise CliError(f"{flag} {path}: the folder {parent} is not writable")


def _can_write_in(folder: str) -> bool:
    try:
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


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


#: The keys a saved result of each benchmark has at its top level.
_LAMP_KEYS = ("warp_version", "git_commit", "date", "devices", "speed", "errors", "sweep")
_POROSITY_KEYS = ("bench", "paper")


def _check_saved(path: str, data: dict, what: str) -> None:
    """A saved result of ``bench what``, or CliError saying what the file holds instead."""
    lamp = all(k in data for k in _LAMP_KEYS)
    porosity = any(isinstance(data.get(k), dict) for k in _POROSITY_KEYS) and not lamp
    if what == "lamp" and not lamp:
        holds = "a bench porosity result: use bench porosity --from-json" if porosity else _holds(data, _LAMP_KEYS)
        raise CliError(f"--from-json {path}: not a bench lamp result; it holds {holds}")
    if what == "porosity" and not porosity:
        holds = "a bench lamp result: use bench --from-json" if lamp else _holds(data, _POROSITY_KEYS)
        raise CliError(f"--from-json {path}: not a bench porosity result; it holds {holds}")
    if what == "porosity":
        bench, paper = data.get("bench"), data.get("paper")
        if (bench is not None and not {"rows", "peers", "scene"} <= set(bench)) or (
            paper is not None and not {"cases", "table_1"} <= set(paper)
        ):
            raise CliError(f"--from-json {path}: a bench porosity result with parts missing")


def _holds(data: dict, need) -> str:
    keys = ", ".join(repr(k) for k in list(data)[:6]) or "no keys"
    missing = ", ".join(repr(k) for k in need if k not in data)
    return f"the keys {keys} (missing: {missing})"


def _write_json(path: str, data: dict) -> None:
    if path == "-":
        json.dump(data, sys.stdout, indent=1)
        sys.stdout.write("\n")
        sys.stdout.flush()
        return
    with open(path, "w") as f:
        json.dump(data, f, indent=1)


def _check_bench(args) -> None:
    lamp_only = {"--plot": args.plot}
    porosity_only = {"--paper": args.paper, "--target": args.target, "--histograms": args.histograms}
    unused = {**porosity_only, "--sweep": args.sweep}
    if args.what == "porosity":
        unused = {**lamp_only, "--repeats": args.repeats, "--sweep": args.sweep}
    elif args.what in ("tolerance", "engines"):
        unused = {**lamp_only, **porosity_only, "--quick": args.quick}
        if args.what == "tolerance":
            unused["--sweep"] = args.sweep
        else:
            unused["--device"] = args.device
        if args.from_json:
            raise CliError(f"--from-json is not used by bench {args.what}")
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
        _check_saved(args.from_json, args.saved, args.what)
        if args.histograms and not args.saved.get("paper"):
            raise CliError(f"--histograms: {args.from_json} holds no --paper results to draw")
    elif args.histograms and not args.paper:
        raise CliError("--histograms draws the --paper experiment: add --paper")
    for flag in ("--json", "--plot", "--histograms"):
        path = getattr(args, flag[2:])
        if path and not (flag == "--json" and path == "-"):
            _check_output(flag, path)
    if args.plot:
        _need_extra("--plot", "matplotlib", "plot")
    if args.histograms:
        _need_extra("--histograms", "matplotlib", "plot")
    if not args.from_json:
        args.devices = [_check_device(d) for d in args.device] if args.device else None


def _check_run(args) -> None:
    """Every check of run that can be made before the work: flags that need others, output paths, extras, the
    device, the particles file, the grid's size and the porosity grid."""
    given = args.given
    if args.particles is None:
        for dest in ("format", "timestep", "scale"):
            if dest in given:
                raise CliError(f"{_flag(dest)} reads --particles FILE: add --particles, or leave {_flag(dest)} out")
    if args.tolerance is not None:
        chosen = [
            dest
            for dest in ("criterion", "cells_per_diameter", "resolver", "subpoints", "depth_slots")
            if dest in given
        ]
        if chosen:
            raise CliError(f"--tolerance chooses {_flag(chosen[0])} itself: give one or the other")
        if args.surfaces == "all" or args.frames > 1:
            raise CliError(
                "--tolerance chooses among the first-surface estimators of one frame: leave out "
                "--surfaces all and --frames"
            )
    if args.criterion != "area":
        for dest in ("resolver", "subpoints", "depth_slots"):
            if dest in given:
                raise CliError(f"{_flag(dest)} is used by --criterion area only")
    if args.surfaces == "all":
        if args.probe_radius is None:
            raise CliError("--surfaces all needs --probe-radius RHO (a quarter to one mean particle radius)")
        if args.criterion != 1:
            raise CliError(f"--surfaces all works with --criterion 1, not {args.criterion}")
    elif "probe_radius" in given:
        raise CliError("--probe-radius is used by --surfaces all only")
    loads = [flag for flag in ("--pressure", "--pressures", "--stress") if flag[2:] in given]
    if len(loads) > 1:
        raise CliError(f"{' and '.join(loads)}: give one of them (one pressure, one per axis, or a stress tensor)")
    if args.stress is not None:
        sxx, syy, szz, sxy, syz, sxz = args.stress
        args.sigma = np.array([[sxx, sxy, sxz], [sxy, syy, syz], [sxz, syz, szz]])
        if not np.any(args.sigma):
            raise CliError("--stress: every component is 0: there is nothing to apply")
        if args.frames > 1:
            raise CliError("--frames averages an isotropic pressure only; a stress tensor has its own frame")
    else:
        args.sigma = None
    if args.frames > 1 and args.pressures is not None and len(set(args.pressures)) > 1:
        raise CliError("--frames averages an isotropic pressure only: give --pressure")
    if args.frames > 1 and args.walls:
        raise CliError("--frames and --wall: walls work with one lamp frame only (a turned frame's axes cut them)")
    if args.subdivisions is not None and args.method in ("exact", "centroid", "polyhedron"):
        raise CliError(
            f"--subdivisions: --method {args.method} does not use it (only voxel and midpoint sub-divide a cell)"
        )
    args.want_porosity = bool(args.vtk) or any(d in given for d in ("grid", "box", "method", "subdivisions"))
    if args.box is not None:
        lo, hi = np.array(args.box[:3]), np.array(args.box[3:])
        if np.any(hi <= lo):
            k = int(np.flatnonzero(hi <= lo)[0])
            raise CliError(f"--box: X1 Y1 Z1 must exceed X0 Y0 Z0; axis {'xyz'[k]} has {hi[k]:g} <= {lo[k]:g}")
    if args.json and args.json != "-":
        _check_output("--json", args.json)
    if args.forces_format is not None and args.forces is None:
        raise CliError("--forces-format is the format of --forces FILE: add --forces, or leave --forces-format out")
    if args.forces:
        _check_output("--forces", args.forces)
    if args.vtk:
        _check_output("--vtk", args.vtk, directory=True)
        _need_extra("--vtk", "pyevtk", "vtk")
    args.devices = [_check_device(args.device)]
    _load_particles(args)
    _check_grid(args)


def _load_particles(args) -> None:
    """The particles of the run: the user's file, read here (its faults are one line naming the file, the line
    and the column), or the built-in specimen, loaded later (it may need packing)."""
    args.info = None
    if args.particles is None:
        return
    from warp_lamp.particles_io import ParticleFileError, read_particles

    if not os.path.isfile(args.particles):
        raise CliError(f"--particles {args.particles}: no such file")
    try:
        c, r, ids, info = read_particles(args.particles, fmt=args.format, timestep=args.timestep, scale=args.scale)
    except (ParticleFileError, ValueError) as e:
        raise CliError(f"--particles {e}") from None
    if len(r) == 0:
        raise CliError(f"--particles {args.particles}: holds no particles")
    args.centers, args.radii, args.ids, args.info = c, r, ids, info


def _check_grid(args) -> None:
    """The lamp grid's size, known from the particles before anything is allocated: cells wider than the body
    light nothing reliably, and a grid over the memory budget is refused (the library's message, naming the
    flag)."""
    if args.info is None:
        # The built-in specimen: a 100 mm ball of 5 mm mean diameter (scenes.scene_sphere_specimen's defaults).
        extent, diameter = 0.1, 0.005
    else:
        lo = np.min(args.centers - args.radii[:, None], axis=0)
        hi = np.max(args.centers + args.radii[:, None], axis=0)
        extent, diameter = float(np.min(hi - lo)), 2.0 * float(np.mean(args.radii))
    cell = diameter / args.cells_per_diameter
    if cell > extent:
        raise CliError(
            f"--cells-per-diameter {args.cells_per_diameter:g}: cells of {cell:.3g}, wider than the whole body "
            f"({extent:.3g} across), so no cell is sure to see it; use 1 or more (the memo uses 2 to 16)"
        )


def _library_error(message: str, args) -> str:
    """A library error (which names its argument, ``cells_per_diameter: ...``) as the flag that set it."""
    name, sep, rest = message.partition(": ")
    flag = _LIBRARY_FLAGS.get(name)
    if not sep or flag is None:
        return message
    if flag == "--pressure" and getattr(args, "sigma", None) is not None:
        flag = "--stress"
    elif flag == "--pressure" and getattr(args, "pressures", None) is not None:
        flag = "--pressures"
    value = getattr(args, {"--grid": "grid", "--box": "box"}.get(flag, flag[2:].replace("-", "_")), None)
    shown = "" if value is None or flag in ("--particles",) else " " + _shown(value)
    return f"{flag}{shown}: {rest}"


def _check_flag_names(argv: list[str], parser, commands: dict) -> None:
    """Refuse a misspelt flag by its name: argparse would take the value after it (``--presure 1e6``) for the
    command's name and blame the value."""
    import difflib

    known = set()
    for p in (parser, *commands.values()):
        known.update(o for o in p._option_string_actions if o.startswith("--"))
    for word in argv:
        if word == "--":
            break
        name = word.split("=", 1)[0]
        if not name.startswith("--") or name in known or any(k.startswith(name) for k in known):
            continue
        close = difflib.get_close_matches(name, sorted(known), n=1)
        parser.error(f"unrecognized flag {name}" + (f" (did you mean {close[0]}?)" if close else ""))


def main(argv=None) -> int:
    """Run the command line ``argv`` (default: ``sys.argv[1:]``); returns the exit status."""
    parser, commands = _parser()
    argv = _join_lamps(list(sys.argv[1:] if argv is None else argv))
    _check_flag_names(argv, parser, commands)
    args = parser.parse_args(argv)
    # Errors found after parsing are reported with the usage of the command that was given.
    usage = commands.get(args.command, parser)
    import warnings

    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    wp.config.quiet = True
    formatwarning = warnings.formatwarning
    with warnings.catch_warnings():
        # A warning is one line on the command line, not Python's file:line and source; the report's units line
        # already says the radii's.
        warnings.formatwarning = lambda message, category, *_, **__: f"warp-lamp: warning: {message}\n"
        warnings.filterwarnings("ignore", message="radii: the mean diameter")
        try:
            _merge_run_options(args)
            wp.init()
            if args.command == "bench":
                _check_bench(args)
                runners = {"porosity": _bench_porosity, "tolerance": _bench_tolerance, "engines": _bench_engines}
                return runners.get(args.what, _bench)(args)
            _check_run(args)
            return _run(args)
        except CliError as e:
            usage.error(str(e))
        except (ValueError, OSError) as e:
            # Input that passed the parser but not the library (a grid over its memory budget, say): one line
            # too, naming the flag.
            usage.error(_library_error(str(e), args))
        finally:
            warnings.formatwarning = formatwarning
    return 2


def _join_lamps(argv: list) -> list:
    """``--lamps -x,+x`` as ``--lamps=-x,+x``: argparse takes a value that starts with '-' for an option."""
    out = []
    for k, tok in enumerate(argv):
        if k and argv[k - 1] == "--lamps" and tok.startswith("-") and not tok.startswith("--"):
            out[-1] = f"--lamps={tok}"
            continue
        out.append(tok)
    return out


def _compiled(device, modules) -> bool:
    """Whether Warp's kernel cache holds ``modules`` built for ``device`` (False when unsure)."""
    import warp as wp

    try:
        for name in modules:
            importlib.import_module(name)
            module = wp.get_module(name)
            block_dim = 1 if device.is_cpu else module.options["block_dim"]
            folder = os.path.join(wp.config.kernel_cache_dir, module.get_module_identifier(block_dim))
            if not os.path.exists(os.path.join(folder, module._get_compile_output_name(device, block_dim=block_dim))):
                return False
    except Exception:  # a private Warp detail moved: say it may compile rather than fail
        return False
    return True


def _first_run_note(args, device) -> None:
    """Say, on stderr, what the run builds the first time, when it does: the specimen's packing, the kernels."""
    from warp_lamp.scenes import specimen_cached

    modules = ["warp_lamp.kernels.lamp"]
    if args.criterion == "area":
        modules.append("warp_lamp.kernels.area")
    if args.surfaces == "all":
        modules += ["warp_lamp.kernels.wetted_sweeps", "warp_lamp.kernels.wetted_cross", "warp_lamp.kernels.wetted"]
    if args.want_porosity:
        modules.append("warp_lamp.kernels.porosity")
    import warp as wp

    from warp_lamp.scenes import _cache_dir

    build = []
    if args.info is None and not specimen_cached():
        packing = "" if _compiled(wp.get_device("cpu"), ["warp_lamp.kernels.packing"]) else " (with its kernel)"
        build.append(f"packs the SphereTest specimen{packing}, in seconds, cached in {_cache_dir()}")
    if not _compiled(device, modules):
        where = "10 to 60 s on a CPU" if device.is_cpu else "up to a minute or two per module on a GPU"
        build.append(f"compiles the kernels for {device.alias} ({where}, cached in {wp.config.kernel_cache_dir})")
    if build:
        print(
            f"warp-lamp: this first run {' and '.join(build)}; later runs start in a second or two",
            file=sys.stderr,
            flush=True,
        )


def _lamp_options(args) -> dict:
    """ShiningLamp's keywords for the run: only those given, so the library's defaults stay its own."""
    options = {"criterion": args.criterion, "lamps": args.lamps}
    for dest in ("resolver", "subpoints", "depth_slots", "frames"):
        if dest in args.given or (dest in args.chosen):
            options[dest] = getattr(args, dest)
    if args.walls:
        # The wall's point is in the particles' units: the reader's factor to metres applies to it too (the
        # distance between a body and a wall decides whether it rests there).
        scale = getattr(getattr(args, "info", None), "scale", 1.0)
        options["walls"] = [([x * scale for x in w[:3]], w[3:]) for w in args.walls]
    if args.surfaces == "all":
        options["surfaces"] = "all"
        options["probe_radius"] = args.probe_radius
    return options


def _inputs(args, grid, pressure) -> dict:
    """The run's inputs as the JSON report and the VTK field data keep them."""
    out = {
        "particles": "built-in SphereTest specimen" if args.info is None else args.info.path,
        "pressure_Pa": pressure if isinstance(pressure, float) else np.asarray(pressure).tolist(),
        "criterion": args.criterion,
        "cells_per_diameter": args.cells_per_diameter,
        "surfaces": args.surfaces,
        "probe_radius": args.probe_radius,
        "lamps": args.lamps if args.lamps == "all" else list(args.lamps),
        "frames": args.frames,
        "lamp_rotation": grid.rotation.tolist(),
    }
    for dest in ("resolver", "subpoints", "depth_slots"):
        if dest in args.given or dest in args.chosen:
            out[dest] = getattr(args, dest)
    if args.walls:
        out["walls"] = [{"point": list(w[:3]), "normal": list(w[3:])} for w in args.walls]
    if args.tolerance is not None:
        out["tolerance"] = args.tolerance
    if args.info is not None:
        out["particles_format"] = args.info.format
        out["particles_scale"] = args.info.scale
        out["particles_timestep"] = args.info.timestep
    return out


def _run(args) -> int:
    import warp as wp

    from warp_lamp import LampGrid, ShiningLamp, porosity
    from warp_lamp.frames import lamp_stress_frame
    from warp_lamp.lamp import _warn_fines
    from warp_lamp.measures import envelope_stress
    from warp_lamp.scenes import scene_sphere_specimen

    device = args.devices[0]
    text = sys.stderr if args.json == "-" else sys.stdout  # with the JSON on standard output, the text goes aside

    def say(line: str) -> None:
        print(line, file=text)

    _first_run_note(args, device)
    if args.info is None:
        scene = scene_sphere_specimen()
        centers, radii, name = scene.centers, scene.radii, scene.name
        body_center, R = scene.center, scene.radius
    else:
        centers, radii, name = args.centers, args.radii, os.path.basename(args.info.path)
        lo, hi = centers.min(axis=0), centers.max(axis=0)
        body_center, R = 0.5 * (lo + hi), None
        for line in args.info.summary().splitlines():
            say(f"particles  {line}")
    n = len(radii)
    if args.tolerance is not None:
        from warp_lamp.tolerance import choose_settings

        choice = choose_settings(args.tolerance, device)
        say(f"choice     {choice.describe()}")
        args.cells_per_diameter = choice.cells_per_diameter
        for dest, value in choice.options().items():
            setattr(args, dest, value)
            args.chosen.add(dest)
    cpd = args.cells_per_diameter
    if args.sigma is not None:
        pressure = args.sigma
        rotation = lamp_stress_frame(args.sigma)[0]
    else:
        pressure = args.pressure if args.pressures is None else np.array(args.pressures)
        rotation = None
    shift = np.zeros(3)
    if args.frames > 1:
        # Frame averaging turns the grid about the body and takes world positions in float32: work about the
        # body's centre, so that float32 holds them as well as it holds one frame's local coordinates.
        shift = np.array(body_center, dtype=np.float64)
        centers, body_center = centers - shift, np.zeros(3)
    probe = args.probe_radius if args.surfaces == "all" else 0.0
    grid = LampGrid.enclosing(centers, radii, cells_per_diameter=cpd, rotation=rotation, probe_radius=probe)
    _warn_fines(radii, grid, args.criterion)
    lamp = ShiningLamp(grid, device=device, **_lamp_options(args))
    if args.walls:
        import warnings

        from warp_lamp.validate import walls_behind_message

        message = walls_behind_message(centers, radii, lamp.frame.wall_planes)
        if message:
            warnings.warn(message, stacklevel=2)
    if args.frames > 1:
        pos = wp.array(centers.astype(np.float32), dtype=wp.vec3, device=device)
        in_frame = False
    else:
        pos = wp.array(grid.to_frame(centers).astype(np.float32), dtype=wp.vec3, device=device)
        in_frame = True
    rad = wp.array(radii.astype(np.float32), dtype=wp.float32, device=device)
    lamp.update(pos, rad, in_frame=in_frame)  # the first call compiles or loads the kernels: not timed
    times = []
    for _ in range(args.repeats):
        wp.synchronize_device(device)
        t0 = time.perf_counter()
        lamp.update(pos, rad, in_frame=in_frame)
        wp.synchronize_device(device)
        times.append(time.perf_counter() - t0)
    f = lamp.forces_numpy(pressure)
    mag = np.linalg.norm(f, axis=1)
    if args.frames > 1:
        diags = [child.diagnostics() for child in lamp.frames]
        surface = np.any(f != 0.0, axis=1)
        lit = None
        invalid, outside = max(d.invalid for d in diags), max(d.outside for d in diags)
    else:
        d = lamp.diagnostics()
        surface = d.surface
        lit = d.lit if hasattr(d, "lit") else d.loaded
        invalid, outside = d.invalid, d.outside
    moment = np.cross(centers - body_center, f).sum(axis=0)
    p_scale = float(np.max(np.abs(pressure))) if args.sigma is not None else float(np.max(pressure))
    h = float(grid.cell[0, 0])
    nu, nv = (int(x) for x in grid.counts[0])
    lit_mag = mag[surface]
    report = {
        "scene": name,
        "particles": int(n),
        "body_diameter_m": None if R is None else 2 * R,
        "mean_particle_diameter_m": float(2 * radii.mean()),
        "pressure_Pa": pressure if isinstance(pressure, float) else np.asarray(pressure).tolist(),
        "cells_per_diameter": cpd,
        "criterion": args.criterion,
        "device": f"{device.alias} ({device.name})",
        "inputs": _inputs(args, grid, pressure),
        "grid": {
            "cell_m": h,
            "cells_per_grid": [nu, nv],
            "cells": grid.n_cells,
            "bytes": grid.nbytes,
            "origin_m": grid.origin.tolist(),
        },
        "update_ms_median": float(np.median(times) * 1e3),
        "repeats": args.repeats,
        "lit_particles": int(surface.sum()),
        "lit_cells": lit,
        "force_sum_N": f.sum(axis=0).tolist(),
        "moment_N_m": moment.tolist(),
        "force_N": {
            "min_lit": float(lit_mag.min()) if lit_mag.size else None,
            "mean_lit": float(lit_mag.mean()) if lit_mag.size else None,
            "max": float(mag.max()) if n else None,
            "total": float(mag.sum()),
        },
        "skipped": {"invalid": int(invalid), "outside": int(outside)},
    }
    if args.walls and args.frames == 1:
        report["wall_forces_N"] = lamp.wall_forces_numpy(pressure).tolist()
    if R is not None:
        report["moment_over_PpiR3"] = float(np.linalg.norm(moment) / (p_scale * np.pi * R**3))
        sigma = envelope_stress(centers, f, body_center, 4.0 / 3.0 * np.pi * R**3)
        report["mean_stress_over_P"] = float(-np.trace(sigma) / 3 / p_scale)
    if R is not None:
        say(f"scene      {name}: {n:,} spheres, body diameter {2 * R * 1e3:.0f} mm")
    else:
        say(f"scene      {name}: {n:,} spheres")
    lamps = "all six lamps" if args.lamps == "all" else "lamps " + " ".join(args.lamps)
    how = f"criterion {args.criterion}" + (
        "" if args.surfaces == "first" else f", every wetted surface (probe radius {args.probe_radius:g})"
    )
    if args.frames > 1:
        how += f", averaged over {args.frames} frames"
    if args.sigma is not None:
        values = lamp_stress_frame(args.sigma)[1]
        say(
            f"pressure   P = {p_scale:.6g} Pa: the stress tensor's principal values {_shown(list(values))} Pa, "
            f"in its principal frame, on {lamps}, {how}"
        )
    elif args.pressures is not None:
        say(f"pressure   P = {_shown(args.pressures)} Pa along x, y, z on {lamps}, {how}")
    else:
        say(f"pressure   P = {pressure:.6g} Pa on {lamps}, {how}")
    length, force, moment_unit = _units(args)
    # The keys keep their _N names for old readers; these say what the numbers are in.
    report["units"] = {"length": length, "force": force, "moment": moment_unit, "pressure": "Pa"}
    k = 1e3 if args.info is None else 1.0  # the built-in specimen's lengths are shown in mm
    shown = "mm" if args.info is None else length
    say(
        f"grid       cells of {h * k:.4g} {shown} ({cpd:g} per mean particle diameter of "
        f"{2 * radii.mean() * k:.3g} {shown}); three grids of {nu} x {nv} cells, "
        f"{grid.n_cells:,} cells, {grid.nbytes:,} bytes"
    )
    say(f"device     {device.alias} ({device.name})")
    say(f"update     {report['update_ms_median']:.3f} ms (median of {args.repeats}, after a first untimed update)")
    per_lamp = "" if lit is None else f"; cells lit per lamp {lit}"
    say(f"surface    {report['lit_particles']:,} particles lit{per_lamp}")
    balanced = args.lamps == "all" and not args.walls
    say(
        f"balance    sum of forces = {report['force_sum_N']} {force}"
        + (" (exact zero by construction)" if balanced else " (only axes with both lamps on and no wall balance)")
    )
    for k, fw in enumerate(report.get("wall_forces_N", [])):
        say(f"wall {k}     force on the wall {np.round(fw, 6).tolist()} {force} (the reaction of the rays it stopped)")
    if R is not None:
        say(f"moment     |M| / (P pi R^3) = {report['moment_over_PpiR3']:.3e} (dimensionless)")
    else:
        say(f"moment     |M| about the centre of the centres' box = {np.linalg.norm(moment):.4g} {moment_unit}")
    fm = report["force_N"]
    if lit_mag.size:
        say(
            f"forces     |F| on lit particles: min {fm['min_lit']:.4g} {force}, mean {fm['mean_lit']:.4g} {force}, max "
            f"{fm['max']:.4g} {force}; total |F| {fm['total']:.4g} {force}"
        )
    else:
        say("forces     no particle is lit: the lamp loads nothing (is the grid finer than the body?)")
    if args.info is not None:
        say(f"units      {_units_note(args)}")
    if R is not None:
        say(
            f"stress     mean -tr(sigma)/3P = {report['mean_stress_over_P']:.4f} (dimensionless; "
            "forces act at particle centres, inside the envelope: expect a little under 1)"
        )
    say(f"skipped    particles invalid {invalid}, outside the grid {outside}")
    if args.want_porosity:
        report["porosity"], eps, box = _porosity(args, centers, radii, body_center, R, shift, device, porosity)
        pr = report["porosity"]
        say(
            f"porosity   {pr['method']} on {pr['shape'][0]} x {pr['shape'][1]} x {pr['shape'][2]} cells: min "
            f"{pr['min']:.3f}, mean {pr['mean']:.3f}, max {pr['max']:.3f} (void fraction)"
        )
    if args.vtk:
        from warp_lamp.export import write_vtk_particles, write_vtk_porosity

        os.makedirs(args.vtk, exist_ok=True)
        fields = _field_data(report)
        stem = "specimen" if args.info is None else "particles"
        world = centers + shift
        a = write_vtk_particles(
            os.path.join(args.vtk, f"{stem}_forces"),
            world,
            radii,
            field_data=fields,
            force=f,
            lit=surface,
            **({} if args.info is None or args.ids is None else {"id": args.ids}),
        )
        b = write_vtk_porosity(os.path.join(args.vtk, f"{stem}_porosity"), eps, box[0], box[1], field_data=fields)
        say(
            f"wrote      {a} (per-particle radius, force, lit) and {b} ({report['porosity']['method']} porosity, "
            f"{tuple(report['porosity']['shape'])} cells)"
        )
    if args.forces:
        from warp_lamp.export import write_forces

        world = centers + shift
        ids = None if args.info is None else args.ids
        written = write_forces(
            args.forces,
            f,
            ids=ids,
            fmt=args.forces_format,
            unit=force.replace("\u00b7", "*").replace("\u00b2", "^2"),
            timestep=0 if args.info is None or args.info.timestep is None else args.info.timestep,
            box=(np.min(world - radii[:, None], axis=0), np.max(world + radii[:, None], axis=0)),
        )
        idw = "the file's ids" if ids is not None else "ids 1 .. N in the particles' order"
        say(f"wrote      {written} ({n:,} forces in {force}, {idw})")
    if args.json:
        _write_json(args.json, report)
        if args.json != "-":
            say(f"wrote      {args.json}")
    return 0


def _units(args) -> tuple[str, str, str]:
    """The run's length, force and moment units, in words. Pressure is in Pa, so forces are in Pa x length^2:
    newtons only where the lengths are known to be metres (the built-in specimen, a file that names its unit, or
    --scale); otherwise the file's own length unit L, and forces in Pa*L^2."""
    if args.info is None or args.info.length_unit == "m":
        return "m", "N", "N\u00b7m"
    return "L", "Pa\u00b7L\u00b2", "Pa\u00b7L\u00b3"


def _units_note(args) -> str:
    """One line on the units of a user's file: what they are, and how to get newtons."""
    if args.info.length_unit == "m":
        return "lengths in metres and pressure in Pa: forces in N"
    r = float(np.median(args.radii))
    look = "millimetres" if 0.05 <= r < 100.0 else ("metres" if 1e-5 <= r < 0.05 else "neither metres nor millimetres")
    hint = "; for millimetres, 1 Pa\u00b7mm\u00b2 = 1e-6 N" if look == "millimetres" else ""
    return (
        f"the file does not name its length unit (L); the radii look like {look}: forces are in Pa\u00b7L\u00b2 "
        f"(N only if L is metres{hint}); give --scale (0.001 for millimetres) to work in metres and newtons"
    )


def _porosity(args, centers, radii, body_center, R, shift, device, porosity) -> tuple[dict, np.ndarray, tuple]:
    """The porosity grid of the run (centres relative to ``shift``): its summary for the report, the grid, and its
    box in the particles' own coordinates."""
    shape = tuple(args.grid) if args.grid is not None else (10, 10, 10)
    if args.box is not None:
        lo, hi = np.array(args.box[:3], dtype=np.float64) - shift, np.array(args.box[3:], dtype=np.float64) - shift
    elif R is not None:
        lo, hi = body_center - R, body_center + R
    else:
        lo, hi = np.min(centers - radii[:, None], axis=0), np.max(centers + radii[:, None], axis=0)
    method = args.method or "voxel"
    kw = {} if method in ("centroid", "polyhedron", "exact") else {"subdivisions": args.subdivisions or 8}
    eps = porosity(centers, radii, lo, hi, shape, method=method, device=device, **kw)
    summary = {
        "method": method,
        "subdivisions": kw.get("subdivisions"),
        "shape": list(shape),
        "box_m": [(lo + shift).tolist(), (hi + shift).tolist()],
        "min": float(eps.min()),
        "mean": float(eps.mean()),
        "max": float(eps.max()),
    }
    return summary, eps, (lo + shift, hi + shift)


def _field_data(report: dict) -> dict:
    """The run's inputs for VTK field data (numbers only): pressure [Pa] (1, 3 or, for a stress tensor, 9 values),
    criterion (0, 1, or 2 for area), cells per diameter, frames, probe radius (0: the first surface only)."""
    inputs = report["inputs"]
    return {
        "pressure_Pa": np.asarray(inputs["pressure_Pa"], dtype=np.float64).ravel(),
        "criterion": CRITERION_CODE[inputs["criterion"]],
        "cells_per_diameter": inputs["cells_per_diameter"],
        "frames": inputs["frames"],
        "probe_radius": inputs["probe_radius"] or 0.0,
    }


def _bench(args) -> int:
    from warp_lamp.bench import bench_lamp, format_tables, plot

    text = sys.stderr if args.json == "-" else sys.stdout
    if args.from_json:
        result = args.saved
    else:
        result = bench_lamp(args.devices, quick=args.quick, progress=not args.no_progress, repeats=args.repeats)
    print(format_tables(result), file=text)
    if args.json:
        _write_json(args.json, result)
        if args.json != "-":
            print(f"\nwrote {args.json}", file=text)
    if args.plot:
        plot(result, args.plot)
        print(f"wrote {args.plot}", file=text)
    return 0


def _bench_tolerance(args) -> int:
    from warp_lamp.bench.tolerance import check_tolerance
    from warp_lamp.tolerance import load_table

    text = sys.stderr if args.json == "-" else sys.stdout
    table = load_table()
    out = {"table": table, "checks": {}}
    print("The speed-error table tolerance= reads (warp_lamp/data/speed_error.json):", file=text)
    print("| setting | cells/d | error (max over its scenes) | time / criterion 1 at 4 |", file=text)
    print("| --- | --- | --- | --- |", file=text)
    for row in table["rows"]:
        name = "criterion 1" if row["criterion"] == 1 else f"area {row['resolver']} D = {row['depth_slots']}"
        ratios = ", ".join(f"{k} {v:.3g}x" for k, v in row["ratio"].items())
        print(f"| {name} | {row['cells_per_diameter']:g} | {100 * row['error']:.3g}% | {ratios} |", file=text)
    for device in args.devices or [None]:
        rows = check_tolerance(table, device)
        out["checks"][str(device)] = rows
        print(
            f"\nChoices on {device or 'the default device'}, and the error each gives (table scenes, held out):",
            file=text,
        )
        print("| tolerance | choice | measured errors | met |", file=text)
        print("| --- | --- | --- | --- |", file=text)
        for r in rows:
            if r["choice"] is None:
                print(f"| {r['tolerance']:g} | none in the table | - | - |", file=text)
                continue
            m = ", ".join(f"{k} {100 * v:.3g}%" for k, v in r["measured"].items())
            print(f"| {r['tolerance']:g} | {r['choice']} | {m} | {'yes' if r['ok'] else 'NO'} |", file=text)
    if args.json:
        _write_json(args.json, out)
    return 0


def _bench_engines(args) -> int:
    from warp_lamp.bench.engines import bench_engines, format_engines

    text = sys.stderr if args.json == "-" else sys.stdout
    result = bench_engines(repeats=args.repeats or 3, sweep=args.sweep, progress=not args.no_progress)
    print(format_engines(result), file=text)
    if args.json:
        _write_json(args.json, result)
    return 0


def _bench_porosity(args) -> int:
    from warp_lamp.bench import porosity as bp

    text = sys.stderr if args.json == "-" else sys.stdout
    if args.from_json:
        result, paper = args.saved.get("bench"), args.saved.get("paper")
    else:
        devices = args.devices
        if args.paper:
            print(bp.paper_note(quick=args.quick), file=sys.stderr, flush=True)
        result = bp.bench_porosity(
            devices, quick=args.quick, progress=not args.no_progress, target=args.target, paper=args.paper
        )
        paper = result.pop("paper", None)
    print(bp.format_porosity(result, paper), file=text)
    if args.json:
        _write_json(args.json, {"bench": result, "paper": paper})
        if args.json != "-":
            print(f"\nwrote {args.json}", file=text)
    if args.histograms:
        bp.plot_histograms(paper, args.histograms)
        print(f"wrote {args.histograms}", file=text)
    return 0
