#!/usr/bin/env bash
# session 46, call 6: R (main + perf/reachends) against S3 (R + a straight phase's steps watched as one
# chord: reach and walk where the phase ends). CUDA tests of S3 (path watch, lanes) beside the warm-ups;
# bench.path cost 1e7 alternated twice, 1e8 once each, bench.rest throughput 1e7 once each; S3 at 1e9.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
( cd .gpu/b/exp/S3 && WARP_RICOCHET_TEST_DEVICES=cuda:0 WARP_CACHE_PATH=/tmp/wc_TS3 PYTHONPATH=/tmp/site:$root/.gpu/t/site:$PWD timeout 200 python3 -m pytest -q -p no:cacheprovider tests/test_lanes.py tests/test_path_watch.py > $out/cuda-tests.txt 2>&1; echo "rc $?" >> $out/cuda-tests.txt ) &
for t in R S3; do
  ( inn $t timeout 150 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path-$t.txt ) &
  ( inn $t timeout 150 python3 -m bench.rest throughput --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-rest-$t.txt ) &
done; wait
tail -n 4 $out/cuda-tests.txt
echo "tests and warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in S3 R; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path.txt
echo "path 1e7 $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for t in S3 R; do
  inn $t timeout 90 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$t: /"
done 2>&1 | tee $out/path-1e8.txt
echo "path 1e8 $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for t in S3 R; do
  inn $t timeout 60 python3 -m bench.rest throughput --device cuda:0 --sizes 1e7 --repeats 2 | filt | grep rest | sed "s/^/$t: /"
done 2>&1 | tee $out/rest.txt
echo "rest $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn S3 timeout 150 python3 -m bench.path cost --device cuda:0 --sizes 1e9 --repeats 1 | filt | grep "N 1e" | sed "s/^/S3: /" | tee $out/path-1e9.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
