#!/usr/bin/env bash
# session 45, call 1: Nsight Compute source counters of the core kernel, bench.path's scene (1e6 pellets),
# the reach and the reach + map cases: where the map's warp instructions and their idle lanes are, by line
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local c=$1; shift; (cd $root/.gpu/b/exp/N && WARP_CACHE_PATH=/tmp/wc_$c PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
start=$(date +%s)
( inn r python3 -m bench.profile_map --device cuda:0 --n 1e4 --case "to rest, reach" > $out/warm-r.txt ) &
( inn m python3 -m bench.profile_map --device cuda:0 --n 1e4 > $out/warm-m.txt ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for c in m r; do
  case_args=(); [ $c = r ] && case_args=(--case "to rest, reach")
  inn $c timeout 200 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \
    --section LaunchStats --import-source yes -o $out/rep-$c python3 -m bench.profile_map --device cuda:0 --n 1e6 "${case_args[@]}" > $out/ncu-$c.txt 2>&1
  tail -3 $out/ncu-$c.txt
  /usr/local/cuda/bin/ncu -i $out/rep-$c.ncu-rep --page source --csv --print-source cuda > $out/source-$c.csv 2>&1
  /usr/local/cuda/bin/ncu -i $out/rep-$c.ncu-rep --page details > $out/details-$c.txt 2>&1
  ls -la $out/source-$c.csv; head -c 600 $out/source-$c.csv; echo
  echo "ncu $c $(( $(date +%s) - start )) s" | tee -a $out/times.txt
done
