#!/usr/bin/env bash
# session 44, call 3: the mesh of a plane and the box on main (N) against helper meshedge's branch (E,
# d154f02: a small mesh's edge and corner search out of line in CUDA code); E's kernel under register caps
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
test -s /tmp/site/warp/bin/warp.so || { echo "fresh machine"; exit 3; }
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl 2>&1 | tail -2
root=$PWD
inn() { local t=$1; shift; (cd $root/.whl/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
for t in N E; do ( inn $t python3 -m bench.meshes plane --device cuda:0 --n 1e5 --repeats 1 > $out/warm-$t.txt; inn $t python3 -m bench.meshes box --device cuda:0 --n 1e5 --jitter 1e-5 > /dev/null ) & done; wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in N E; do
  inn $t python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 | filt | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/mesh-plane.txt
echo "plane timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for t in N E; do
  inn $t python3 -m bench.meshes box --device cuda:0 --n 1e7 --jitter 1e-5 | filt | sed "s/^/$t: /"
done 2>&1 | tee $out/box.txt
echo "box $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn E timeout 200 python3 -m bench.variants --device cuda:0 --mesh --precisions float32 --caps none,128 --n 1e8 --no-run | filt | tee $out/variants-E.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
