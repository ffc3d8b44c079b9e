#!/usr/bin/env bash
# session 44: the terrain (1e6 triangles) on main (N) against main + the height grid of perf/chords (C),
# now that terrain runs use threads of 16 pellets; then Nsight Compute counters of both at 1e7, vacuum
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
test -s /tmp/site/warp/bin/warp.so || { echo "fresh machine"; exit 3; }
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl 2>&1 | tail -2
root=$PWD
inn() { local t=$1; shift; (cd $root/.whl/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
start=$(date +%s)
for t in N C; do ( inn $t python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 > $out/warm-$t.txt ) & done; wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in N C; do
  inn $t python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 | grep "vacuum\|air\|terrain:" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
M=smsp__inst_executed.sum,smsp__thread_inst_executed_per_inst_executed.ratio,l1tex__t_bytes_pipe_lsu_mem_local_op_ld.sum,l1tex__t_bytes_pipe_lsu_mem_global_op_ld.sum,sm__warps_active.avg.pct_of_peak_sustained_active,launch__registers_per_thread,launch__grid_size,gpu__time_duration.sum,sm__throughput.avg.pct_of_peak_sustained_elapsed
for t in N C; do
  inn $t timeout 200 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --metrics $M python3 -m bench.mesh_profile --case terrain --n 1e7 --repeats 0 > $out/ncu-$t.txt 2>&1
  grep -v "^==PROF==\|^Warp\|CUDA Toolkit\|Devices\|Kernel cache\|cuda:0\|\"cpu\"" $out/ncu-$t.txt | grep -v "^ *$" | head -40 | sed "s/^/$t: /"
done
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
