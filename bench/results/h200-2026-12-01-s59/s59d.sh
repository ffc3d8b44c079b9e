#!/usr/bin/env bash
# session 59, call 4: the mesh of the paper's plane at 1e8 (vacuum and sea-level air, alternated
# twice) for main M (73e74c6), R6 (`features_theta`'s edges and corners in one run-time loop: one
# copy of `line_theta`, as `features_time` does; sm_90 code of the flat air kernel 590,720 ->
# 416,384 bytes) and NE (for the measure only, wrong near a border: no edge or corner code compiled
# in, 277,504 bytes); per-pellet outputs of R6 against M (cmpgpu.py: the mesh in air and in vacuum
# over three bounces, the box to rest in air, the box in vacuum over three bounces).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
c=$root/bench/results/h200-2026-12-01-s57/cmpgpu.py
mkdir -p /tmp/cg /tmp/w
trees="M R6 NE"
for t in $trees; do
  ( inn $t timeout 250 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 --flights vacuum,air > /tmp/w/warm-$t.txt ) &
done
for t in M R6; do
  ( inn $t timeout 250 python3 $c run 2e4 /tmp/cg $t cuda:0 mesh-vac-3,mesh-air-3,box-rest-air,box-vac-3 > /tmp/w/cmp-$t.txt ) &
done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in $trees; do
  inn $t timeout 90 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 --flights vacuum,air | filt | grep "pellets/s\|plane time" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/plane.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn M python3 $c compare /tmp/cg M R6 | filt | tee $out/compare.txt
(cd /tmp/w && tar czf $out/logs.tgz .)
