#!/usr/bin/env bash
# The first-hour branch's tests on CUDA (the device fixture adds cuda:0 on a GPU machine): the CLI in every mode
# with --device cuda:0 against lamp_forces on the GPU, frames and porosity on the GPU, resolve_device with an
# ordinal past the GPUs present, the README's blocks (the Newton block records its CUDA graph), the examples.
# Under 5 minutes on one H100 (about 2 on the 2-core CPU). Writes $OUT/firsthour_pytest.log; prints the summary.
source "$(dirname "$0")/../preamble.sh"
python3 -m pytest -q -p no:cacheprovider -rfE \
  tests/test_cli_first_hour.py tests/test_first_hour_api.py tests/test_readme.py tests/test_particles_io.py \
  tests/test_plots_examples.py tests/test_specimen_sizes.py tests/test_bench_porosity_progress.py \
  tests/test_cli.py tests/test_frames.py 2>&1 | tee "$OUT/firsthour_pytest.log" | tail -12
