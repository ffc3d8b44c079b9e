#!/usr/bin/env bash
# session 45, call 4: Nsight Compute source counters of tree X (lanes meet per pellet, around the watch,
# the surface phase and the flight), bench.path's map case at 1e6 pellets: where lanes still idle
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local c=$1; shift; (cd $root/.gpu/b/exp/X && WARP_CACHE_PATH=/tmp/wc_$c PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
start=$(date +%s)
inn m python3 -m bench.profile_map --device cuda:0 --n 1e4 > $out/warm-m.txt
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
inn m timeout 200 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \
  --import-source yes -o $out/rep-m python3 -m bench.profile_map --device cuda:0 --n 1e6 > $out/ncu-m.txt 2>&1
tail -3 $out/ncu-m.txt
/usr/local/cuda/bin/ncu -i $out/rep-m.ncu-rep --page source --csv --print-source cuda,sass > $out/src-m.csv 2>&1
/usr/local/cuda/bin/ncu -i $out/rep-m.ncu-rep --page details > $out/details-m.txt 2>&1
rm $out/rep-m.ncu-rep; xz -6 $out/src-m.csv
echo "ncu $(( $(date +%s) - start )) s" | tee -a $out/times.txt
