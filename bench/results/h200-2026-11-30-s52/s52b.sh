#!/usr/bin/env bash
# session 52, call 2: W = main 935f3da + perf/walk (the map walk's run along a row in closed form):
# bench.path cost at 1e9; Nsight Compute source counters (1e6) of the replay kernel (reach; reach + map)
# and of the recording core (reach), by line (bench.ncu_lines): where the reach's time goes
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
( inn W timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > /dev/null ) &
( inn W timeout 200 python3 -m bench.profile_map --device cuda:0 --n 1e4 > /dev/null ) &
( inn W timeout 200 python3 -m bench.profile_map --device cuda:0 --n 1e4 --case "to rest, reach" > /dev/null ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
inn W timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e9 --repeats 1 | filt | grep "N 1e" | tee $out/path-1e9.txt
echo "1e9 $(( $(date +%s) - start )) s" | tee -a $out/times.txt
prof() {  # name kernel-regex case
  inn W timeout 150 /usr/local/cuda/bin/ncu -k regex:$2 -c 1 --section WarpStateStats --section SourceCounters --section LaunchStats --section Occupancy \
    --import-source yes -o /tmp/rep-$1 python3 -m bench.profile_map --device cuda:0 --n 1e6 --case "$3" > $out/ncu-$1.txt 2>&1
  /usr/local/cuda/bin/ncu -i /tmp/rep-$1.ncu-rep --page source --csv --print-source cuda,sass > /tmp/src-$1.csv 2>&1
  /usr/local/cuda/bin/ncu -i /tmp/rep-$1.ncu-rep --page details > $out/details-$1.txt 2>&1
  inn W python3 -m bench.ncu_lines /tmp/src-$1.csv --top 60 > $out/lines-$1.txt 2>&1
  inn W python3 -m bench.ncu_lines /tmp/src-$1.csv --by samples --top 60 > $out/lines-$1-samples.txt 2>&1
  xz -6 -c /tmp/src-$1.csv > $out/src-$1.csv.xz
  echo "ncu $1 $(( $(date +%s) - start )) s" | tee -a $out/times.txt
}
prof rreach replay_kernel "to rest, reach"
prof rmap replay_kernel "to rest, reach + map"
prof creach ricochet_kernel "to rest, reach"
cd $out && tar cf ncu.tar src-*.csv.xz && rm -f src-*.csv.xz && tar czf all.tgz *.txt && ls
