#!/usr/bin/env bash
# session 45, call 9: the branch (V) on CUDA: its new and changed tests (lanes, the path's watch), then
# bench.path cost at 1e8 and 1e9 (pytest and hypothesis carried in .gpu/t)
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/V && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$root/.gpu/t/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
( inn P python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path.txt ) &
WARP_RICOCHET_TEST_DEVICES=cuda:0 inn T timeout 240 python3 -m pytest -q -x -p no:cacheprovider tests/test_lanes.py tests/test_path_watch.py 2>&1 | tail -6 | tee $out/cuda-tests.txt
wait
echo "tests and warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
inn P timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | tee $out/path-1e8.txt
echo "1e8 $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn P timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e9 --repeats 1 | filt | grep "N 1e" | tee $out/path-1e9.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
