#!/usr/bin/env bash
# session 51, call 1 (trees M = main c5f40b8, C = perf/count 323c87e; carry .gpu/b and .gpu/t):
# C = perf/count, as in session 50: `git ls-files -co --exclude-standard` minus bench/results, docs,
# RESULTS, CHANGELOG, tests, .gpu; carry .gpu/b and .gpu/t):
# 1. main after session 50's review fixes (rerun launched after every replay, no host read), never run
#    on a GPU: gpucheck.py chunks/rerun (examples/hazard.toml) + bench.path cost 1e8;
# 2. perf/count (C) against M at 1e8, alternated twice; scmp.py bits C vs M (same records expected);
# 3. the replay kernel under register caps (R128, R96: patch core/replay.py's options on tree copies).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for cap in 128 96; do
  rm -rf $root/.gpu/b/exp/R$cap; cp -r $root/.gpu/b/exp/M $root/.gpu/b/exp/R$cap
  python3 - $root/.gpu/b/exp/R$cap $cap <<'PY'
import sys
p = f"{sys.argv[1]}/warp_ricochet/core/replay.py"
s = open(p).read()
a = '    options.pop("cuda_max_registers", None)\n'
assert s.count(a) == 1
open(p, "w").write(s.replace(a, f'    options["cuda_max_registers"] = {sys.argv[2]}\n'))
PY
done
for w in chunks rerun; do
  ( WARP_CACHE_PATH=/tmp/wc_$w PYTHONPATH=/tmp/site:$PWD/.gpu/t/site:$PWD timeout 250 python3 .gpu/b/gpucheck.py $w > $out/$w.txt 2>&1; echo "rc $?" >> $out/$w.txt ) &
done
for t in M C R128 R96; do ( inn $t timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-$t.txt ) & done
for t in M C; do ( cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_s$t PYTHONPATH=/tmp/site:$PWD timeout 200 python3 $root/.gpu/b/scmp.py /tmp/$t.npz > $out/scmp-$t.txt 2>&1 ) & done
wait
echo "checks + warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
grep "same bits\|rc " $out/chunks.txt $out/rerun.txt
python3 - <<'PY' | tee $out/cmp.txt
import numpy as np
a, b = np.load("/tmp/M.npz"), np.load("/tmp/C.npz")
for k in a.files:
    print(k, "bitwise" if np.array_equal(a[k], b[k], equal_nan=True) else f"{int((a[k] != b[k]).sum())} differ")
PY
for r in 1 2; do for t in M C R128 R96; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path-1e8.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt && ls
