#!/usr/bin/env bash
# session 56, call 2: Nsight Compute source counters of O's core kernel, the terrain in air (1e6).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
[ -d $root/.gpu/b/exp/O ] || { mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp; }
for c in terrain-air; do
  inn O timeout 200 python3 -m bench.mesh_profile --case $c --n 1e4 --repeats 0 | filt | tail -2
  mkdir -p $out/ncu-$c
  inn O timeout 200 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \
    --section LaunchStats --section Occupancy --section SpeedOfLight --import-source yes -o $out/ncu-$c/rep \
    python3 -m bench.mesh_profile --case $c --n 1e6 --repeats 0 | filt | tail -5
  inn O /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page source --csv --print-source cuda,sass > $out/ncu-$c/source.csv
  inn O /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page details > $out/ncu-$c/details.txt
  inn O python3 -m bench.ncu_lines $out/ncu-$c/source.csv --top 80 > $out/ncu-$c/lines.txt
  gzip -c $out/ncu-$c/source.csv > $out/source-$c.csv.gz; rm -f $out/ncu-$c/source.csv $out/ncu-$c/rep.ncu-rep
  echo "ncu $c $(( $(date +%s) - start )) s" | tee -a $out/times.txt
done
cd $out && tar czf all.tgz *.txt ncu-*/*.txt
