#!/usr/bin/env bash
# session 51, call 4: each kernel's GPU time in bench.path cost's cases at 1e8 (M = main 2d72f12: the
# replay's cap, the slim track); R (perf/raw: the record log's words read and written by raw index,
# no negative wrap, no stride) against M at 1e8, alternated, and its bits (scmp.py)
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M R; do ( inn $t timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-$t.txt ) & done
for t in M R; do ( cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_s$t PYTHONPATH=/tmp/site:$PWD timeout 200 python3 $root/.gpu/b/scmp.py /tmp/$t.npz > $out/scmp-$t.txt 2>&1 ) & done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
python3 - <<'PY' | tee $out/cmp.txt
import numpy as np
a, b = np.load("/tmp/M.npz"), np.load("/tmp/R.npz")
for k in a.files:
    print(k, "bitwise" if np.array_equal(a[k], b[k], equal_nan=True) else f"{int((a[k] != b[k]).sum())} differ, at most {np.nanmax(np.abs(a[k] - b[k]))}")
PY
for r in 1 2; do for t in M R; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path-1e8.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for t in M R; do inn $t timeout 100 python3 $root/.gpu/b/ktime.py 1e8 | filt | sed "s/^/$t /"; done 2>&1 | tee $out/ktime.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt && rm -f warm-*.txt && ls
