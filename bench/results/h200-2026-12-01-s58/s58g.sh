#!/usr/bin/env bash
# session 58, call 7: F6 (a flat mesh's inside tests and its contact normal's on in-plane edge lines
# from float64, `Surfaces.flat_edge` and `flat_offset`; the air's screen slack from the host) and F6C
# (F6 with the air's kernel among solids capped at 96 registers in blocks of 128) against F4b (main
# dd48fcf): the mesh of the paper's plane at 1e8 in vacuum and in air, twice; per-pellet outputs of
# F6 against main H (1b287ae; cmpgpu.py: the mesh in vacuum and in air, the box in vacuum).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
c=$root/bench/results/h200-2026-12-01-s57/cmpgpu.py
mkdir -p /tmp/cg
for t in F4b F6 F6C; do
  ( inn $t timeout 200 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 --flights vacuum,air > $out/warm-$t.txt ) &
done
for t in H F6; do ( inn $t timeout 200 python3 $c run 2e4 /tmp/cg $t cuda:0 mesh-vac-3,mesh-air-3,box-vac-3 > $out/cmp-$t.txt ) & done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in F4b F6 F6C; do
  inn $t timeout 90 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 --flights vacuum,air | filt | grep "pellets/s\|plane time" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/plane.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn H python3 $c compare /tmp/cg H F6 | filt | tee $out/compare.txt
