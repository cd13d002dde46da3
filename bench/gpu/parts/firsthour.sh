#!/usr/bin/env bash
# The first-hour branch's tests on CUDA: the CLI in every mode on cuda:0, the README's blocks, the examples.
# Sourced by bench/gpu/lease.sh after the preamble ($OUT, PYTHONPATH set): bash bench/gpu/lease.sh firsthour.
# The device fixture adds cuda:0 on a GPU machine: the CLI's modes with --device cuda:0 against lamp_forces on the
# GPU, frames and porosity on the GPU, resolve_device with an ordinal past the GPUs present, the Newton block of the
# README recording its CUDA graph. About 25 s on the 2-core CPU without a GPU; well under 5 minutes on an H100.
python3 -m pytest -q -p no:cacheprovider -rfE \
  tests/test_cli.py tests/test_errors.py tests/test_readme.py tests/test_cli.py \
  tests/test_examples.py tests/test_scenes.py tests/test_bench.py \
  tests/test_cli.py tests/test_frames.py 2>&1 | tee "${OUT:-/tmp/out}/firsthour_pytest.log" | tail -12
