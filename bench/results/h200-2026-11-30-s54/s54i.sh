#!/usr/bin/env bash
# session 54, call 9: main's head after the review's fix (F = 755037c: a block past the raster's edge
# passed only above the whole raster; the vertices' offsets in the margin) against e380e41 (P) and
# main (M): bench.meshes terrain 1e7 alternated twice; F's per-pellet outputs against the BVH's;
# tests/test_grid_walk.py on CUDA only.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M P F; do
  ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 > $out/warm-$t.txt ) &
done
( inn F timeout 250 python3 $root/bench/results/h200-2026-11-30-s54/cmpwalk.py 2e3 cuda:0 float32 > $out/warm-cmp.txt ) &
cp -r $root/tests $root/.gpu/b/exp/F/ 2>/dev/null
( inn F env WARP_RICOCHET_TEST_DEVICES=cuda:0 timeout 280 python3 -m pytest -q -p no:cacheprovider tests/test_grid_walk.py 2>&1 | tail -6 > $out/tests.txt ) &
wait
echo "warm-up and tests $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in M P F; do
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 | filt | grep "vacuum\|air" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
echo "terrain $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn F timeout 120 python3 $root/bench/results/h200-2026-11-30-s54/cmpwalk.py 2e4 cuda:0 float32 | filt | tee $out/cmpwalk.txt
cat $out/tests.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt
