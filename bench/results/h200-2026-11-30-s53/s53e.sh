#!/usr/bin/env bash
# session 53, call 5: the device tests of the grid-constant change and the pipeline on CUDA (the
# carried checkout: main with physics/grid_constant.py), CUDA only.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
export WARP_RICOCHET_TEST_DEVICES=cuda:0 WARP_CACHE_PATH=/tmp/wc_tests
timeout 100 python3 -m pytest -q -p no:cacheprovider tests/test_grid_constant.py 2>&1 | tail -15 | tee $out/grid_constant.txt
timeout 200 python3 -m pytest -q -p no:cacheprovider -x tests/test_pipeline.py tests/test_chunk_plan.py 2>&1 | tail -15 | tee $out/pipeline.txt
