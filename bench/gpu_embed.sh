#!/usr/bin/env bash
# One device lease for embedding: every test on CPU and CUDA (with overlap and newton from carried wheels), the
# SphereTest at four resolutions with its step in one CUDA graph, and the Newton ball on CUDA.
set -o pipefail
export PYTHONUNBUFFERED=1
OUT="${OUT:-/tmp/out}"
mkdir -p "$OUT"
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --target /root/site .whl/*.whl
python3 -m pytest -q -p no:cacheprovider tests 2>&1 | tee "$OUT/pytest.log" | tail -6
python3 examples/sphere_test.py --device cuda:0 --steps 40000 --json "$OUT/sphere_test.json" 2>&1 \
  | tee "$OUT/sphere_test.log" | grep -v "unbalanced ratio"
python3 examples/newton_pressure.py --device cuda:0 --frames 200 2>&1 | tee "$OUT/newton.log"
