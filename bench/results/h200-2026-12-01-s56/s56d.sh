#!/usr/bin/env bash
# session 56, call 4: V (call 3: the air flight out of line in a landing kernel over the terrain) gave
# 0.932 hit and walk != chords. Is main's own out-of-line air flight (kernels to rest) affected?
# cmprest.py: walk against chords, the bench terrain in air, on the H200: M to its landing and to
# rest, V to its landing.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
c=$root/bench/results/h200-2026-12-01-s56/cmprest.py
( inn M timeout 400 python3 $c 2e4 cuda:0 rest | filt > $out/M-rest.txt ) &
( inn M timeout 400 python3 $c 2e4 cuda:0 landing | filt > $out/M-landing.txt ) &
( inn V timeout 400 python3 $c 2e4 cuda:0 landing | filt > $out/V-landing.txt ) &
wait
echo "done $(( $(date +%s) - start )) s" | tee $out/times.txt
tail -n 8 $out/*.txt
