#!/usr/bin/env bash
# session 59, call 3: the air's kernel of a flat mesh (the mesh of the paper's plane, 1e8, vacuum and
# sea-level air, alternated twice) for main M (73e74c6, ZF landed) and: U (the kernel not capped at
# 128 registers where every mesh is flat), PO (a flat mesh's roots, `root`, one function in CUDA
# code), UPO (both), FT (`flat_theta` one function in CUDA code); per-pellet outputs of U, PO, UPO
# and FT against M (cmpgpu.py: the mesh in air and in vacuum, three bounces).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
c=$root/bench/results/h200-2026-12-01-s57/cmpgpu.py
mkdir -p /tmp/cg
trees="M U PO UPO FT"
for t in $trees; do
  ( inn $t timeout 250 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 --flights vacuum,air > $out/warm-$t.txt ) &
  ( inn $t timeout 250 python3 $c run 2e4 /tmp/cg $t cuda:0 mesh-vac-3,mesh-air-3 > $out/cmp-$t.txt ) &
done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in $trees; do
  inn $t timeout 90 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 --flights vacuum,air | filt | grep "pellets/s\|plane time" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/plane.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for t in U PO UPO FT; do echo "M vs $t"; inn M python3 $c compare /tmp/cg M $t | filt; done 2>&1 | tee $out/compare.txt
