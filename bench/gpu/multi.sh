#!/usr/bin/env bash
# Lists of parts at once on a machine of several GPUs, one list per GPU (each sees its GPU as cuda:0), under one
# deadline, every output kept in one tarball under $OUT refreshed every 20 s (the device tool brings back few
# files, and what a killed command left under $OUT still comes back):
#   LEASE_SECONDS=560 bash bench/gpu/multi.sh "cuda_tests_1 wetted32" "cuda_tests_2 area33" "deme38" "-"
# A list "-" leaves that GPU idle. lease.sh gives each part the time left before the deadline, at most PART_TIMEOUT.
# Kernel cache: bench/gpu/aot_cache.py builds .wcache (cubin and PTX; the H200 hosts load the cubin: carry both).
# Staging: run stage-warp's three steps as three calls, step 3 alone, then this in a fourth call carrying .wcache and
# the trees (step 3's .w3 and a full .wcache together pass the device tool's 64 MiB carry limit); the machine is
# released 30 s after a call, so make the calls back to back.
# two.sh is this script with two lists.
set -u
OUT="${OUT:-/tmp/out}"
WORK="${LEASE_WORK:-/tmp/lease}"
tag="$(date +%H%M%S)"
mkdir -p "$OUT"
here="$(dirname "${BASH_SOURCE[0]}")"
export LEASE_END=$(( $(date +%s) + ${LEASE_SECONDS:-540} ))
snap() { tar czf "$OUT/.lease.tgz" -C "$WORK" . 2>/dev/null && mv "$OUT/.lease.tgz" "$OUT/lease-$tag.tgz"; }
( while sleep 20; do snap; done ) >/dev/null 2>&1 & ticker=$!
pids=()
gpu=0
lists=("$@")
for list in "${lists[@]}"; do
  mkdir -p "$WORK/g$gpu"
  if [ "$list" != "-" ]; then
    (CUDA_VISIBLE_DEVICES=$gpu OUT="$WORK/g$gpu" bash "$here/lease.sh" $list > "$WORK/g$gpu.log" 2>&1) & pids+=($!)
  fi
  gpu=$((gpu + 1))
done
[ ${#pids[@]} -gt 0 ] && wait "${pids[@]}"
kill "$ticker" 2>/dev/null
snap
gpu=0
for list in "${lists[@]}"; do
  [ "$list" != "-" ] && { echo "== GPU $gpu: $list =="; tail -30 "$WORK/g$gpu.log"; }
  gpu=$((gpu + 1))
done
exit 0
