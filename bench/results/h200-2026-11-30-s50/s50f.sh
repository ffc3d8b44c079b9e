#!/usr/bin/env bash
# Session 50, call 6: perf/steps (S) against main (M) on the GPU: the same records replayed, the same bits?
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M S; do ( cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_c$t PYTHONPATH=/tmp/site:$PWD timeout 170 python3 $root/.gpu/b/scmp.py /tmp/$t.npz > $out/scmp-$t.txt 2>&1 ) & done
wait
python3 - <<'PY' | tee $out/cmp.txt
import numpy as np
a, b = np.load("/tmp/M.npz"), np.load("/tmp/S.npz")
for k in a.files:
    x, y = a[k], b[k]
    print(k, "bitwise" if np.array_equal(x, y, equal_nan=True) else f"{int((x != y).sum())} differ")
PY
echo "done $(( $(date +%s) - start )) s" | tee $out/times.txt
