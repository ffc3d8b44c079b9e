#!/usr/bin/env bash
# session 43: the terrain's height grid (CH) against its base (A), 1e7 pellets, vacuum and air
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
test -s /tmp/site/warp/bin/warp.so || { echo "fresh machine"; exit 3; }
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl 2>&1 | tail -2
root=$PWD
inn() { local t=$1; shift; (cd $root/.whl/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
start=$(date +%s)
for t in A CH; do ( inn $t python3 -m bench.meshes terrain --device cuda:0 --n 1e5 --repeats 1 > $out/warm-terrain-$t.txt ) & done; wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times-terrain.txt
for t in A CH A CH; do
  inn $t timeout 100 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 | grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\"cpu\"\|\"cuda:0\"\|^Module " | sed "s/^/$t: /"
done 2>&1 | tee $out/terrain.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times-terrain.txt
