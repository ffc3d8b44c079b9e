#!/usr/bin/env bash
# session 58, call 6: where the flat mesh's vacuum time goes, by ablation (not correct code, for
# the measure only): X1 its contact normal without the over-a-triangle test, X2 without the box's
# window, X3 without the inside tests, X4 all three; against F4 (main dd48fcf). And the air's
# kernel among solids: C (cap 96, blocks of 128), D (cap 128, blocks of 128) against F4. The mesh of
# the paper's plane at 1e8, twice.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in F4 X1 X2 X3 X4; do
  ( inn $t timeout 200 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 --flights vacuum > $out/warm-$t.txt ) &
done
for t in C D; do
  ( inn $t timeout 200 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 --flights air > $out/warm-$t.txt ) &
done
wait
( inn F4 timeout 200 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 --flights air > $out/warm-F4a.txt )
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in F4 X1 X2 X3 X4; do
  inn $t timeout 60 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 --flights vacuum | filt | grep "pellets/s\|plane time" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/vacuum.txt
for r in 1 2; do for t in F4 C D; do
  inn $t timeout 60 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 --flights air | filt | grep "pellets/s\|plane time" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/air.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
