#!/usr/bin/env bash
# One call on the lent GPU machine: the CUDA tests, then the benchmarks. Results land in $OUT.
# Usage there (after stage1/stage2): . .gpu/b/env.sh && bash bench/gpu_session.sh [tests|bench|all]
set -uo pipefail
what=${1:-all}
out=${OUT:-/tmp/out}
mkdir -p "$out"
nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.max.sm --format=csv | tee "$out/gpu.txt"
if [[ $what == tests || $what == all ]]; then
  python3 -m pytest tests -q -x -n 8 -p no:cacheprovider 2>&1 | tail -15 | tee "$out/tests.txt"
fi
if [[ $what == bench || $what == all ]]; then
  python3 -m bench throughput --device cuda:0 --sizes 1e4,1e5,1e6,1e7,1e8 --numpy-max 1e6 --repeats 5 --out "$out" 2>&1 | grep -v "^Warp\|CUDA Toolkit\|Devices\|Kernel cache\|\.cache" | tee "$out/throughput.txt"
  python3 -m bench throughput --device cuda:0 --sizes 1e8 --numpy-max 0 --repeats 5 --precision float64 --out "$out" 2>&1 | grep "N=" | tee -a "$out/throughput.txt"
  python3 -m bench throughput --device cpu --sizes 1e6 --numpy-max 1e6 --repeats 3 --out "$out" 2>&1 | grep "N=" | tee -a "$out/throughput.txt"
  python3 -m bench write --device cuda:0 --write-n 1e8 --out /tmp/wr-bench 2>&1 | grep "write" | tee "$out/write.txt"
  python3 -m bench memory --device cuda:0 --memory-cases "1e9:,1e8:landing" --out /tmp/wr-bench 2>&1 | grep "memory" | tee "$out/memory.txt"
fi
