# Sourced by every lease script: logs and JSON to $OUT, the GPU named, carried wheels installed.
# Sourced by bench/gpu/lease.sh (after ../shared/gpu stage-warp steps).
set -o pipefail
export PYTHONUNBUFFERED=1
OUT="${OUT:-/tmp/out}"
mkdir -p "$OUT"
export PYTHONPATH="/root/site:$PWD${PYTHONPATH:+:$PYTHONPATH}"
if compgen -G ".whl/*.whl" >/dev/null && [ ! -f /root/site/.whl-installed ]; then
  # Optional test extras (overlap, newton, scipy) that the machine lacks, carried as wheels.
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /root/site .whl/*.whl \
    && touch /root/site/.whl-installed
fi
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv | tee "$OUT/gpu.txt"
# The dev machine's specimen packings, carried in .scenes/ (the same particles everywhere; no packing time here).
[ -d .scenes ] && export WARP_LAMP_CACHE="$PWD/.scenes"
