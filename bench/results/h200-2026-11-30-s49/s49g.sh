#!/usr/bin/env bash
# Session 49, call 7: RM = perf/replay recording into a Track of its own (cell, column, count: hack/rpmin), no fallback; RMN: its replay not launched.

set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
v() { case $1 in M) inn M "${@:2}";; RM) HACK_NOFALLBACK=1 HACK_MINTRACK=1 inn RM "${@:2}";; RMN) HACK_NOFALLBACK=1 HACK_MINTRACK=1 HACK_NOREPLAY=1 inn RM "${@:2}";; esac; }
start=$(date +%s)
for t in M RM; do ( v $t timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-$t.txt ) & done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in M RM RMN; do
  v $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path.txt
for t in RM RMN; do
  v $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$t: /"
done 2>&1 | tee $out/path-1e8.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt && ls
