#!/usr/bin/env bash
# First-use compile time of every kernel module on this GPU (a cold Warp cache), module by module.
python3 - <<'PY' 2>&1 | tee "$OUT/compile.log"
import importlib, pkgutil, time
import warp as wp
import warp_lamp.kernels as k
wp.init()
total = 0.0
for info in pkgutil.iter_modules(k.__path__):
    name = f"warp_lamp.kernels.{info.name}"
    importlib.import_module(name)
    t = time.perf_counter()
    wp.load_module(name, device="cuda:0")
    dt = time.perf_counter() - t
    total += dt
    print(f"| {name} | {dt:.1f} s |", flush=True)
print(f"| all | {total:.1f} s |")
PY
