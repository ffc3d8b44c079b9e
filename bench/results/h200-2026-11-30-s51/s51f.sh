#!/usr/bin/env bash
# session 51, call 6: W (perf/wide: the record log indexed in 64 bits, a GPU chunk bounded by memory
# alone) against M (main 675e5c6) at 1e8 alternated, and at 1e9 once each; each kernel's time in W;
# a 2e7-pellet run's statistics and hazard answers in W (one chunk, a log in rows past 2^31 words)
# against M (5 chunks) bit for bit; scmp.py bits; examples/hazard.toml chunks/resume in W
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M W; do ( inn $t timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-$t.txt ) & done
for t in M W; do ( cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_s$t PYTHONPATH=/tmp/site:$PWD timeout 200 python3 $root/.gpu/b/scmp.py /tmp/$t.npz > $out/scmp-$t.txt 2>&1 ) & done
( cd $root/.gpu/b/exp/W && WARP_CACHE_PATH=/tmp/wc_gW PYTHONPATH=/tmp/site:$PWD timeout 250 python3 $root/.gpu/b/gpucheck.py chunks > $out/chunks.txt 2>&1; echo "rc $?" >> $out/chunks.txt ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
grep "same bits\|rc " $out/chunks.txt
python3 - <<'PY' | tee $out/cmp.txt
import numpy as np
a, b = np.load("/tmp/M.npz"), np.load("/tmp/W.npz")
for k in a.files:
    print(k, "bitwise" if np.array_equal(a[k], b[k], equal_nan=True) else f"{int((a[k] != b[k]).sum())} differ")
PY
for t in M W; do inn $t timeout 100 python3 $root/.gpu/b/wcmp.py 2e7 /tmp/w-$t.pkl | filt | tail -1; done
python3 - <<'PY' | tee $out/wcmp.txt
import pickle, numpy as np
a, b = pickle.load(open("/tmp/w-M.pkl", "rb")), pickle.load(open("/tmp/w-W.pkl", "rb"))
bad = [k for k in a if k not in b or not np.array_equal(np.asarray(a[k]), np.asarray(b[k]))]
print(len(a), "values;", "all the same bits" if not bad and a.keys() == b.keys() else f"differ: {bad[:20]}")
PY
for r in 1 2; do for t in M W; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path-1e8.txt
inn W timeout 100 python3 $root/.gpu/b/ktime.py 1e8 | filt | tee $out/ktime.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn W timeout 150 python3 -m bench.path cost --device cuda:0 --sizes 1e9 --repeats 1 | filt | grep "N 1e" | sed "s/^/W: /" | tee $out/path-1e9.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt && rm -f warm-*.txt && ls
