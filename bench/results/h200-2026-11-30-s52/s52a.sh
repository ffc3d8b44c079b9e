#!/usr/bin/env bash
# DRAFT for session 52, call 1 (copy to .gpu/b/s52a.sh). Trees (mkexp.sh): M = main, K = perf/walk,
# (closed-form run along a row), B = perf/block (record log in blocks of 32 columns), A = perf/ahead (next step's words read while a step is watched), KB = perf/s52-all (all three merged; worktree /work/wt-walk).
# Carry .gpu/b and .gpu/t. mkexp: M=/work/main K=<wt of perf/walk> B=/work/wt-block A=/work/wt-ahead KB=/work/wt-walk
# 1. gpucheck.py chunks on main from the carried checkout ($PWD: it needs tests/);
# 2. scmp.py of M, K, B, KB: B bitwise with M expected; K/KB maps may differ in a few cells (count them);
# 3. bench.path cost 1e8 alternated twice for M K B KB; ktime.py 1e8 for each; then 1e9 for the best.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
( WARP_CACHE_PATH=/tmp/wc_g PYTHONPATH=/tmp/site:$PWD/.gpu/t/site:$PWD timeout 250 python3 .gpu/b/gpucheck.py chunks > $out/chunks.txt 2>&1; echo "rc $?" >> $out/chunks.txt ) &
for t in M K B A KB; do ( inn $t timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > /dev/null ) & done
for t in M K B A KB; do ( cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_s$t PYTHONPATH=/tmp/site:$PWD timeout 200 python3 $root/.gpu/b/scmp.py /tmp/$t.npz > $out/scmp-$t.txt 2>&1 ) & done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
grep "same bits\|rc " $out/chunks.txt
python3 - <<'PY' | tee $out/cmp.txt
import numpy as np
a = np.load("/tmp/M.npz")
for t in ("K", "B", "A", "KB"):
    b = np.load(f"/tmp/{t}.npz")
    for k in a.files:
        d = a[k] != b[k]
        print(t, k, "bitwise" if np.array_equal(a[k], b[k], equal_nan=True) else f"{int(d.sum())} differ, at most {np.nanmax(np.abs(a[k] - b[k]))}")
PY
for r in 1 2; do for t in M K B A KB; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path-1e8.txt
for t in M K B A KB; do inn $t timeout 100 python3 $root/.gpu/b/ktime.py 1e8 | filt | sed "s/^/$t /"; done 2>&1 | tee $out/ktime.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt && ls
