#!/usr/bin/env bash
# session 57, call 1: R (an air step's roots at one evaluation site: `plane_theta` one loop, a
# face's two passes one call) and E (a small mesh's edge search out of line in CUDA code) against
# main M: per-pellet outputs on the H200 (cmpgpu.py: landings in air over the terrain, the mesh of
# the plane and the plane; kernels to rest over turf, the trap field, the mesh and the box, in vacuum
# and in air), and the terrain in air at 1e7, M and R alternated twice.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
c=$root/bench/results/h200-2026-12-01-s57/cmpgpu.py
mkdir -p /tmp/cg
LAND=terrain-air,terrain-air-3,mesh-air-3,paper-air,paper-air-64
for t in M R; do
  ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 --flights air > $out/warm-$t.txt ) &
  ( inn $t timeout 280 python3 $c run 2e4 /tmp/cg $t cuda:0 $LAND > $out/cmp-$t-a.txt ) &
done
( inn M timeout 280 python3 $c run 2e4 /tmp/cg M cuda:0 turf-rest-air,trap-rest,mesh-rest-air > $out/cmp-M-b.txt ) &
( inn M timeout 280 python3 $c run 2e4 /tmp/cg M cuda:0 mesh-rest-vac,box-rest-air,box-rest-vac > $out/cmp-M-c.txt ) &
( inn R timeout 280 python3 $c run 2e4 /tmp/cg R cuda:0 turf-rest-air,trap-rest,mesh-rest-air,box-rest-air > $out/cmp-R-b.txt ) &
( inn E timeout 280 python3 $c run 2e4 /tmp/cg E cuda:0 mesh-rest-air,mesh-rest-vac,box-rest-air,box-rest-vac > $out/cmp-E.txt ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in M R; do
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 --flights air | filt | grep "pellets/s" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
echo "terrain $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for t in R E; do echo "== M against $t"; inn M python3 $c compare /tmp/cg M $t | filt; done 2>&1 | tee $out/compare.txt
cd $out && tar czf all.tgz *.txt
