#!/usr/bin/env bash
# session 55, call 9: L2 (L with the leaving rule also asking that no kept edge or corner projecting
# inside the face lies within the centre's overlap behind its plane: `face_depth`), the code that
# lands, against main M: plane 1e8 and terrain 1e7, once each (the device time left).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M L2; do
  ( inn $t timeout 150 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 > $out/warm-$t.txt ) &
  ( inn $t timeout 150 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 > $out/warm-plane-$t.txt ) &
done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for t in M L2; do
  inn $t timeout 60 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 | filt | grep "pellets/s\|plane time" | sed "s/^/1 $t: /"
done 2>&1 | tee $out/plane.txt
for t in M L2; do
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 | filt | grep "vacuum, terrain\|air, terrain" | sed "s/^/1 $t: /"
done 2>&1 | tee $out/terrain.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt
