#!/usr/bin/env bash
# session 57, call 2: the air's root finding. M2 = main with E landed (40a9b46); Z: a face's own
# plane crossed (`through`) found only where its offset plane is not met over it; ZK: Z with the
# root's bracket ends given by the callers (the step's ends, a turn's or a bottom's gap: two
# evaluations fewer a root, the same iterates); ZK1: ZK with `root` out of line in CUDA code;
# ZKN: ZK with a safeguarded Newton iteration (other bits). The terrain in air at 1e7, alternated
# twice; per-pellet outputs of ZK against M2 on the H200 (cmpgpu.py).
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
TREES="M2 Z ZK ZK1 ZKN"
for t in $TREES; do
  ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 --flights air > $out/warm-$t.txt ) &
done
for t in M2 ZK; do
  ( inn $t timeout 250 python3 $c run 2e4 /tmp/cg $t cuda:0 terrain-air,terrain-air-3,mesh-air-3,paper-air > $out/cmp-$t-a.txt ) &
  ( inn $t timeout 250 python3 $c run 2e4 /tmp/cg $t cuda:0 turf-rest-air,mesh-rest-air,box-rest-air,trap-rest > $out/cmp-$t-b.txt ) &
done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in $TREES; do
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 --flights air | filt | grep "pellets/s" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
echo "terrain $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn M2 python3 $c compare /tmp/cg M2 ZK | filt | tee $out/compare.txt
cd $out && tar czf all.tgz *.txt
