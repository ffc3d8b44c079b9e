#!/usr/bin/env bash
# On the lent GPU machine: . .gpu/b/env.sh && bash bench/gpu_profile.sh
# Where the dense phase's time goes for skins, step fractions and rounds (1e6 pellets of paper shots)
set -uo pipefail
out=${OUT:-/tmp/out}
mkdir -p "$out"
for a in "--rounds 4" "--rounds 2" "--skin 3 --step-fraction 0.375" "--skin 4 --step-fraction 0.5" "--skin 4 --step-fraction 0.5 --rounds 2" "--skin 6 --step-fraction 0.75 --rounds 2"; do
  timeout 100 python3 -m bench.collision_profile $a 2>&1 | grep -v "^Warp\|^Module" | tee -a "$out/profile.txt"
done
