#!/usr/bin/env bash
# Issue 32: the queued exact tests' register cap (branch wetted-regs) in one run: main's code (.tMain, 255 registers,
# 256 threads per SM), 168 registers (this tree, 384), 128 (.r128, 512) and 255 with shared-memory spilling (.rS);
# carry .wcache with their sm_90 cubins (built ahead with wp.compile_aot_module).
AB_TREES="${AB_REGS:-main:.tMain r168:. r128:.r128 smem:.rS}" source bench/gpu/parts/ab32.sh
