#!/usr/bin/env bash
# One lease on the lent GPU: the preamble, then the named parts in order (bench/gpu/parts/<part>.sh), each
# logged to $OUT/<part>.log; a short table of what ran, and how long, last.
#
#   bash bench/gpu/lease.sh tests bench          # after ../shared/gpu's stage-warp steps
#   bash bench/gpu/lease.sh --list
#
# A part is a bash file sourced in a subshell after the preamble (so $OUT, PYTHONPATH and the carried wheels are
# set); it may read $BEFORE, a checkout of the code before a change carried beside the tree (see parts/replay.sh).
set -u
here="$(cd "$(dirname "$0")" && pwd)"
if [ "${1:-}" = "--list" ] || [ $# -eq 0 ]; then
  echo "parts:"; for f in "$here"/parts/*.sh; do printf '  %-18s %s\n' "$(basename "$f" .sh)" "$(sed -n 2p "$f" | sed 's/^# //')"; done
  exit 0
fi
source "$here/preamble.sh"
summary=()
for part in "$@"; do
  file="$here/parts/$part.sh"
  [ -f "$file" ] || { echo "lease: no part '$part' (bench/gpu/lease.sh --list)"; exit 2; }
  echo "== $part =="
  t0=$(date +%s)
  # Each part under a time limit, so that one that hangs cannot cost the others their results.
  limit="${PART_TIMEOUT:-580}"
  if [ -n "${LEASE_END:-}" ]; then
    # multi.sh's deadline: a part gets the time left, and none starts in the last 15 s.
    left=$(( LEASE_END - $(date +%s) )); [ "$left" -lt "$limit" ] && limit=$left
    if [ "$limit" -lt 15 ]; then summary+=("$(printf '| %-18s | skip | %5s s |' "$part" 0)"); continue; fi
  fi
  ( timeout "$limit" bash -c "source '$here/preamble.sh' >/dev/null; source '$file'" ) 2>&1 | tee "$OUT/$part.log"
  rc=${PIPESTATUS[0]}
  summary+=("$(printf '| %-18s | %4s | %5s s |' "$part" "$rc" "$(( $(date +%s) - t0 ))")")
done
echo
echo "| part               |   rc |    time |"
echo "| ---                | ---  | ---     |"
printf '%s\n' "${summary[@]}"
