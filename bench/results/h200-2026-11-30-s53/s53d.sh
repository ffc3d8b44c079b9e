#!/usr/bin/env bash
# session 53, call 4: the terrain's chord length (mesh_contact.CHORD_EDGES: 2, 4 = main F, 8, 16 median
# triangle edges a chord) on the H200: bench.meshes terrain 1e7 (vacuum and air) for each, alternated
# twice; then bench.meshes plane 1e8 on F (the two-triangle mesh against the plane, parameters in place).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in C2 F C8 C16; do
  ( inn $t timeout 200 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 > $out/warm-$t.txt ) &
done
( inn F timeout 200 python3 -m bench.meshes plane --device cuda:0 --n 1e5 --repeats 1 > $out/warm-plane.txt ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in C2 F C8 C16; do
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 | filt | grep "vacuum\|air" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
echo "terrain $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn F timeout 90 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 | filt | tee $out/plane.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt
