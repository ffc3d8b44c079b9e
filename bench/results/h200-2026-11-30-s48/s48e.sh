#!/usr/bin/env bash
# session 48, call 5: the step log (branch perf/steplog: a phase's steps along a line logged and
# watched after, `physics.line_log`) S against main M (84dddf8): CUDA tests of S, per-pellet outputs of
# both on CUDA (float32, /tmp/lead/cmp48.py), bench.path cost 1e7 alternated twice, 1e8 each, S at 1e9.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
( cd $root && WARP_RICOCHET_TEST_DEVICES=cuda:0 WARP_CACHE_PATH=/tmp/wc_T PYTHONPATH=/tmp/site:$root/.gpu/t/site:$root/.gpu/b/exp/S timeout 280 python3 -m pytest -q -p no:cacheprovider -n 6 tests/test_path_watch.py tests/test_lanes.py tests/test_path_calls.py --deselect tests/test_path_calls.py::test_an_out_of_line_function_is_a_call_in_ptx_and_runs_on_the_cpu > $out/cuda-tests.txt 2>&1; echo "rc $?" >> $out/cuda-tests.txt ) &
for t in M S; do
  ( inn $t timeout 250 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path-$t.txt ) &
  ( PRECS=float32 inn $t timeout 280 python3 $root/.gpu/b/cmp48.py $out/cmp-$t.npz cuda:0 > $out/cmp-$t.txt ) &
done; wait
echo "tests + warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
tail -3 $out/cuda-tests.txt
python3 $root/.gpu/b/cmpnpz.py $out/cmp-M.npz $out/cmp-S.npz 2>&1 | tee $out/cmp.txt
for r in 1 2; do for t in M S; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path.txt
echo "path 1e7 $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for t in M S; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$t: /"
done 2>&1 | tee $out/path-1e8.txt
echo "path 1e8 $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn S timeout 150 python3 -m bench.path cost --device cuda:0 --sizes 1e9 --repeats 1 | filt | grep "N 1e" | sed "s/^/S: /" 2>&1 | tee $out/path-1e9.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
