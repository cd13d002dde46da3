"""The ``warp-lamp`` command: ``run`` (the default) loads a built-in body with fluid pressure and reports."""

from __future__ import annotations

import argparse
import time

import numpy as np

__all__ = ["main"]


def _run(args) -> int:
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    from warp_lamp import LampGrid, ShiningLamp
    from warp_lamp.lamp import pressure_area
    from warp_lamp.measures import envelope_stress
    from warp_lamp.scenes import scene_sphere_specimen

    scene = scene_sphere_specimen()
    device = wp.get_device(args.device)
    grid = LampGrid.enclosing(scene.centers, scene.radii, cells_per_diameter=args.cells_per_diameter)
    lamp = ShiningLamp(grid, criterion=args.criterion, device=device)
    pos = wp.array((scene.centers - grid.origin).astype(np.float32), dtype=wp.vec3, device=device)
    rad = wp.array(scene.radii.astype(np.float32), dtype=wp.float32, device=device)
    forces = wp.zeros(scene.n, dtype=wp.vec3, device=device)
    lamp.update(pos, rad, in_frame=True)  # first call compiles or loads the kernels
    times = []
    for _ in range(args.repeats):
        wp.synchronize_device(device)
        t0 = time.perf_counter()
        lamp.update(pos, rad, in_frame=True)
        wp.synchronize_device(device)
        times.append(time.perf_counter() - t0)
    lamp.add_forces(forces, args.pressure)
    d = lamp.diagnostics(scene.centers, args.pressure, moment_origin=scene.center)
    f = d.counts * pressure_area(args.pressure, grid)
    mag = np.linalg.norm(f, axis=1)
    R = scene.radius
    sigma = envelope_stress(scene.centers, f, scene.center, 4.0 / 3.0 * np.pi * R**3)
    print(f"scene      {scene.name}: {scene.n} spheres, body diameter {2 * R * 1e3:.0f} mm")
    print(f"grid       {grid.counts.tolist()} cells of {grid.cell[0, 0] * 1e3:.3f} mm, criterion {args.criterion}")
    print(f"device     {device} ({device.name})")
    print(f"update     {np.median(times) * 1e3:.3f} ms (median of {args.repeats})")
    print(f"surface    {int(d.surface.sum())} particles lit; cells lit per lamp {d.lit}")
    print(f"balance    sum of forces = {f.sum(axis=0).tolist()} N (exact zero by construction)")
    print(f"moment     |M| / (P pi R^3) = {np.linalg.norm(d.moment) / (args.pressure * np.pi * R**3):.3e}")
    print(
        f"forces     |F| on lit particles: min {mag[d.surface].min():.4g}, mean {mag[d.surface].mean():.4g}, "
        f"max {mag.max():.4g} N; total |F| {mag.sum():.4g} N"
    )
    print(
        f"stress     mean -tr(sigma)/3P = {-np.trace(sigma) / 3 / args.pressure:.4f}  "
        f"(forces act at particle centres, inside the envelope: expect a little under 1)"
    )
    print(f"skipped    invalid {d.invalid}, outside the grid {d.outside}")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="warp-lamp", description=__doc__)
    sub = parser.add_subparsers(dest="command")
    run = sub.add_parser(
        "run", help="pressure on the built-in 100 mm SphereTest specimen of 5 mm particles (the default)"
    )
    for p in (parser, run):
        p.add_argument("--device", default=None, help="warp device, e.g. cpu or cuda:0 (default: Warp's default)")
        p.add_argument("--cells-per-diameter", type=float, default=4.0, help="cells per mean particle diameter")
        p.add_argument("--criterion", type=int, default=1, choices=(0, 1), help="1: cell-centre ray, 0: overlap")
        p.add_argument("--pressure", type=float, default=10e6, help="fluid pressure [Pa]")
        p.add_argument("--repeats", type=int, default=5, help="timed updates")
    bench = sub.add_parser("bench", help="speed against error, on every device present, with peers")
    bench.add_argument("what", nargs="?", default="lamp", choices=("lamp", "porosity"), help="what to benchmark")
    bench.add_argument("--paper", action="store_true", help="porosity: also reproduce the paper's Table 1 and 3.2")
    bench.add_argument("--target", action="store_true", help="porosity: also time the 1 mm, 0.1 mm target scene")
    bench.add_argument("--histograms", metavar="PATH", help="porosity --paper: histograms as a PNG")
    bench.add_argument("--quick", action="store_true", help="a CPU-sized subset, under a minute")
    bench.add_argument("--device", action="append", help="a warp device to time (repeatable; default: all)")
    bench.add_argument("--json", metavar="PATH", help="write the results as JSON")
    bench.add_argument("--plot", metavar="PATH", help="time against error as a PNG (needs the plot extra)")
    bench.add_argument("--repeats", type=int, default=None, help="timed repeats per figure")
    bench.add_argument("--no-progress", action="store_true", help="no progress bar")
    bench.add_argument("--from-json", metavar="PATH", help="print and plot a saved result instead of measuring")
    args = parser.parse_args(argv)
    if args.command == "bench":
        return _bench(args)
    return _run(args)


def _bench(args) -> int:
    import json

    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    from warp_lamp.bench import bench_lamp, format_tables, plot

    if args.what == "porosity":
        return _bench_porosity(args)
    if args.from_json:
        with open(args.from_json) as f:
            result = json.load(f)
    else:
        result = bench_lamp(args.device, quick=args.quick, progress=not args.no_progress, repeats=args.repeats)
    print(format_tables(result))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
        print(f"\nwrote {args.json}")
    if args.plot:
        plot(result, args.plot)
        print(f"wrote {args.plot}")
    return 0


def _bench_porosity(args) -> int:
    import json

    from warp_lamp import bench_porosity as bp

    if args.from_json:
        with open(args.from_json) as f:
            saved = json.load(f)
        result, paper = saved.get("bench"), saved.get("paper")
    else:
        result = bp.bench_porosity(args.device, quick=args.quick, progress=not args.no_progress, target=args.target)
        paper = bp.paper_experiment((args.device or [None])[-1], quick=args.quick) if args.paper else None
    print(bp.format_porosity(result, paper))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"bench": result, "paper": paper}, f, indent=1)
        print(f"\nwrote {args.json}")
    if args.histograms and paper:
        bp.plot_histograms(paper, args.histograms)
        print(f"wrote {args.histograms}")
    return 0
