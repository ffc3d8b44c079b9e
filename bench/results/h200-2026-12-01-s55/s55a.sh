#!/usr/bin/env bash
# session 55, call 1: a small mesh's edges searched only before its covering faces' planes, and
# steeper's early exit (C, the working tree), against main (M = 527f13f): bench.meshes plane 1e8 and
# terrain 1e7 alternated twice; Nsight Compute's source counters of C's two-triangle mesh of the plane.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M C; do
  ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 > $out/warm-$t.txt ) &
  ( inn $t timeout 250 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 > $out/warm-plane-$t.txt ) &
done
( inn C timeout 250 python3 -m bench.mesh_profile --case mesh --n 1e4 --repeats 1 > $out/warm-prof.txt ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in M C; do
  inn $t timeout 60 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 | filt | grep "pellets/s\|plane time" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/plane.txt
echo "plane $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for r in 1 2; do for t in M C; do
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 | filt | grep "vacuum\|air" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
echo "terrain $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for c in mesh; do
  mkdir -p $out/ncu-$c
  inn C timeout 150 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \
    --section LaunchStats --section Occupancy --section SpeedOfLight --import-source yes -o $out/ncu-$c/rep \
    python3 -m bench.mesh_profile --case $c --n 1e7 --repeats 0 | filt | tail -3
  inn C /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page source --csv --print-source cuda,sass > $out/ncu-$c/source.csv
  inn C /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page details > $out/ncu-$c/details.txt
  inn C python3 -m bench.ncu_lines $out/ncu-$c/source.csv > $out/ncu-$c/lines.txt
  inn C python3 -m bench.ncu_lines $out/ncu-$c/source.csv --top 150 > $out/ncu-$c/lines150.txt 2>/dev/null
  rm -f $out/ncu-$c/source.csv $out/ncu-$c/rep.ncu-rep
  echo "ncu $c $(( $(date +%s) - start )) s" | tee -a $out/times.txt
done
cd $out && tar czf all.tgz *.txt ncu-*/*.txt
