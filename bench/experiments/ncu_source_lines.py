"""Nsight Compute's per-instruction counts (``bench/gpu/parts/wetted_ncu_src.sh``'s ``*_sass.csv.gz``) attributed to
the kernel module's functions and Python statements, on the dev machine.

The device's report carries no line info, so the same module is built here with ``wp.config.lineinfo`` (and no #line
directives: the lines then refer to Warp's generated .cu, whose comments carry the Python statements), disassembled
with ``nvdisasm -gi`` (the ``nvidia-cuda-nvdisasm`` wheel), checked to be the report's instruction sequence, and each
instruction credited to the innermost generated function of its inline chain (self) and to every function on that
chain (inclusive).

    python bench/experiments/ncu_source_lines.py DISASM.sass MODULE.cu KERNEL REPORT_sass.csv.gz [...]

KERNEL: the start of the kernel's name (``wet_classify_queued``).
"""

from __future__ import annotations

import bisect
import collections
import csv
import gzip
import re
import sys

FUNC = re.compile(r"^(?:static CUDA_CALLABLE .*? |extern \"C\" __global__ void |__global__ void )(\w+)\(")
PY = re.compile(r"//\s(.*?)\s+<L (\d+)>\s*$")
LOC = re.compile(r'File "([^"]+)", line (\d+)')
INST = re.compile(r"\s*/\*([0-9a-f]{4,})\*/\s+(.*?);")


def opcode(text: str) -> str:
    parts = text.strip().split()
    return parts[1] if parts[0].startswith("@") else parts[0]


def main() -> None:
    sass_file, cu_file, kernel, reports = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
    cu = open(cu_file).read().split("\n")
    funcs = [(n, m.group(1)) for n, line in enumerate(cu, start=1) if (m := FUNC.match(line))]
    starts = [n for n, _ in funcs]
    statement, last = {}, None
    for n, line in enumerate(cu, start=1):
        if m := PY.search(line):
            last = m.group(1).strip()[:70]
        statement[n] = last

    def func_of(n: int) -> str:
        k = bisect.bisect_right(starts, n) - 1
        return funcs[k][1] if k >= 0 else "?"

    lines = open(sass_file).read().split("\n")
    first = next(i for i, line in enumerate(lines) if line.startswith(".text." + kernel))
    inst, chain, pending = [], (), []
    for line in lines[first:]:
        if line.startswith("//-----"):
            break
        if "//##" in line:
            pending += [int(m.group(2)) for m in LOC.finditer(line) if m.group(1).endswith(".cu")]
            continue
        if m := INST.match(line):
            if pending:
                chain, pending = tuple(pending), []
            inst.append((opcode(m.group(2)), chain))
    for report in reports:
        rows = list(csv.reader(gzip.open(report, "rt")))
        head, data = rows[1], rows[2:]
        if [opcode(r[1]) for r in data] != [op for op, _ in inst]:
            raise SystemExit(f"{report}: not the disassembled instruction sequence")
        col = [head.index(k) for k in ("Instructions Executed", "Thread Instructions Executed")]
        col.append(head.index("Warp Stall Sampling (All Samples)"))
        own = collections.defaultdict(lambda: [0, 0, 0])
        incl = collections.defaultdict(lambda: [0, 0, 0])
        stmt = collections.defaultdict(lambda: [0, 0, 0])
        for (_, ch), r in zip(inst, data, strict=True):
            v = [int(r[c] or 0) for c in col]
            names = {func_of(n) for n in ch} or {"?"}
            keys = [(own, func_of(ch[0]) if ch else "?"), (stmt, (func_of(ch[0]), statement.get(ch[0])) if ch else "?")]
            keys += [(incl, name) for name in names]
            for table, key in keys:
                for j in range(3):
                    table[key][j] += v[j]
        tot = [sum(v[j] for v in own.values()) for j in range(3)]
        print(f"\n{report}: {tot[0]:,} warp instructions, {tot[1] / tot[0]:.1f} lanes active, {tot[2]:,} stall samples")
        print("| function | self: warp inst % | stall % | lanes | inclusive: warp inst % | stall % |")
        print("| --- | --- | --- | --- | --- | --- |")
        for name, v in sorted(incl.items(), key=lambda kv: -kv[1][2])[:24]:
            s = own.get(name, [0, 0, 0])
            print(
                f"| {name} | {100 * s[0] / tot[0]:.1f} | {100 * s[2] / tot[2]:.1f} | {s[1] / max(s[0], 1):.1f} | "
                f"{100 * v[0] / tot[0]:.1f} | {100 * v[2] / tot[2]:.1f} |"
            )
        print("statements (self) by stall samples:")
        for key, v in sorted(stmt.items(), key=lambda kv: -kv[1][2])[:30]:
            share = f"inst {100 * v[0] / tot[0]:.1f}%, stall {100 * v[2] / tot[2]:.1f}%"
            print(f"  {key}: {share}, lanes {v[1] / max(v[0], 1):.1f}")


if __name__ == "__main__":
    main()
