#!/usr/bin/env bash
# session 59, call 2 (the same machine as call 1): call 1's Nsight Compute reports again, packed in
# one file (call 1's six came back as too many files): main H on the mesh of the paper's plane in
# air and in vacuum, the plane in air, 1e7 pellets.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
[ -d $root/.gpu/b/exp/H ] || { mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp; }
p=/tmp/prof; mkdir -p $p
for c in mesh-air plane-air mesh; do
  mkdir -p $p/ncu-$c
  inn H timeout 150 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \
    --section LaunchStats --section Occupancy --section SpeedOfLight --import-source yes -f -o $p/ncu-$c/rep \
    python3 -m bench.mesh_profile --case $c --n 1e7 --repeats 0 | filt | tail -3
  inn H /usr/local/cuda/bin/ncu -i $p/ncu-$c/rep.ncu-rep --page source --csv --print-source cuda,sass > $p/ncu-$c/source.csv
  inn H /usr/local/cuda/bin/ncu -i $p/ncu-$c/rep.ncu-rep --page details > $p/ncu-$c/details.txt
  inn H python3 -m bench.ncu_lines $p/ncu-$c/source.csv --top 150 > $p/ncu-$c/lines.txt
  rm -f $p/ncu-$c/source.csv $p/ncu-$c/rep.ncu-rep
  echo "ncu $c $(( $(date +%s) - start )) s" | tee -a $p/times.txt
done
(cd $p && tar czf $out/ncu.tgz .)
