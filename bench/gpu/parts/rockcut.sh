#!/usr/bin/env bash
# Rock cutting under mud pressure (issue 25): the study, both lamp modes, on one GPU (about 5 minutes on an H100).
#
#   OUT=/tmp/out bash bench/gpu/parts/rockcut.sh                      # the study: the default device (a GPU)
#   OUT=/tmp/tiny bash bench/gpu/parts/rockcut.sh --tiny --device cpu  # the same path, tiny, on the CPU (~1 minute)
#
# Runs from the repository root; any arguments go to examples/rock_cutting.py. Writes $OUT/rock-cutting.json (copy it
# to bench/results/<gpu>-<date>-rock-cutting.json), $OUT/rock-cutting.png and $OUT/rock-cutting-damage.png (the
# README's figures, docs/rock_cutting*.png), $OUT/rock-cutting.log; prints the tables last. The rock's calibration
# (UCS, Brazilian tensile strength) is read from the committed CPU result: the specimens are packed on the CPU, so a
# GPU run of examples/bonded_rock.py would give the same figures to rounding (about 30 s more; not needed).
source "$(dirname "${BASH_SOURCE[0]}")/../preamble.sh"
CAL="bench/results/cpu-dev-2026-11-25-rock-calibration.json"
t0=$(date +%s)
python3 examples/rock_cutting.py --calibration "$CAL" --json "$OUT/rock-cutting.json" --plot "$OUT/rock-cutting.png" \
  "$@" > "$OUT/rock-cutting.log" 2>&1
rc=$?
echo "rc=$rc, $(( $(date +%s) - t0 )) s"
grep -E "^(first|all):|^  Fc" "$OUT/rock-cutting.log" | tail -30
sed -n '/^| lamp | P MPa | P \/ UCS/,$p' "$OUT/rock-cutting.log"
