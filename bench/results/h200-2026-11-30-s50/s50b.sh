#!/usr/bin/env bash
# Session 50, call 2: perf/replay (RP, merged with main) with env hacks (rphack.py): on the GPU, the
# rough-ground reach replayed by kind against the same records replayed in order (rkcmp.py, 20000);
# the reach's cost split at 1e8: RP (lines + flights kernels), RPO (one ordered kernel), RPL (no
# flights kernel), RPF (no lines kernel), RPN (no replay).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
v() { case $1 in RPO) HACK_ORDERED=1 inn RP "${@:2}";; RPL) HACK_NOFLIGHTS=1 inn RP "${@:2}";; RPF) HACK_NOLINES=1 inn RP "${@:2}";; RPN) HACK_NOREPLAY=1 inn RP "${@:2}";; *) inn $1 "${@:2}";; esac; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp ./RP ./M && python3 $root/.gpu/b/rphack.py $root/.gpu/b/exp/RP
( cd $root/.gpu/b/exp/RP && OUT=$out WARP_CACHE_PATH=/tmp/wc_K PYTHONPATH=/tmp/site:$PWD timeout 280 python3 $root/.gpu/b/rkcmp.py 20000 cuda:0 > $out/rkcmp.txt 2>&1 ) &
for t in RP RPO M; do ( v $t timeout 250 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-$t.txt ) & sleep 2; done
wait
echo "warm-up + rkcmp $(( $(date +%s) - start )) s" | tee $out/times.txt
grep "vs\|kind" $out/rkcmp.txt
for t in M RP RPO RPL RPF RPN; do
  v $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$t: /"
done 2>&1 | tee $out/path-1e8.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt *.npz && ls
