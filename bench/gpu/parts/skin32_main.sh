#!/usr/bin/env bash
# skin32 (bench/gpu/parts/skin32.sh) on main's library, carried as .tMain (git archive main warp_lamp): the before of
# an A/B with skin32 on this tree, same script. Writes $OUT/skin32_main.json and $OUT/skin32_main.log.
LOG="$OUT/skin32_main.log"
: >"$LOG"
t0=$SECONDS
PYTHONPATH="$PWD/.tMain:/root/site" timeout 330 python3 bench/gpu/parts/skin32_run.py --device cuda:0 \
  --out "$OUT/skin32_main.json" ${SKIN32_ARGS:-} >>"$LOG" 2>&1
echo "skin32_main: rc $? in $((SECONDS - t0)) s" | tee -a "$LOG"
tail -n 24 "$LOG"
