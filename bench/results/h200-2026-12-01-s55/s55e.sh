#!/usr/bin/env bash
# session 55, call 5: H (E with the contact-normal and inside tests' edge lengths found only where
# a point is past an edge, a small mesh's edges searched while a centre leaving a face from within R
# gets out to R, and the walk's cells passed whose window starts at or after the contact found)
# against E and main M: plane 1e8 and terrain 1e7, alternated twice; cmpwalk on H.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M E H; do
  ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 > $out/warm-$t.txt ) &
  ( inn $t timeout 250 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 > $out/warm-plane-$t.txt ) &
done
( inn H timeout 250 python3 $root/bench/results/h200-2026-11-30-s54/cmpwalk.py 2e3 cuda:0 float32 > $out/warm-cmp.txt ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in M E H; do
  inn $t timeout 60 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 | filt | grep "pellets/s\|plane time" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/plane.txt
echo "plane $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for r in 1 2; do for t in M E H; do
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 | filt | grep "vacuum, terrain\|air, terrain" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
echo "terrain $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn H timeout 120 python3 $root/bench/results/h200-2026-11-30-s54/cmpwalk.py 2e4 cuda:0 float32 | filt | tee $out/cmpwalk.txt
echo "cmpwalk $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt
