#!/usr/bin/env bash
# session 56, call 8: the landed tree Q (05bfc51: H with the screen's hull crossings written once)
# against H (b6be32a): the terrain in air, 1e7, alternated twice; cmpwalk on Q; tests/test_grid_walk.py
# and tests/test_air_flight.py on the H200 (CUDA only).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in H Q; do
  ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 --flights air > $out/warm-$t.txt ) &
done
( inn Q timeout 250 python3 $root/bench/results/h200-2026-11-30-s54/cmpwalk.py 2e3 cuda:0 float32 > $out/warm-cmp.txt ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in H Q; do
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 --flights air | filt | grep "air, terrain" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
echo "terrain $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn Q timeout 120 python3 $root/bench/results/h200-2026-11-30-s54/cmpwalk.py 2e4 cuda:0 float32 | filt | tee $out/cmpwalk.txt
echo "cmpwalk $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn Q env WARP_RICOCHET_TEST_DEVICES=cuda:0 timeout 250 python3 -m pytest -q -p no:cacheprovider tests/test_grid_walk.py tests/test_air_flight.py 2>&1 | tail -8 | tee $out/tests.txt
echo "tests $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt
