#!/usr/bin/env bash
# wetted_ncu_src on the 1M lattice box.
NCU_SCENE=lattice source bench/gpu/parts/wetted_ncu_src.sh
