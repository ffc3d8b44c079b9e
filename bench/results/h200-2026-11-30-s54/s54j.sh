#!/usr/bin/env bash
# session 54, call 10 (the device time's last 150 s): main's head (G, the raster's top held only where
# the line leaves the raster) against e380e41 (P): bench.meshes terrain 1e7, vacuum, alternated twice.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in P G; do
  ( inn $t timeout 100 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 --flights vacuum > $out/warm-$t.txt ) &
done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in P G; do
  inn $t timeout 30 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 --flights vacuum | filt | grep "vacuum, terrain" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
