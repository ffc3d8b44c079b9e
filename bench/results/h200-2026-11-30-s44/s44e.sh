#!/usr/bin/env bash
# session 44, call 5: main (N) against main with a stricter vote (S: a lane in flight also waits while any lane of its warp is at a contact):
# session 42's open question (the map in half the time in a tree with the default unroll)
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
for t in N S; do
  ( inn $t python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path-$t.txt ) &
  ( inn $t python3 -m bench.rest throughput --device cuda:0 --sizes 1e5 --repeats 1 --only "rest, turf" > $out/warm-rest-$t.txt ) &
done; wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in N S; do
  inn $t timeout 120 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/order-path.txt
echo "path $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for r in 1 2; do for t in N S; do
  inn $t python3 -m bench.rest throughput --device cuda:0 --sizes 1e7 --repeats 2 --only "rest, turf" | filt | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/order-rest.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
