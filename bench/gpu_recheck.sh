#!/usr/bin/env bash
# On the lent GPU machine (after stage1/stage2, with .gpu/ref carried): . .gpu/b/env.sh && bash bench/gpu_recheck.sh
# After the collision work: rounds per step at 1e6 and 4.5e6 pellets, then the core kernel's CUDA tests,
# its CPU-GPU agreement and its throughput re-measured (the kernel changed for collisions).
set -uo pipefail
out=${OUT:-/tmp/out}
mkdir -p "$out"
quiet() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module "; }
nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.max.sm --format=csv | tee "$out/gpu.txt"
for r in 1 2; do
  timeout 60 python3 -m bench.collisions throughput --device cuda:0 --count 450 --shots 2223 --repeats 3 --rounds $r 2>&1 | grep shots | tee -a "$out/collisions-rounds.txt"
done
timeout 90 python3 -m bench.collisions throughput --device cuda:0 --count 450 --shots 10000 --repeats 3 --rounds 2 2>&1 | grep shots | tee -a "$out/collisions-rounds.txt"
WARP_RICOCHET_TEST_DEVICES=cuda:0 WARP_RICOCHET_CPU_REFERENCE=.gpu/ref/cpu.h5 timeout 240 python3 -m pytest tests -q -n 8 -p no:cacheprovider -k "not cli" 2>&1 | tail -8 | tee "$out/tests.txt"
timeout 60 python3 -m bench.agreement compare --device cuda:0 --file .gpu/ref/cpu.h5 2>&1 | quiet | tee "$out/agreement.txt"
timeout 90 python3 -m bench throughput --device cuda:0 --sizes 1e6,1e8 --numpy-max 0 --repeats 5 --out "$out" 2>&1 | grep "N=" | tee "$out/throughput.txt"
