#!/usr/bin/env bash
# session 57, call 6: the vacuum's search of a mesh or a post (`geometry.solid_time`, V1) and, with
# it, a mesh's contact normal (`edge_contact.contact_normal`, V3) out of line in CUDA code, against
# main H (af07cef): the mesh of the paper's plane at 1e8 and the terrain in vacuum at 1e7,
# alternated twice; per-pellet outputs of V3 against H (cmpgpu.py: landings in vacuum on the mesh,
# the box and the terrain, runs to rest on the mesh and the box in vacuum and in air).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
c=$root/bench/results/h200-2026-12-01-s57/cmpgpu.py
mkdir -p /tmp/cg
TREES="H V1 V3"
for t in $TREES; do
  ( inn $t timeout 250 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 > $out/warm-$t.txt ) &
  ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 --flights vacuum > $out/warm-t-$t.txt ) &
done
for t in H V3; do
  ( inn $t timeout 250 python3 $c run 2e4 /tmp/cg $t cuda:0 mesh-vac-3,box-vac-3,terrain-vac-3 > $out/cmp-$t-a.txt ) &
  ( inn $t timeout 250 python3 $c run 2e4 /tmp/cg $t cuda:0 mesh-rest-vac,box-rest-vac,mesh-rest-air,box-rest-air > $out/cmp-$t-b.txt ) &
done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in $TREES; do
  inn $t timeout 60 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 | filt | grep "pellets/s\|plane time" | sed "s/^/$r $t: /"
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 --flights vacuum | filt | grep "pellets/s" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/timed.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn H python3 $c compare /tmp/cg H V3 | filt | tee $out/compare.txt
cd $out && tar czf all.tgz *.txt
