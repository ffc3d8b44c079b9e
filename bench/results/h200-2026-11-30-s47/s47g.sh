#!/usr/bin/env bash
# session 47, call 7: the CUDA tests of the lanes, the path watch, and its calls on
# the repository's tree (main at the reach alone's chord), 8 workers (the terrain watch needs SciPy: not there).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
start=$(date +%s)
( cd $root && WARP_RICOCHET_TEST_DEVICES=cuda:0 WARP_CACHE_PATH=/tmp/wc_T PYTHONPATH=/tmp/site:$root/.gpu/t/site:$PWD timeout 300 python3 -m pytest -q -p no:cacheprovider -n 8 tests/test_lanes.py tests/test_path_watch.py tests/test_path_calls.py > $out/cuda-tests.txt 2>&1; echo "rc $?" >> $out/cuda-tests.txt )
tail -n 6 $out/cuda-tests.txt
echo "done $(( $(date +%s) - start )) s" | tee $out/times.txt
