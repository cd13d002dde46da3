"""Find whole-vector copies in a Warp module's generated CUDA: per function, the local vectors of 8 or more elements
that a ``wp::load`` (a struct member's vector read whole), ``wp::where`` (a vector merged after a branch) or
``wp::copy`` fills. In a kernel that runs at every update these copies are local-memory traffic (measured on the
exact test: six 512-byte copies of its gathered list, `bench/NOTES.md`).

    python bench/experiments/cuda_copies.py .wcache/1.19.0/wp_warp_lamp.kernels.area_*/*.cu

The static frame and spills of a kernel come from ptxas (CUDA 13.0 on the dev machine, which reads PTX up to 9.0):
build the module's PTX (``wp.compile_aot_module(module, arch=90, use_ptx=True)``), set its ``.version`` line to
9.0, drop its trailing NUL (``tr -d '\\000'``), then ``ptxas -arch=sm_90 -v -o /dev/null module.ptx``.
"""

import re
import sys


def copies(source: str) -> list[tuple[str, list[tuple[str, int, str]]]]:
    """(function head, [(variable, elements, how)]) for every forward function or kernel with such copies."""
    out = []
    for part in re.split(r'\n(?=static CUDA_CALLABLE |extern "C" __global__ )', source):
        head = part.split("(")[0][-80:].strip()
        if "adj_" in head or "backward" in head:
            continue
        sizes = {m.group(2): int(m.group(1)) for m in re.finditer(r"wp::vec_t<(\d+), [^>]+> (var_\w+);", part)}
        big = {v: n for v, n in sizes.items() if n >= 8}
        hits = [
            (m.group(1), big[m.group(1)], m.group(2))
            for m in re.finditer(r"(var_\w+) = (wp::load|wp::where|wp::copy)\(", part)
            if m.group(1) in big
        ]
        if hits:
            out.append((head, hits))
    return out


if __name__ == "__main__":
    for path in sys.argv[1:]:
        with open(path) as f:
            found = copies(f.read())
        print(f"{path}: {len(found)} functions with whole-vector copies")
        for head, hits in found:
            print(f"  {head}: " + ", ".join(f"{v} ({n}, {how})" for v, n, how in hits[:8]))
