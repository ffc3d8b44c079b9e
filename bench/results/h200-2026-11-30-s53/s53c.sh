#!/usr/bin/env bash
# session 53, call 3: M = main dfd7c24 against F = main + grid_constant as it lands (every core and
# replay kernel's parameters read in place but the map's replay's). 1. scmp.py M F (bitwise expected);
# 2. bench.path cost 1e8 --repeats 3 M F; F --repeats 1 (a first run); F at 1e9.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M F; do
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
    if not os.path.exists(f"/tmp/M{part}.npz") or not os.path.exists(f"/tmp/F{part}.npz"): print(part, "missing"); continue
    a, b = np.load(f"/tmp/M{part}.npz"), np.load(f"/tmp/F{part}.npz")
    bad = [k for k in a.files if k in b.files and not np.array_equal(a[k], b[k], equal_nan=True)]
    print(part, "F", len(a.files), len(b.files), "bitwise" if not bad and sorted(a.files) == sorted(b.files) else f"{len(bad)} differ: {bad[:12]}")
PY
for t in M F; do
  inn $t timeout 100 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 3 | filt | grep "N 1e" | sed "s/^/repeats 3 $t: /"
done 2>&1 | tee $out/path-1e8.txt
inn F timeout 100 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/repeats 1 F: /" | tee -a $out/path-1e8.txt
echo "1e8 $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn F timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e9 --repeats 1 | filt | grep "N 1e" | sed "s/^/F /" | tee $out/path-1e9.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt
