#!/usr/bin/env bash
# session 56, call 5: S as landed (off_step given the contact so far, cells from the step's start,
# posts' and edges' code left out of the air search where the scene has none) against main M: the
# terrain in air, 1e7, alternated twice; cmpwalk on S; Nsight Compute source counters of S (1e6).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M S; do
  ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 --flights air > $out/warm-$t.txt ) &
done
( inn S timeout 250 python3 -m bench.mesh_profile --case terrain-air --n 1e4 --repeats 0 > $out/warm-prof.txt ) &
( inn S timeout 250 python3 $root/bench/results/h200-2026-11-30-s54/cmpwalk.py 2e3 cuda:0 float32 > $out/warm-cmp.txt ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in M S; do
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 --flights air | filt | grep "air, terrain" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
echo "terrain $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn S timeout 120 python3 $root/bench/results/h200-2026-11-30-s54/cmpwalk.py 2e4 cuda:0 float32 | filt | tee $out/cmpwalk.txt
echo "cmpwalk $(( $(date +%s) - start )) s" | tee -a $out/times.txt
c=terrain-air; mkdir -p $out/ncu-$c
inn S timeout 200 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \
  --section LaunchStats --section Occupancy --section SpeedOfLight --import-source yes -o $out/ncu-$c/rep \
  python3 -m bench.mesh_profile --case $c --n 1e6 --repeats 0 | filt | tail -3
inn S /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page source --csv --print-source cuda,sass > $out/ncu-$c/source.csv
inn S /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page details > $out/ncu-$c/details.txt
inn S python3 -m bench.ncu_lines $out/ncu-$c/source.csv --top 80 > $out/ncu-$c/lines.txt
rm -f $out/ncu-$c/source.csv $out/ncu-$c/rep.ncu-rep
echo "ncu $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt ncu-*/*.txt
