#!/usr/bin/env bash
# session 43: terrain runs with many threads of few pellets (L = main e560c9c) against 85a1341 (A)
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
test -s /tmp/site/warp/bin/warp.so || { echo "fresh machine"; exit 3; }
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl 2>&1 | tail -2
root=$PWD
inn() { local t=$1; shift; (cd $root/.whl/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
start=$(date +%s)
for t in A L; do ( inn $t python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 > /dev/null ) & done; wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times-lanes.txt
for n in 1e6 1e7; do for t in A L; do
  inn $t python3 -m bench.meshes terrain --device cuda:0 --n $n --repeats 3 | grep "vacuum, terrain\|air, terrain\|terrain:" | sed "s/^/$n $t: /"
done; done 2>&1 | tee $out/lanes-terrain.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times-lanes.txt
