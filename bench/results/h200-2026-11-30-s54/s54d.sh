#!/usr/bin/env bash
# session 54, call 4: the walk with a tighter margin and each cell's own time window (W4, the working
# tree) against main (M), bench.meshes terrain 1e7 alternated twice; W4's per-pellet outputs against
# the BVH's (cmpwalk.py, 2e4, float32); Nsight Compute's source counters of the two-triangle mesh of
# the paper's plane and of the plane (bench.mesh_profile, 1e7 pellets).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M W4; do
  ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 > $out/warm-$t.txt ) &
done
( inn W4 timeout 250 python3 $root/bench/results/h200-2026-11-30-s54/cmpwalk.py 2e3 cuda:0 float32 > $out/warm-cmp.txt ) &
for c in mesh plane; do
  ( inn W4 timeout 250 python3 -m bench.mesh_profile --case $c --n 1e4 --repeats 1 > $out/warm-prof-$c.txt ) &
done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in M W4; do
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 | filt | grep "vacuum\|air" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
echo "terrain $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn W4 timeout 120 python3 $root/bench/results/h200-2026-11-30-s54/cmpwalk.py 2e4 cuda:0 float32 | filt | tee $out/cmpwalk.txt
echo "cmpwalk $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for c in mesh plane; do
  mkdir -p $out/ncu-$c
  inn W4 timeout 150 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \
    --section LaunchStats --section Occupancy --section SpeedOfLight --import-source yes -o $out/ncu-$c/rep \
    python3 -m bench.mesh_profile --case $c --n 1e7 --repeats 0 | filt | tail -3
  inn W4 /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page source --csv --print-source cuda,sass > $out/ncu-$c/source.csv
  inn W4 /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page details > $out/ncu-$c/details.txt
  inn W4 python3 -m bench.ncu_lines $out/ncu-$c/source.csv > $out/ncu-$c/lines.txt
  rm -f $out/ncu-$c/source.csv $out/ncu-$c/rep.ncu-rep
  echo "ncu $c $(( $(date +%s) - start )) s" | tee -a $out/times.txt
done
cd $out && tar czf all.tgz *.txt ncu-*/*.txt
