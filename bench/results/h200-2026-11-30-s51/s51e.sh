#!/usr/bin/env bash
# session 51, call 5: M = main e2c6034 + the segment reduction's loads batched (same bits, CPU-checked):
# bench.path cost at 1e8 twice and at 1e9 once; each kernel's GPU time at 1e8; Nsight Compute source
# counters of the replay kernel with the map (1e6 pellets): where the map's replay waits
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
( inn M timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-M.txt ) &
( inn M timeout 200 python3 -m bench.profile_map --device cuda:0 --n 1e4 > /dev/null ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do inn M timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r M: /"; done 2>&1 | tee $out/path-1e8.txt
inn M timeout 100 python3 $root/.gpu/b/ktime.py 1e8 | filt | tee $out/ktime.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn M timeout 150 /usr/local/cuda/bin/ncu -k regex:replay_kernel -c 1 --section WarpStateStats --section SourceCounters \
  --section LaunchStats --section Occupancy --section MemoryWorkloadAnalysis --import-source yes -o /tmp/rep-rmap python3 -m bench.profile_map --device cuda:0 --n 1e6 > $out/ncu-rmap.txt 2>&1
tail -2 $out/ncu-rmap.txt
/usr/local/cuda/bin/ncu -i /tmp/rep-rmap.ncu-rep --page source --csv --print-source cuda,sass > /tmp/src-rmap.csv 2>&1
/usr/local/cuda/bin/ncu -i /tmp/rep-rmap.ncu-rep --page details > $out/details-rmap.txt 2>&1
xz -6 -c /tmp/src-rmap.csv > $out/src-rmap.csv.xz
echo "ncu $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn M timeout 150 python3 -m bench.path cost --device cuda:0 --sizes 1e9 --repeats 1 | filt | grep "N 1e" | tee $out/path-1e9.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar cf ncu.tar src-rmap.csv.xz details-rmap.txt ncu-rmap.txt && rm -f src-rmap.csv.xz details-rmap.txt ncu-rmap.txt warm-M.txt && tar czf all.tgz *.txt && ls
