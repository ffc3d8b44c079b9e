#!/usr/bin/env bash
# session 55, call 3: D (C2 with each triangle test returning early where its offset plane is reached
# no earlier than the contact found so far: a small mesh's faces and the walk's cells) against C2 and
# main M: plane 1e8 and terrain 1e7, twice; cmpwalk on D; Nsight Compute of D's terrain in vacuum and mesh.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M C2 D; do
  ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 > $out/warm-$t.txt ) &
  ( inn $t timeout 250 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 > $out/warm-plane-$t.txt ) &
done
( inn D timeout 250 python3 $root/bench/results/h200-2026-11-30-s54/cmpwalk.py 2e3 cuda:0 float32 > $out/warm-cmp.txt ) &
for c in mesh terrain; do
  ( inn D timeout 250 python3 -m bench.mesh_profile --case $c --n 1e4 --repeats 1 > $out/warm-prof-$c.txt ) &
done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in M C2 D; do
  inn $t timeout 60 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 | filt | grep "pellets/s\|plane time" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/plane.txt
echo "plane $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for r in 1 2; do for t in M C2 D; do
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 | filt | grep "vacuum, terrain\|air, terrain" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
echo "terrain $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn D timeout 120 python3 $root/bench/results/h200-2026-11-30-s54/cmpwalk.py 2e4 cuda:0 float32 | filt | tee $out/cmpwalk.txt
echo "cmpwalk $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for c in terrain mesh; do
  mkdir -p $out/ncu-$c
  n=1e7; [ $c = terrain ] && n=1e6
  inn D timeout 150 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \
    --section LaunchStats --section Occupancy --section SpeedOfLight --import-source yes -o $out/ncu-$c/rep \
    python3 -m bench.mesh_profile --case $c --n $n --repeats 0 | filt | tail -3
  inn D /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page source --csv --print-source cuda,sass > $out/ncu-$c/source.csv
  inn D python3 -m bench.ncu_lines $out/ncu-$c/source.csv --top 120 > $out/ncu-$c/lines.txt
  rm -f $out/ncu-$c/source.csv $out/ncu-$c/rep.ncu-rep
  echo "ncu $c $(( $(date +%s) - start )) s" | tee -a $out/times.txt
done
cd $out && tar czf all.tgz *.txt ncu-*/*.txt
