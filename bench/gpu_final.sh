#!/usr/bin/env bash
# On the lent GPU machine (after stage1/stage2): . .gpu/b/env.sh && bash bench/gpu_final.sh
# The final code: collision and stability tests on CUDA, DEM example beside our throughput (rounds 4, 2, 1),
# 10,000 shots x 450, and where the time goes.
set -uo pipefail
out=${OUT:-/tmp/out}
mkdir -p "$out"
quiet() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module "; }
bash bench/gpu_collisions.sh all
for r in 2 1; do
  timeout 60 python3 -m bench.collisions throughput --device cuda:0 --count 450 --shots 2223 --repeats 3 --rounds $r 2>&1 | grep shots | tee -a "$out/collisions-throughput.txt"
done
timeout 60 python3 -m bench.collision_profile 2>&1 | quiet | tee "$out/profile.txt"
