#!/usr/bin/env bash
# session 57, call 7: occupancy by block size and register caps. H: main (256 threads a block, the
# vacuum's mesh kernels uncapped: 255 registers, 8 warps an SM); B4: 128 threads a block; B1: B4 with
# the vacuum's kernels among solids capped at 168 registers (12 warps an SM); B2: B4 capped at 160,
# and the air's among solids at 96 (20 warps an SM). The mesh of the paper's plane at 1e8 and the
# terrain at 1e7 (B2 and H in air, B1 and H in vacuum), alternated twice.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in H B1 B2 B4; do
  ( inn $t timeout 250 python3 -m bench.meshes plane --device cuda:0 --n 1e4 --repeats 1 > $out/warm-$t.txt ) &
done
for t in H B2; do ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 --flights air > $out/warm-a-$t.txt ) & done
for t in H B1; do ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 --flights vacuum > $out/warm-v-$t.txt ) & done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do
  for t in H B1 B2 B4; do
    inn $t timeout 60 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 | filt | grep "pellets/s\|plane time" | sed "s/^/$r $t: /"
  done
  for t in H B2; do
    inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 --flights air | filt | grep "terrain: .*pellets/s" | sed "s/^/$r $t: /"
  done
  for t in H B1; do
    inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 --flights vacuum | filt | grep "terrain: .*pellets/s" | sed "s/^/$r $t: /"
  done
done 2>&1 | tee $out/timed.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt
