#!/usr/bin/env bash
# session 59, call 1: Nsight Compute source counters of main H (2f31c4f) on the mesh of the paper's
# plane in sea-level air and in vacuum, and of the plane in air (1e7 pellets); ZF (a flat mesh's
# own plane crossed by the centre found only where its offset plane is not met over a triangle)
# against H, the mesh of the plane at 1e8 in vacuum and in air, alternated twice; per-pellet
# outputs of ZF against H (cmpgpu.py: the mesh in air and in vacuum, three bounces).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
c=$root/bench/results/h200-2026-12-01-s57/cmpgpu.py
mkdir -p /tmp/cg
for t in H ZF; do
  ( inn $t timeout 200 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 --flights vacuum,air > $out/warm-$t.txt ) &
  ( inn $t timeout 200 python3 $c run 2e4 /tmp/cg $t cuda:0 mesh-vac-3,mesh-air-3 > $out/cmp-$t.txt ) &
done
( inn H timeout 200 python3 -m bench.mesh_profile --case mesh-air --n 1e5 --repeats 1 > $out/warm-prof.txt;
  inn H timeout 200 python3 -m bench.mesh_profile --case plane-air --n 1e5 --repeats 1 >> $out/warm-prof.txt;
  inn H timeout 200 python3 -m bench.mesh_profile --case mesh --n 1e5 --repeats 1 >> $out/warm-prof.txt ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in H ZF; do
  inn $t timeout 90 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 --flights vacuum,air | filt | grep "pellets/s\|plane time" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/plane.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn H python3 $c compare /tmp/cg H ZF | filt | tee $out/compare.txt
for c in mesh-air plane-air mesh; do
  mkdir -p $out/ncu-$c
  inn H timeout 150 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \
    --section LaunchStats --section Occupancy --section SpeedOfLight --import-source yes -o $out/ncu-$c/rep \
    python3 -m bench.mesh_profile --case $c --n 1e7 --repeats 0 | filt | tail -3
  inn H /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page source --csv --print-source cuda,sass > $out/ncu-$c/source.csv
  inn H /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page details > $out/ncu-$c/details.txt
  inn H python3 -m bench.ncu_lines $out/ncu-$c/source.csv --top 150 > $out/ncu-$c/lines.txt
  rm -f $out/ncu-$c/source.csv $out/ncu-$c/rep.ncu-rep
  echo "ncu $c $(( $(date +%s) - start )) s" | tee -a $out/times.txt
done
