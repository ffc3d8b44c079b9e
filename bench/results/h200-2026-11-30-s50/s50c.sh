#!/usr/bin/env bash
# Session 50, call 3: perf/replay's records row-major (L: a pellet's column contiguous) against
# word-major (RP), both replayed in order (HACK_ORDERED: faster than by kind in call 2); LN/RPN their
# cores alone (HACK_NOREPLAY); T: the recording core with nothing written (claim always full), alone.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
v() { case $1 in RP) HACK_ORDERED=1 inn RP "${@:2}";; RPN) HACK_NOREPLAY=1 inn RP "${@:2}";; L) HACK_ORDERED=1 inn L "${@:2}";; LN) HACK_NOREPLAY=1 inn L "${@:2}";; T) HACK_NOREPLAY=1 inn T "${@:2}";; esac; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp ./RP && python3 $root/.gpu/b/rphack.py $root/.gpu/b/exp/RP
for t in L T; do rm -rf $root/.gpu/b/exp/$t; cp -r $root/.gpu/b/exp/RP $root/.gpu/b/exp/$t; python3 $root/.gpu/b/rphack2.py $root/.gpu/b/exp/$t $t; done
for t in RP L T; do ( v $t timeout 250 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-$t.txt ) & sleep 2; done
( cd $root/.gpu/b/exp/L && OUT=$out HACK_ORDERED=1 WARP_CACHE_PATH=/tmp/wc_K PYTHONPATH=/tmp/site:$PWD timeout 250 python3 $root/.gpu/b/rkcmp.py 20000 cuda:0 > $out/rkcmp-L.txt 2>&1 ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
grep "vs" $out/rkcmp-L.txt; tail -2 $out/warm-T.txt
for r in 1 2; do for t in RP L; do
  v $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path-1e8.txt
for t in RPN LN T; do
  v $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | grep -v "no hazard" | sed "s/^/$t: /"
done 2>&1 | tee -a $out/path-1e8.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && rm -f *.npz && tar czf all.tgz *.txt && ls
