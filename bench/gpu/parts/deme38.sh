#!/usr/bin/env bash
# DEM-Engine (DEME 3): the SphereTest held by the lamp inside DEME, then the lamp's share of a DEME step (4,628, ~1M).
# Needs ../shared/gpu/stage-deme's four device steps first (/root/dv, deme 3.0.19 + CUDA 12.8 wheels) and Warp as in
# stage-warp. About 7 minutes: DEME's first Initialize() compiles for ~3 (Warp's kernels compile beside it), the
# settle run, the shares; the 1M stage runs under the time left. One file back: $OUT/deme38.json (the log is
# lease.sh's $OUT/deme38.log).
PY="${DEME38_PY:-/root/dv/bin/python}"  # DEME38_PY, DEME38_ARGS="--standin ...": a CPU dry run
export PYTHONPATH=/root/site:/opt/torch/.venv/lib/python3.12/site-packages:$PWD${PYTHONPATH:+:$PYTHONPATH}
if [ ! -x "$PY" ]; then
  echo "deme38: $PY missing: run ../shared/gpu/stage-deme's device steps first"
  echo '{"error": "deme venv /root/dv missing (stage-deme not run)"}' > "$OUT/deme38.json"
  exit 3
fi
"$PY" -c "import deme, warp; print('deme', deme.__version__, '| warp', warp.config.version)" 2>&1 | tail -3
( "$PY" bench/deme_share.py --stage warm --json /tmp/deme38-warm.json > /tmp/deme38-warm.log 2>&1; tail -2 /tmp/deme38-warm.log ) &
warm=$!
t0=$(date +%s)
timeout 480 "$PY" bench/deme_share.py --json "$OUT/deme38.json" --budget "${DEME38_BUDGET:-430}" ${DEME38_ARGS:-} 2>&1 \
  | grep -v "^Warp \(UserWarning\|DeprecationWarning\)"
rc=${PIPESTATUS[0]}
wait "$warm" 2>/dev/null
echo "deme38: exit $rc after $(( $(date +%s) - t0 )) s"
# The real-DEME test, where time is left (DEME's kernels are compiled by now; it builds as the example does).
left=$(( 470 - ($(date +%s) - t0) ))
if [ "$left" -gt 30 ] && "$PY" -c "import pytest" 2>/dev/null; then
  timeout "$left" "$PY" -m pytest tests/test_deme.py -q -p no:cacheprovider -k "inside_deme or owner_kernels" 2>&1 | tail -4
fi
[ -f "$OUT/deme38.json" ] || echo "{\"error\": \"deme_share.py exit $rc before its first stage ended\"}" > "$OUT/deme38.json"
exit "$rc"
