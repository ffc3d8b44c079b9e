#!/usr/bin/env bash
# session 46, call 7: S3 against S4 (S3 with a step's quick watch out of line on CUDA): bench.path cost 1e7 once each.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
for t in S3 S4; do
  ( inn $t timeout 70 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path-$t.txt ) &
done; wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for t in S4 S3; do
  inn $t timeout 25 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | grep "N 1e" | sed "s/^/$t: /"
done 2>&1 | tee $out/path.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
