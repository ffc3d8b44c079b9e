#!/usr/bin/env bash
# session 46, call 1: CUDA tests (N); main (N), R (perf/reachends), M (perf/stepmeet): bench.path cost 1e7
# and bench.rest throughput 1e7 alternated twice; then Nsight source counters of N's reach case
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
( cd .gpu/b/exp/N && WARP_RICOCHET_TEST_DEVICES=cuda:0 WARP_CACHE_PATH=/tmp/wc_TN PYTHONPATH=/tmp/site:$root/.gpu/t/site:$PWD timeout 290 python3 -m pytest -q -p no:cacheprovider -x tests/test_lanes.py tests/test_path_watch.py > $out/cuda-tests-full.txt 2>&1; echo "rc $?" >> $out/cuda-tests-full.txt ) &
for t in N R M; do
  ( inn $t python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path-$t.txt ) &
  ( inn $t python3 -m bench.rest throughput --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-rest-$t.txt ) &
done; wait
tail -5 $out/cuda-tests-full.txt
echo "tests and warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in M R N; do
  inn $t timeout 120 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path.txt
echo "path $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for r in 1 2; do for t in M R N; do
  inn $t python3 -m bench.rest throughput --device cuda:0 --sizes 1e7 --repeats 2 | filt | grep rest | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/rest.txt
echo "rest $(( $(date +%s) - start )) s" | tee -a $out/times.txt
( cd .gpu/b/exp/N && WARP_CACHE_PATH=/tmp/wc_N timeout 150 bash bench/ncu_source.sh $out/ncu-N-reach 1e6 --case "to rest, reach" > $out/ncu-N-reach.log 2>&1 ); rm -f $out/ncu-N-reach/rep.ncu-rep
head -30 $out/ncu-N-reach/lines.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
