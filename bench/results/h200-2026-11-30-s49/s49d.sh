#!/usr/bin/env bash
# Session 49, call 4: branch perf/replay (RP: the core records the watch, a replay kernel replays it)
# against main (M): bitwise on the GPU (rpcmp.py: REPLAY never vs always, five scenes; and with columns
# of 64 words, so that pellets spill), then bench.path cost 1e7 alternated twice and 1e8 each.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
( inn M timeout 250 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-M.txt ) &
( inn RP timeout 250 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-RP.txt ) &
( cd $root/.gpu/b/exp/RP && WARP_CACHE_PATH=/tmp/wc_C1 PYTHONPATH=/tmp/site:$PWD timeout 280 python3 $root/.gpu/b/rpcmp.py reach,map,rough,places,collisions 20000 cuda:0 > $out/cmp.txt 2>&1 ) &
( cd $root/.gpu/b/exp/RP && SPILL=64 WARP_CACHE_PATH=/tmp/wc_C2 PYTHONPATH=/tmp/site:$PWD timeout 280 python3 $root/.gpu/b/rpcmp.py reach,map 20000 cuda:0 > $out/cmp-spill.txt 2>&1 ) &
wait
echo "warm-up + compare $(( $(date +%s) - start )) s" | tee $out/times.txt
grep "replay vs" $out/cmp.txt $out/cmp-spill.txt; tail -3 $out/cmp.txt
for r in 1 2; do for t in M RP; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path.txt
for t in M RP; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$t: /"
done 2>&1 | tee $out/path-1e8.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt && ls
