#!/usr/bin/env bash
# session 52, call 4: U = perf/unroll (main + the stretch's threshold loops unrolled), V = U + the map walk
# keeps a chord's level until its next bound (perf/levels), VE = V + the step log left unzeroed
# (perf/empty-log): bits (scmp), bench.path cost 1e8 alternated twice with --repeats 1 (a first run:
# the log allocated) and once with --repeats 3 (median: the log kept), ktime, the best at 1e9
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in U V VE; do ( inn $t timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > /dev/null ) & done
for t in U V VE; do ( cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_s$t PYTHONPATH=/tmp/site:$PWD timeout 200 python3 $root/.gpu/b/scmp.py /tmp/$t.npz > $out/scmp-$t.txt 2>&1 ) & done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
python3 - <<'PY' | tee $out/cmp.txt
import numpy as np
a = np.load("/tmp/U.npz")
for t in ("V", "VE"):
    b = np.load(f"/tmp/{t}.npz")
    for k in a.files:
        same = np.array_equal(a[k], b[k], equal_nan=True)
        print(t, k, "bitwise" if same else f"{int((a[k] != b[k]).sum())} differ, at most {np.nanmax(np.abs(a[k] - b[k]))}")
PY
for r in 1 2; do for t in U V VE; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path-1e8.txt
for t in U V VE; do
  inn $t timeout 90 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 3 | filt | grep "N 1e" | sed "s/^/median of 3 $t: /"
done 2>&1 | tee $out/path-1e8-r3.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for t in V VE; do inn $t timeout 100 python3 $root/.gpu/b/ktime.py 1e8 | filt | grep -v " 0.00[01] s" | sed "s/^/$t /"; done 2>&1 | tee $out/ktime.txt
echo "ktime $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn VE timeout 150 python3 -m bench.path cost --device cuda:0 --sizes 1e9 --repeats 1 | filt | grep "N 1e" | sed "s/^/VE /" | tee $out/path-1e9.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt && ls
