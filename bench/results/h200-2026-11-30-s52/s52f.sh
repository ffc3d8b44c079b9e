#!/usr/bin/env bash
# session 52, call 6: M = main c11a32e against P = perf/plan (chunks planned equal, counting the buffers a run
# keeps as free): bench.path cost 1e8 with --repeats 1 (a first run) and 3 (median: later runs), P at 1e9,
# ktime2 of P (wall against GPU operations). Both trees compile the same kernels: one cache.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_shared PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
inn M timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > /dev/null
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 3; do for t in M P; do
  inn $t timeout 90 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats $r | filt | grep "N 1e" | sed "s/^/repeats $r $t: /"
done; done 2>&1 | tee $out/path-1e8.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn P timeout 150 python3 -m bench.path cost --device cuda:0 --sizes 1e9 --repeats 1 | filt | grep "N 1e" | sed "s/^/P /" | tee $out/path-1e9.txt
echo "1e9 $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn P timeout 100 python3 $root/.gpu/b/ktime2.py 1e8 | grep "^==\|host marks" | tee $out/ktime2.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt
