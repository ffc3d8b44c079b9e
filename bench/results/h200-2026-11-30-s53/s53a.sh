#!/usr/bin/env bash
# session 53, call 1: M = main dfd7c24 against G = main + physics/grid_constant (kernel parameters
# __grid_constant__, read in place). 1. scmp.py of both (bitwise expected); 2. bench.path cost 1e8
# --repeats 3 alternated M G M G; 3. bench.mesh_profile plane/mesh/terrain/terrain-air 1e7 for M, G.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M G; do
  ( inn $t timeout 240 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-$t.txt
    for c in plane mesh terrain terrain-air; do inn $t timeout 120 python3 -m bench.mesh_profile --case $c --n 1e5 --repeats 0 >> $out/warm-$t.txt; done ) &
  ( cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_s$t PYTHONPATH=/tmp/site:$PWD timeout 240 python3 $root/.gpu/b/scmp.py /tmp/$t.npz cuda:0 20000 > $out/scmp-$t.txt 2>&1 ) &
done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
python3 - <<'PY' | tee $out/cmp.txt
import numpy as np
a, b = np.load("/tmp/M.npz"), np.load("/tmp/G.npz")
print("datasets", len(a.files), len(b.files), "same names" if sorted(a.files) == sorted(b.files) else "DIFFERENT NAMES")
bad = [k for k in a.files if k in b.files and not np.array_equal(a[k], b[k], equal_nan=True)]
print("bitwise" if not bad else f"{len(bad)} differ: {bad[:20]}")
PY
for r in 1 2; do for t in M G; do
  inn $t timeout 120 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 3 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path-1e8.txt
echo "path $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for c in plane mesh terrain terrain-air; do for t in M G; do
  inn $t timeout 100 python3 -m bench.mesh_profile --case $c --n 1e7 --repeats 3 | filt | sed "s/^/$t /"
done; done 2>&1 | tee $out/mesh.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt
