"""Build the lease's kernel cache on the dev machine: warp_lamp's kernel modules compiled ahead of time for sm_90,
as both cubin and PTX, into Warp's cache (``WARP_CACHE_PATH``), to carry as ``.wcache``.

Both, because which one Warp loads depends on the lent host: Warp 1.19 builds PTX where the driver is at least its
CUDA toolkit and a cubin where the driver is older (``Device.get_cuda_output_format``), and looks only for that file
(``<module>.sm90.cubin`` or ``.sm90.ptx``). The H200 hosts run driver 13.0 under Warp's toolkit 13.4, so by that
code they load the cubin. Yet a lease of 2026-11-28 compiled ``kernels.wetted`` on the device with only its cubin
carried, and one of 2026-11-29 compiled it (205 s, the lease lost to it) with only its PTX. A module found without the
file it wants is compiled there, in every process that loads it. Carry both.

    WARP_CACHE_PATH=$PWD/.wcache PYTHONPATH=$PWD python bench/gpu/aot_cache.py            # every module
    WARP_CACHE_PATH=$PWD/.wcache PYTHONPATH=$PWD python bench/gpu/aot_cache.py wetted     # the named ones
"""

import argparse
import importlib
import pkgutil
import time

import warp as wp


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("modules", nargs="*", help="names under warp_lamp.kernels (default: all)")
    ap.add_argument("--arch", type=int, default=90)
    args = ap.parse_args()
    wp.config.quiet = True
    wp.init()
    import warp_lamp.kernels as kernels

    names = args.modules or [m.name for m in pkgutil.iter_modules(kernels.__path__)]
    for name in names:
        mod = importlib.import_module(f"warp_lamp.kernels.{name}")
        t = time.perf_counter()
        try:
            for ptx in (False, True):
                wp.compile_aot_module(mod, arch=args.arch, use_ptx=ptx)
        except RuntimeError as e:
            if "No compilable kernels" not in str(e):
                raise
            print(f"{name}: functions only, compiled into the modules that use them", flush=True)
            continue
        print(f"{name}: cubin and PTX for sm_{args.arch} in {time.perf_counter() - t:.1f} s", flush=True)


if __name__ == "__main__":
    main()
