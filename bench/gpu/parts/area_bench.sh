#!/usr/bin/env bash
# The benchmark's area section on the GPU (specimen at 2/3/4 cells/d, criterion 1 to 32, the overlapping ball, the
# lone sphere, the 1M lattice box); the area tests run in the tests part.
python3 bench/run_area_section.py --device cuda:0 --large --json "$OUT/area_section.json" 2>&1 | tail -40
