#!/usr/bin/env bash
# Session 50, call 4: perf/replay's final form F (one ordered replay kernel, reruns) against main M:
# bench.path logs on F (replay within rounding); cost at 1e8 and 1e9; pair collisions (shots of 200,
# 1000 shots) M vs F; T = F's recording core writing nothing, no replay (reach and map, 1e8).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
v() { case $1 in T) HACK_NOREPLAY=1 inn T "${@:2}";; *) inn $1 "${@:2}";; esac; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
rm -rf $root/.gpu/b/exp/T; cp -r $root/.gpu/b/exp/F $root/.gpu/b/exp/T; python3 $root/.gpu/b/rphack3.py $root/.gpu/b/exp/T
for t in M F T; do ( v $t timeout 250 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-$t.txt ) & sleep 2; done
for t in M F; do ( v $t timeout 250 python3 $root/.gpu/b/colcost.py 5 cuda:0 > $out/warmcol-$t.txt ) & done
( cd $root/.gpu/b/exp/F && WARP_CACHE_PATH=/tmp/wc_L PYTHONPATH=/tmp/site:$PWD timeout 250 python3 -m bench.path logs --device cuda:0 --count 20000 > $out/logs-F.txt 2>&1 ) &
wait
echo "warm-up + logs $(( $(date +%s) - start )) s" | tee $out/times.txt
grep "against" $out/logs-F.txt; tail -3 $out/warmcol-F.txt
for t in M F T; do
  v $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$t: /"
done 2>&1 | tee $out/path-1e8.txt
for t in M F; do
  v $t timeout 100 python3 $root/.gpu/b/colcost.py 1000 cuda:0 | grep "^collisions" | sed "s/^/$t: /"
done 2>&1 | tee $out/col.txt
for t in F M; do
  v $t timeout 160 python3 -m bench.path cost --device cuda:0 --sizes 1e9 --repeats 1 | filt | grep "N 1e" | sed "s/^/$t: /"
done 2>&1 | tee $out/path-1e9.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt && ls
