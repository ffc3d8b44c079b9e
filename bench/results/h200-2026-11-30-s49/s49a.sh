#!/usr/bin/env bash
# Session 49, call 1: CUDA tests of main;
# bench.path logs on CUDA (the step log against each step at once: races would show); bench.path
# cost of main M against perf/flightlog FL, 1e7 alternated twice, 1e8 each.
# Trees: .gpu/b/exp/M (main), .gpu/b/exp/FL (git worktree of perf/flightlog), built as in session 48:
#   git ls-files -co --exclude-standard | grep -v "^bench/results\|^docs/\|RESULTS\|CHANGELOG\|^tests/" | tar ...
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
( cd $root && WARP_RICOCHET_TEST_DEVICES=cuda:0 WARP_CACHE_PATH=/tmp/wc_T PYTHONPATH=/tmp/site:$root/.gpu/t/site:$PWD timeout 280 python3 -m pytest -q -p no:cacheprovider -n 6 tests/test_path_watch.py tests/test_lanes.py tests/test_path_calls.py --deselect tests/test_path_calls.py::test_an_out_of_line_function_is_a_call_in_ptx_and_runs_on_the_cpu > $out/cuda-tests.txt 2>&1; echo "rc $?" >> $out/cuda-tests.txt ) &
for t in M FL; do
  ( inn $t timeout 250 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path-$t.txt ) &
done
( inn M timeout 280 python3 -m bench.path logs --device cuda:0 --count 20000 > $out/logs.txt ) &
wait
echo "tests + warm-up + logs $(( $(date +%s) - start )) s" | tee $out/times.txt
tail -3 $out/cuda-tests.txt; grep "against" $out/logs.txt
for r in 1 2; do for t in M FL; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path.txt
for t in M FL; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$t: /"
done 2>&1 | tee $out/path-1e8.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt && ls
