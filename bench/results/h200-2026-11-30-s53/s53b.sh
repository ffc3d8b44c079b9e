#!/usr/bin/env bash
# session 53, call 2: M = main, G = grid_constant everywhere, R = grid_constant except the replay kernels.
# 1. scmp.py M G R in two parts each (bitwise expected); 2. ktime3 1e8 per kernel; 3. bench.path cost 1e8 M G R x2.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M G R; do
  ( inn $t timeout 240 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-$t.txt ) &
  for part in a b; do
    ( cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_s$t$part PYTHONUNBUFFERED=1 PYTHONPATH=/tmp/site:$PWD timeout 290 python3 $root/.gpu/b/scmp.py /tmp/$t$part.npz cuda:0 20000 $part > $out/scmp-$t$part.txt 2>&1 ) &
  done
done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
python3 - <<'PY' | tee $out/cmp.txt
import numpy as np, os
for part in "ab":
    if not os.path.exists(f"/tmp/M{part}.npz"): print(part, "no M"); continue
    a = np.load(f"/tmp/M{part}.npz")
    for t in "GR":
        if not os.path.exists(f"/tmp/{t}{part}.npz"): print(part, t, "missing"); continue
        b = np.load(f"/tmp/{t}{part}.npz")
        bad = [k for k in a.files if k in b.files and not np.array_equal(a[k], b[k], equal_nan=True)]
        print(part, t, len(a.files), len(b.files), "bitwise" if not bad and sorted(a.files) == sorted(b.files) else f"{len(bad)} differ: {bad[:12]}")
PY
for t in M G R; do inn $t timeout 100 python3 $root/.gpu/b/ktime3.py 1e8 | filt | sed "s/^/$t /"; done 2>&1 | tee $out/ktime.txt
echo "ktime $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for r in 1; do for t in M G R; do
  inn $t timeout 100 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 3 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path-1e8.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt
