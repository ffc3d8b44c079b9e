#!/usr/bin/env bash
# session 41 on the H200: posts old/new (round $1), then (round 2) the dense-phase cases
set -uo pipefail
out=${OUT:-/tmp/out}; mkdir -p "$out"
root=$PWD
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$out/gpu.txt"
cp bench/meshes.py .gpu/b/exp/old/bench/meshes.py
round=${1:-1}
for v in new old; do
  if [[ $v == new ]]; then d=$root; else d=$root/.gpu/b/exp/old; fi
  start=$(date +%s)
  (cd "$d" && PYTHONPATH=/tmp/site:$d timeout ${TPOST:-280} python3 -m bench.meshes posts --n ${NPOST:-1e6} --device cuda:0 --repeats 2) 2>&1 \
    | grep -v '^Warp \|^Module \|CUDA Toolkit\|Devices:\|Kernel cache\|"cpu"\|"cuda:0"' | sed "s/^/$v round $round: /" | tee -a "$out/posts.txt"
  echo "$v round $round: call $(( $(date +%s) - start )) s" | tee -a "$out/posts.txt"
done
if [[ $round == 2 ]]; then
  for c in ${CASES:-true}; do
    for i in 1 2; do
      start=$(date +%s)
      timeout 150 python3 -m warp_ricochet.cli run examples/hazard.toml --set shot.shots=${SHOTS:-100} --set collisions.enabled=$c \
        --device cuda:0 -o /tmp/hz-$c.h5 --overwrite > /tmp/hz.log 2>&1; rc=$?
      echo "hazard example ${SHOTS:-100} shots x 280, collisions=$c, run $i: rc $rc, $(( $(date +%s) - start )) s wall" | tee -a "$out/hazard-collisions.txt"
      tail -15 /tmp/hz.log >> "$out/hazard-collisions.txt"
    done
  done
  if [[ -n ${BERM:-} ]]; then
  start=$(date +%s)
  timeout 240 python3 examples/berm_collisions_study.py --shots 400 --device cuda:0 2>&1 | tail -8 | tee "$out/berm.txt"
  echo "berm study 2 x 400 shots: $(( $(date +%s) - start )) s wall (compiling included)" | tee -a "$out/berm.txt"
  fi
fi
