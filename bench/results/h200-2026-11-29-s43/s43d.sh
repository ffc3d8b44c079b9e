#!/usr/bin/env bash
# session 43, call 4: A (85a1341), M (main: air functions out of line), H (M + the flattened rest loop),
# C43 (A + the CPU helper's one fewer air-law evaluation a surface step), CH (A + the terrain's height grid)
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
for t in A M H C43; do
  ( inn $t python3 -m bench.rest throughput --device cuda:0 --sizes 1e5 --repeats 1 --only "rest, turf" > $out/warm-rest-$t.txt ) &
done
for t in M H; do ( inn $t python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path-$t.txt ) & done
wait
echo "warm-up (compile) $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in A M H C43; do
  inn $t python3 -m bench.rest throughput --device cuda:0 --sizes 1e7 --repeats 2 --only "rest, turf" | filt | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/rest.txt
echo "rest done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for t in M H; do
  inn $t timeout 100 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | sed "s/^/$t: /"
done 2>&1 | tee $out/path.txt
echo "all done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
