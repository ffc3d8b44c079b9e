#!/usr/bin/env bash
# session 43, call 1: inlining variants A (main), B (flight loop out of line), C (all out of line)
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_"; }
start=$(date +%s)
for t in A B D E; do
  ( inn $t python3 -m bench.rest throughput --device cuda:0 --sizes 1e5 --repeats 1 --only "rest, turf" > $out/warm-rest-$t.txt
    inn $t python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path-$t.txt ) &
done
wait
echo "warm-up (compile) $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in A B D E; do
  inn $t python3 -m bench.rest throughput --device cuda:0 --sizes 1e7 --repeats 2 --only "rest, turf" | filt | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/rest.txt
echo "rest done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for t in A B D E; do
  timeout 150 bash -c "$(declare -f inn filt); root=$root; inn $t python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1" | filt | sed "s/^/$t: /"
done 2>&1 | tee $out/path.txt
echo "all done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
