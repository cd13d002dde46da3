"""The lamp's share of a DEM cycle (examples/sphere_test.py, whole cycle in one CUDA graph), with the v4 depth pass
and the automatic split, at 2, 4, 8, 16 cells per diameter.

    python bench/experiments/sphere_share.py --json out.json
"""

import argparse
import importlib.util
import json
from pathlib import Path

import warp as wp

import warp_lamp as wl
from warp_lamp.timing import run_header

wp.config.log_level = wp.LOG_WARNING


def load_sphere_test():
    path = Path(__file__).resolve().parents[2] / "examples" / "sphere_test.py"
    spec = importlib.util.spec_from_file_location("sphere_test", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--cells", type=float, nargs="*", default=[2, 4, 8, 16])
    parser.add_argument("--json")
    args = parser.parse_args()
    st = load_sphere_test()
    device = wp.get_device("cuda:0")
    rows = []
    for k in args.cells:
        for depth_pass, options in (("v4", {"split": 0, "order": False}), ("auto", {})):
            test = st.SphereTest(k, device=device)
            test.lamp = wl.ShiningLamp(test.lamp.grid, device=device, **options)
            test.lamp.reserve(test.n)
            for _ in range(4):
                test.step()
            t = test.time_cycle(repeats=30)
            # The lamp's update alone, captured, static and moving as in the benchmark.
            with wp.ScopedCapture(device=device) as cap:
                test.lamp.update(test.dem.pos32, test.dem.radius32)
            from warp_lamp.timing import time_median_events

            t["update_s"] = time_median_events(lambda c=cap: wp.capture_launch(c.graph), device, repeats=100)
            row = {"cells_per_diameter": k, "depth_pass": depth_pass, "split": test.lamp.split, **t}
            rows.append(row)
            print(
                f"d/{k:g} {depth_pass:<6} split {test.lamp.split:>2}: cycle {t['cycle_s'] * 1e6:8.1f} us, without lamp "
                f"{t['cycle_without_lamp_s'] * 1e6:8.1f} us, lamp share {t['lamp_share']:.0%}, "
                f"update alone {t['update_s'] * 1e6:8.1f} us",
                flush=True,
            )
    if args.json:
        with open(args.json, "w") as f:
            json.dump({**run_header([device]), "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
