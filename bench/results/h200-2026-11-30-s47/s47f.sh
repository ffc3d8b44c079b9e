#!/usr/bin/env bash
# session 47, call 6: the CUDA chord tests (tests/test_path_watch.py -k chord, 4 workers) on the
# repository's tree (C3, main), then C3 against C4 (C3, a chord's start kept in the pending steps and
# marked where it ends: no event to begin one). bench.path cost 1e7 alternated twice, 1e8 once each.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
( cd $root && WARP_RICOCHET_TEST_DEVICES=cuda:0 WARP_CACHE_PATH=/tmp/wc_T PYTHONPATH=/tmp/site:$root/.gpu/t/site:$PWD timeout 280 python3 -m pytest -q -p no:cacheprovider -n 4 tests/test_path_watch.py -k chord > $out/cuda-tests.txt 2>&1; echo "rc $?" >> $out/cuda-tests.txt ) &
for t in C3 C4; do
  ( inn $t timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path-$t.txt ) &
done
wait
tail -n 4 $out/cuda-tests.txt
echo "tests and warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in C4 C3; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
