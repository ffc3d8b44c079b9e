#!/usr/bin/env bash
# session 58, call 2: Nsight Compute source counters of F's kernel (the flat search) on the mesh of
# the paper's plane, 1e7 pellets, and of the plane itself.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for c in mesh plane; do
  inn F timeout 100 python3 -m bench.mesh_profile --case $c --n 1e5 --repeats 1 | filt | tail -2
  mkdir -p $out/ncu-$c
  inn F timeout 150 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \
    --section LaunchStats --section Occupancy --section SpeedOfLight --import-source yes -o $out/ncu-$c/rep \
    python3 -m bench.mesh_profile --case $c --n 1e7 --repeats 0 | filt | tail -3
  inn F /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page source --csv --print-source cuda,sass > $out/ncu-$c/source.csv
  inn F /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page details > $out/ncu-$c/details.txt
  inn F python3 -m bench.ncu_lines $out/ncu-$c/source.csv --top 150 > $out/ncu-$c/lines.txt
  rm -f $out/ncu-$c/source.csv $out/ncu-$c/rep.ncu-rep
  echo "ncu $c $(( $(date +%s) - start )) s" | tee -a $out/times.txt
done
