#!/usr/bin/env bash
# session 47, call 5: the CUDA tests of the lanes and the path watch on the committed candidate (the
# repository's tree, C3), then where C3's reach cost is: HD (C3, no event ever taken: a hack), HE (C3,
# the events' condition kept, their bodies empty: a hack). bench.path cost 1e7 alternated twice.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
( cd $root && WARP_RICOCHET_TEST_DEVICES=cuda:0 WARP_CACHE_PATH=/tmp/wc_T PYTHONPATH=/tmp/site:$root/.gpu/t/site:$PWD timeout 330 python3 -m pytest -q -p no:cacheprovider tests/test_lanes.py tests/test_path_watch.py > $out/cuda-tests.txt 2>&1; echo "rc $?" >> $out/cuda-tests.txt ) &
tests=$!
for t in C3 HD HE; do
  ( inn $t timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path-$t.txt ) &
done
wait
tail -n 3 $out/cuda-tests.txt
echo "tests and warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in C3 HD HE; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
