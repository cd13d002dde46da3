#!/usr/bin/env bash
# Nsight Compute's source counters on the queued exact tests, per line of kernels/wetted.py: the module built with
# line info and #line directives (carry its cubin: wp.config.lineinfo and line_directives, wp.compile_aot_module),
# the sources found where the cubin names them (/work/main, linked here). NCU_SCENE=lattice: the 1M lattice box.
# NCU_LINEINFO=0: the module as cached, without line info. On 2026-11-28 the report had no source either way; map the
# SASS on the dev machine with bench/experiments/ncu_source_lines.py (a lineinfo build of the same module).
# Writes $OUT/<tag>_cuda.csv (per source line) and <tag>_sass.csv (per instruction).
NCU="$(command -v ncu || ls /usr/local/cuda*/bin/ncu /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)"
if [ -z "$NCU" ]; then echo "ncu: not found on this machine"; exit 0; fi
[ -e /work/main ] || { mkdir -p /work && ln -s "$PWD" /work/main; }
scene="${NCU_SCENE:-specimen}"; kern=wet_classify_queued; tag="src_$scene"
timeout 400 "$NCU" --target-processes all -k "regex:$kern" --launch-skip 2 --launch-count 1 \
  --section SourceCounters --section WarpStateStats --section InstructionStats --section LaunchStats \
  --import-source yes -f -o "$OUT/$tag" \
  python3 bench/experiments/ncu_probe.py wetted $([ "${NCU_LINEINFO:-1}" = 0 ] || echo --lineinfo) --updates 4 --scene "$scene" > "$OUT/${tag}_ncu.log" 2>&1
echo "ncu rc=$?"; tail -3 "$OUT/${tag}_ncu.log"
"$NCU" --import "$OUT/$tag.ncu-rep" --page details --csv > "$OUT/${tag}_details.csv" 2>&1
grep -E "Duration|Executed Instructions\"|Warp Cycles Per Issued" "$OUT/${tag}_details.csv" | cut -c1-200 | head
"$NCU" --import "$OUT/$tag.ncu-rep" --page source --csv --print-source cuda > "$OUT/${tag}_cuda.csv" 2>&1
echo "cuda rc=$? lines=$(wc -l < "$OUT/${tag}_cuda.csv")"; head -c 600 "$OUT/${tag}_cuda.csv"; echo
"$NCU" --import "$OUT/$tag.ncu-rep" --page source --csv --print-source sass > "$OUT/${tag}_sass.csv" 2>&1
echo "sass rc=$? lines=$(wc -l < "$OUT/${tag}_sass.csv")"
gzip -f "$OUT/${tag}_sass.csv"; rm -f "$OUT/$tag.ncu-rep"
