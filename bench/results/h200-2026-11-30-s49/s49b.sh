#!/usr/bin/env bash
# Session 49, call 2: the reach and map with a phase's line steps replayed by a kernel of their own
# (hack HX, branch hack/hx: the core kernel logs each line step and never watches it; a second kernel,
# one thread a pellet, replays the log with the same watch_step). M = main; HX; HN = HX without the
# replay (a reset of the counters only). bench.path cost, 1e7 alternated twice, 1e8 each.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
v() { case $1 in M) inn M "${@:2}";; HX) HX=1 inn HX "${@:2}";; HN) HX=1 HX_NOREPLAY=1 inn HX "${@:2}";; esac; }
start=$(date +%s)
( v M timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-M.txt ) &
( v HX timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-HX.txt ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in M HX HN; do
  v $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path.txt
for t in M HX HN; do
  v $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$t: /"
done 2>&1 | tee $out/path-1e8.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt && ls
