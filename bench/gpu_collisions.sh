#!/usr/bin/env bash
# On the lent GPU machine (after stage1/stage2): . .gpu/b/env.sh && bash bench/gpu_collisions.sh [check|speed|all]
#   check: the collision tests on CUDA (dense phase, graph capture, grouped HashGrid against the references)
#   speed: Warp's own DEM example and our dense phase in the same run, then 10,000 shots x 450 pellets
set -uo pipefail
what=${1:-all}
out=${OUT:-/tmp/out}
mkdir -p "$out"
quiet() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module "; }
nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.max.sm --format=csv | tee "$out/gpu.txt"
if [[ $what == check || $what == all ]]; then
  WARP_RICOCHET_TEST_DEVICES=cuda:0 timeout 300 python3 -m pytest tests/test_collisions.py tests/test_stability.py tests/test_pipeline.py -q -n 8 -p no:cacheprovider -k "not cli" -rfE 2>&1 | grep "^FAILED\\|^ERROR\\|passed\\|failed" | cut -c1-300 | tee "$out/collision-tests.txt"
fi
if [[ $what == speed || $what == all ]]; then
  timeout 120 python3 -m bench.example_dem --device cuda:0 --sizes 65536,524288 --frames 20 2>&1 | quiet | tee "$out/example_dem.txt"
  for p in float32 float64; do
    timeout 150 python3 -m bench.collisions throughput --device cuda:0 --precision $p --count 450 --shots 2223 --repeats 3 2>&1 | quiet | tee -a "$out/collisions-throughput.txt"
  done
  timeout 300 python3 -m bench.collisions throughput --device cuda:0 --precision float32 --count 450 --shots 10000 --repeats 3 2>&1 | quiet | tee -a "$out/collisions-throughput.txt"
  timeout 60 python3 -m bench.example_dem --device cuda:0 --sizes 65536,524288 --frames 20 2>&1 | quiet | tee -a "$out/example_dem.txt"
fi
