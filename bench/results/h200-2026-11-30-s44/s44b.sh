#!/usr/bin/env bash
# session 44, call 2: Nsight Compute instruction counts a pellet on main (N): issue 25's turf run to rest,
# issue 26's path cases (no hazard, reach, reach + map)
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local c=$1; shift; (cd $root/.gpu/b/exp/N && WARP_CACHE_PATH=/tmp/wc_$c PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
start=$(date +%s)
/usr/local/cuda/bin/ncu --query-metrics 2>/dev/null | grep -i "pipe_xu\|pipe_fma\b\|pipe_alu\b" | head -8 > $out/pipe-metrics.txt
i=0; for c in "air, rest, turf" "to rest, no hazard" "to rest, reach" "to rest, reach + map"; do
  i=$((i+1)); ( inn p$i python3 -m bench.profile_map --device cuda:0 --n 1e4 --case "$c" > $out/warm-$i.txt ) &
done; wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
cat $out/pipe-metrics.txt
M=smsp__inst_executed.sum,smsp__thread_inst_executed_per_inst_executed.ratio,sm__warps_active.avg.pct_of_peak_sustained_active,launch__registers_per_thread,launch__grid_size,gpu__time_duration.sum,sm__throughput.avg.pct_of_peak_sustained_elapsed
grep -q "sm__inst_executed_pipe_xu" $out/pipe-metrics.txt && M=$M,sm__inst_executed_pipe_xu.sum
grep -q "sm__inst_executed_pipe_fma " $out/pipe-metrics.txt && M=$M,sm__inst_executed_pipe_fma.sum
i=0; for c in "air, rest, turf" "to rest, no hazard" "to rest, reach" "to rest, reach + map"; do
  i=$((i+1)); n=1e7; [ $i = 4 ] && n=1e6
  inn p$i timeout 240 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --metrics $M python3 -m bench.profile_map --device cuda:0 --n $n --case "$c" > $out/ncu-$i.txt 2>&1
  echo "== $c, $n pellets"; grep -v "^==PROF==\|^Warp\|CUDA Toolkit\|Devices\|Kernel cache\|cuda:0\|\"cpu\"" $out/ncu-$i.txt | grep -v "^ *$" | head -18
  echo "ncu $i $(( $(date +%s) - start )) s"
done 2>&1 | tee $out/ncu.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
