#!/usr/bin/env bash
# session 56, call 9: E (Q with a small mesh's edge and corner search, `features_time`, out of line in
# CUDA code: rarely run, 161 -> 144 kB of code, spills 1,192 -> 540 B) against Q: the mesh of the
# paper's plane at 1e8, alternated twice; per-pellet outputs of E and Q on the H200 (cmpbox.py, 2e4).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
mkdir -p /tmp/cmpb
c=$root/bench/results/h200-2026-12-01-s56/cmpbox.py
for t in Q E; do
  ( inn $t timeout 200 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 > $out/warm-plane-$t.txt ) &
  ( inn $t timeout 200 python3 $c run 2e4 /tmp/cmpb $t cuda:0 > $out/cmpbox-$t.txt ) &
done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
inn Q python3 $c compare /tmp/cmpb Q E | filt | tee $out/cmpbox.txt
for r in 1 2; do for t in Q E; do
  inn $t timeout 60 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 | filt | grep "pellets/s\|plane time" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/plane.txt
echo "plane $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt
