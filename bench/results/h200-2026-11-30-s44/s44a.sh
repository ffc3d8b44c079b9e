#!/usr/bin/env bash
# session 44, call 1: F (564a5f3, the tree timed as 1.62e7/s on turf in session 43) against N (main with
# numerics.surface_tolerance: kernels to rest as at b067626), and N at surface tolerances 1e-5 and 1e-4
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv > $out/gpu.txt
for t in F N; do
  ( inn $t python3 -m bench.rest throughput --device cuda:0 --sizes 1e5 --repeats 1 --only "rest" > $out/warm-rest-$t.txt ) &
  ( inn $t python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path-$t.txt ) &
done
wait
echo "warm-up (compile) $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in F N; do
  inn $t python3 -m bench.rest throughput --device cuda:0 --sizes 1e7 --repeats 2 --only "rest" | filt | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/rest.txt
echo "rest done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for r in 1 2; do for tol in 1e-6 1e-5 1e-4; do
  inn N python3 -m bench.rest throughput --device cuda:0 --sizes 1e7 --repeats 2 --only "rest, turf" --set numerics.surface_tolerance=$tol | filt | sed "s/^/$r N tol $tol: /"
done; done 2>&1 | tee $out/rest-tolerance.txt
echo "tolerance done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for t in F N; do
  inn $t timeout 120 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | sed "s/^/$t: /"
done 2>&1 | tee $out/path.txt
echo "all done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
