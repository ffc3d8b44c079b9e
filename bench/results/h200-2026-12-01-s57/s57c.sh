#!/usr/bin/env bash
# session 57, call 3: main H (fe34c30: E landed, the tuple rule) against B (b07c078, before
# fde1c90's shared hull crossings, which session 56 could not time): the terrain in air at 1e7,
# alternated twice; H's mesh of the paper's plane in vacuum and in air at 1e8 (bench.meshes plane
# --flights vacuum,air), twice; tests of the meshes' edges and the Warp rules on CUDA.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in H B; do
  ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 --flights air > $out/warm-$t.txt ) &
done
( inn H timeout 250 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 --flights vacuum,air > $out/warm-plane.txt ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in H B; do
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 --flights air | filt | grep "pellets/s" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
for r in 1 2; do
  inn H timeout 90 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 --flights vacuum,air | filt | grep "pellets/s\|plane time" | sed "s/^/$r H: /"
done 2>&1 | tee $out/plane.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn H env WARP_RICOCHET_TEST_DEVICES=cuda:0 timeout 200 python3 -m pytest -q -p no:cacheprovider -x tests/test_warp_rules.py tests/test_edges.py tests/test_meshes.py 2>&1 | tail -8 | tee $out/tests.txt
echo "tests $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt
