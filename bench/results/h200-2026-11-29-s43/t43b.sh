#!/usr/bin/env bash
# session 43: where the terrain's kernel spends its time (Nsight Compute), vacuum and air, 1e6 pellets
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
test -s /tmp/site/warp/bin/warp.so || { echo "fresh machine"; exit 3; }
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl 2>&1 | tail -2
cd .whl/exp/T && export WARP_CACHE_PATH=/tmp/wc_T PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1
start=$(date +%s)
( python3 -m bench.mesh_profile --case terrain --n 1e7 --repeats 3 > $out/terrain-time.txt 2>&1 ) &
( python3 -m bench.mesh_profile --case terrain-air --n 1e4 --repeats 0 > /dev/null 2>&1 ) &
wait
python3 -m bench.mesh_profile --case terrain-air --n 1e7 --repeats 3 >> $out/terrain-time.txt 2>&1
echo "compiled and timed $(( $(date +%s) - start )) s"; grep -v "^Warp\|CUDA Toolkit\|Devices\|Kernel cache\|cuda:0\|\"cpu\"" $out/terrain-time.txt
M=smsp__inst_executed.sum,smsp__thread_inst_executed_per_inst_executed.ratio,l1tex__t_bytes_pipe_lsu_mem_local_op_ld.sum,l1tex__t_bytes_pipe_lsu_mem_global_op_ld.sum,sm__warps_active.avg.pct_of_peak_sustained_active,launch__registers_per_thread,gpu__time_duration.sum,dram__throughput.avg.pct_of_peak_sustained_elapsed,sm__throughput.avg.pct_of_peak_sustained_elapsed
for c in terrain terrain-air; do
  timeout 150 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section Occupancy --metrics $M python3 -m bench.mesh_profile --case $c --n 1e6 --repeats 0 > $out/ncu-$c.txt 2>&1
  grep -v "^==PROF==\|^Warp\|CUDA Toolkit\|Devices\|Kernel cache\|cuda:0\|\"cpu\"" $out/ncu-$c.txt | tail -60
done
echo "done $(( $(date +%s) - start )) s"
