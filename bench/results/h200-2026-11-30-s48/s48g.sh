#!/usr/bin/env bash
# session 48, call 7: variants of the step log S (main after perf/steplog): SA, the step loop without the lanes' meeting
# (going_alone: the watch is out of the loop); S64, 64 steps a log (32 in S).
# bench.path cost 1e7 alternated twice, 1e8 each.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
for t in S SA S64; do
  ( inn $t timeout 250 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path-$t.txt ) &
done; wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
tail -3 $out/warm-path-S.txt
for r in 1 2; do for t in S SA S64; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path.txt
echo "path 1e7 $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for t in S SA S64; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$t: /"
done 2>&1 | tee $out/path-1e8.txt
echo "path 1e8 $(( $(date +%s) - start )) s" | tee -a $out/times.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
