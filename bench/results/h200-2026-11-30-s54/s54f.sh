#!/usr/bin/env bash
# session 54, call 6: the walk starting from a single cell (W6, the working tree: also the landing's
# range from its contact normal) against main (M) and the last commit (H = 0e5a609): bench.meshes
# terrain 1e7 alternated twice; bench.meshes plane 1e8 on M, H and W6; bench.meshes box (1e7 pellets
# at a closed box from all sides, half at its edges and vertices) on W6; tests/test_grid_walk.py on CUDA.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M H W6; do
  ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 > $out/warm-$t.txt ) &
  ( inn $t timeout 250 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 > $out/warm-plane-$t.txt ) &
done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in M H W6; do
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 | filt | grep "vacuum\|air" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
for t in M H W6; do
  inn $t timeout 60 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 | filt | sed "s/^/$t: /"
done 2>&1 | tee $out/plane.txt
echo "bench $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn W6 timeout 200 python3 -m bench.meshes box --device cuda:0 --n 1e7 --chunk 1e6 | filt | tee $out/box.txt
echo "box $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cp -r $root/tests $root/.gpu/b/exp/W6/ 2>/dev/null
inn W6 env WARP_RICOCHET_TEST_DEVICES=cuda:0 timeout 240 python3 -m pytest -q -p no:cacheprovider tests/test_grid_walk.py 2>&1 | tail -15 | tee $out/tests.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt
