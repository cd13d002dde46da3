"""The benchmark's area section alone (``warp_lamp.bench.modes.section_area``) on one device: JSON and Markdown.

    PYTHONPATH=. python bench/run_area_section.py --device cpu --json bench/results/cpu-dev-2026-11-25-area.json
    PYTHONPATH=. python bench/run_area_section.py --device cuda:0 --large --json $OUT/area.json   # the GPU part

On the CPU criterion 1 runs to 16 cells per diameter (as ``warp-lamp bench --quick``); on CUDA to 32, and with
``--large`` the 1M lattice box too (as the full bench).
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import warp as wp

from warp_lamp.bench.modes import format_modes, section_area


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--repeats", type=int, default=None, help="timed repeats (default 5 on the CPU, 50 on CUDA)")
    ap.add_argument("--large", action="store_true", help="also the 1M lattice box (CUDA)")
    ap.add_argument("--json", help="write the section here")
    ap.add_argument("--md", help="write its tables here (default: the JSON path with .md)")
    args = ap.parse_args()
    device = wp.get_device(args.device)
    repeats = args.repeats or (50 if device.is_cuda else 5)
    c1 = (2, 4, 8, 16, 32) if device.is_cuda else (2, 4, 8, 16)
    t0 = time.perf_counter()
    sec = section_area(
        device, repeats=repeats, criterion1_cpd=c1, overlap=True, lone_samples=64, large=(100,) if args.large else ()
    )
    sec["seconds"] = time.perf_counter() - t0
    sec["machine"] = {"platform": platform.platform(), "device": device.name, "alias": device.alias}
    text = format_modes({"area": [sec]})
    print(text)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(sec, fh, indent=1)
        md = args.md or args.json.rsplit(".", 1)[0] + ".md"
        with open(md, "w") as fh:
            fh.write(f"# Area section on {device.alias} ({device.name}), {sec['seconds']:.0f} s\n{text}\n")


if __name__ == "__main__":
    main()
