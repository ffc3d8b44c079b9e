#!/usr/bin/env bash
# session 45, call 7: main (N), Y and Z (Y + a straight stretch's cells along u counted as one run at once):
# bench.path cost at 1e7 alternated twice, then Z at 1e8; the rest cases on N and Z
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
for t in N Y Z; do
  ( inn $t python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path-$t.txt ) &
done
( inn Z python3 -m bench.rest throughput --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-rest-Z.txt ) &
( inn N python3 -m bench.rest throughput --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-rest-N.txt ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in Z Y N; do
  inn $t timeout 120 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path.txt
echo "path $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn Z timeout 150 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/Z: /" | tee $out/path-1e8.txt
echo "path 1e8 $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for t in Z N; do
  inn $t python3 -m bench.rest throughput --device cuda:0 --sizes 1e7 --repeats 2 | filt | sed "s/^/$t: /"
done 2>&1 | tee $out/rest.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
