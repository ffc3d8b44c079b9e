#!/usr/bin/env bash
# session 44, call 8: the terrain with helper terrain2's hop screen in air (P, perf/terrain2 9dafa1d)
# against main (B, 623b996)
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
test -s /tmp/site/warp/bin/warp.so || { echo "fresh machine"; exit 3; }
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl 2>&1 | tail -2
root=$PWD
inn() { local t=$1; shift; (cd $root/.whl/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
start=$(date +%s)
for t in B P; do ( inn $t python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 > $out/warm-$t.txt ) & done; wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in B P; do
  inn $t python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 | grep "vacuum, terrain\|air, terrain" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain-screen.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
