#!/usr/bin/env bash
# On the lent GPU machine (after stage1/stage2): . .gpu/b/env.sh && bash bench/gpu_session.sh [check|bench]
#   check: the CUDA tests (with the CPU-GPU test against .gpu/ref/cpu.h5, saved here by
#          `python -m bench.agreement save --device cpu --file .gpu/ref/cpu.h5`), the agreement table
#   bench: kernel variants, throughput against N (beside NumPy), the write run, peak host memory, run time against error
#   air: flight in air beside vacuum (statistics only, 1e8; collisions, 10,000 x 450)
#   air-tests: the air tests on CUDA; air-study: the tradeoff's timings and states, the air study
#          (1000 shots), the air stability sweep
#   tallies-tests: the CUDA tests of the landing tallies, hazard and precision, collisions, air dense phase
#   tallies: statistics only before this work (.gpu/old, a git archive of 27e7781) beside now, with
#          quantiles and hazard maps
#   tallies-collisions: collisions 10,000 x 450 old beside new, the launch overlaps, the safety study
#   sampling (issue 28), rest, rest-collisions (issue 25), terrain, meshes (issue 27), profile-map (issue 26: ncu),
#   dask (issue 29), gpus-a|b|c (issues 29 and 30, on nvidia-h200-x2: dask-cuda's wheels, `gpu_wheels.sh dask`), terrain, mesh-rest and meshes need the wheels of bench/gpu_wheels.sh installed into /tmp/site first
#   interrupts: signal-to-exit latency of collision runs on CUDA (10,000 paper shots, one shot of 3e6)
#   collisions: the collision, stability and pipeline tests on CUDA; Warp's DEM example and the dense phase in the
#          same run (1e6 pellets: rounds 4, 2, 1, float64; 10,000 shots x 450); where the dense phase's time goes
set -uo pipefail
what=${1:-check}
out=${OUT:-/tmp/out}
mkdir -p "$out"
quiet() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module "; }
nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.max.sm --format=csv | tee "$out/gpu.txt"
if [[ $what == check || $what == all ]]; then
  WARP_RICOCHET_TEST_DEVICES=cuda:0 WARP_RICOCHET_CPU_REFERENCE=.gpu/ref/cpu.h5 python3 -m pytest tests -q -n 8 -p no:cacheprovider -k "not cli" 2>&1 | tail -6 | tee "$out/tests.txt"
  [[ -f .gpu/ref/cpu.h5 ]] && python3 -m bench.agreement compare --device cuda:0 --file .gpu/ref/cpu.h5 2>&1 | quiet | tee "$out/agreement.txt"
fi
if [[ $what == bench || $what == all ]]; then
  python3 -m bench.variants --device cuda:0 --n 1e8 --caps default,default+fast,none,96+fast 2>&1 | quiet | tee "$out/variants.txt"
  python3 -m bench throughput --device cuda:0 --sizes 1e4,1e5,1e6,1e7,1e8,1e9 --numpy-max 1e6 --repeats 5 --out "$out" 2>&1 | grep "N=" | tee "$out/throughput.txt"
  python3 -m bench throughput --device cuda:0 --sizes 1e8 --numpy-max 0 --repeats 5 --precision float64 --out "$out" 2>&1 | grep "N=" | tee -a "$out/throughput.txt"
  python3 -m bench write --device cuda:0 --write-n 1e8 --out /tmp/wr-bench 2>&1 | grep "write" | tee "$out/write.txt"
  python3 -m bench memory --device cuda:0 --memory-cases "1e9:,1e8:landing,1e7:" --out /tmp/wr-bench 2>&1 | grep "memory" | tee "$out/memory.txt"
  python3 -m bench tradeoff --device cuda:0 --tradeoff-n 1e6,1e8 --out /tmp/wr-bench 2>&1 | grep "tradeoff" | tee "$out/tradeoff.txt"
fi
if [[ $what == collisions || $what == all ]]; then
  WARP_RICOCHET_TEST_DEVICES=cuda:0 timeout 300 python3 -m pytest tests/test_collisions.py tests/test_stability.py tests/test_pipeline.py -q -n 8 -p no:cacheprovider -k "not cli" -rfE 2>&1 | grep "^FAILED\|^ERROR\|passed\|failed" | cut -c1-300 | tee "$out/collision-tests.txt"
  timeout 120 python3 -m bench.example_dem --device cuda:0 --sizes 65536,524288 --frames 20 2>&1 | quiet | tee "$out/example_dem.txt"
  for a in "--rounds 4" "--rounds 2" "--rounds 1" "--precision float64"; do
    timeout 150 python3 -m bench.collisions throughput --device cuda:0 --shots 2223 $a 2>&1 | grep shots | tee -a "$out/collisions-throughput.txt"
  done
  timeout 300 python3 -m bench.collisions throughput --device cuda:0 --shots 10000 2>&1 | grep shots | tee -a "$out/collisions-throughput.txt"
  timeout 60 python3 -m bench.collisions profile --device cuda:0 2>&1 | quiet | tee "$out/collisions-profile.txt"
  timeout 120 python3 -m bench.example_dem --device cuda:0 --sizes 65536,524288 --frames 20 2>&1 | quiet | tee -a "$out/example_dem.txt"
fi
if [[ $what == air ]]; then
  python3 -m bench.air throughput --device cuda:0 --sizes 1e6,1e8 --repeats 5 --out "$out/air" 2>&1 | quiet | tee "$out/air-throughput.txt"
  python3 -m bench.air throughput --device cuda:0 --sizes 1e7 --precision float64 --repeats 3 --out "$out/air64" 2>&1 | quiet | tee -a "$out/air-throughput.txt"
  timeout 400 python3 -m bench.air collisions --device cuda:0 --shots 10000 --repeats 2 --out "$out/air" 2>&1 | quiet | tee "$out/air-collisions.txt"
fi
if [[ $what == air-tests ]]; then
  WARP_RICOCHET_TEST_DEVICES=cuda:0 timeout 400 python3 -m pytest tests/test_air_laws.py tests/test_air_flight.py tests/test_air_dense.py tests/test_stability_air.py -q -n 8 -p no:cacheprovider -rfE 2>&1 | grep "^FAILED\|^ERROR\|passed\|failed\|^E " | cut -c1-300 | tee "$out/air-tests.txt"
fi
if [[ $what == air-study ]]; then
  timeout 200 python3 -m bench.air tradeoff --device cuda:0 --checked 200 --timed 1e7 --no-errors --out "$out/tradeoff" 2>&1 | quiet | tee "$out/air-tradeoff.txt"
  timeout 250 python3 examples/air_study.py --shots 1000 --device cuda:0 --out "$out/study" 2>&1 | quiet | tee "$out/air-study.txt"
  timeout 100 python3 -m bench.stability_air --device cuda:0 2>&1 | quiet | tee "$out/stability-air.txt"
fi
if [[ $what == tallies-tests ]]; then
  WARP_RICOCHET_TEST_DEVICES=cuda:0 timeout 420 python3 -m pytest tests/test_quantiles.py tests/test_hazard.py tests/test_block_table.py \
    tests/test_precision.py tests/test_collisions.py tests/test_air_dense.py tests/test_resume_collisions.py \
    tests/test_golden.py -q -n 8 -p no:cacheprovider -rfE 2>&1 | grep "^FAILED\|^ERROR\|passed\|failed\|^E " \
    | cut -c1-300 | tee "$out/tallies-tests.txt"
fi
if [[ $what == tallies ]]; then
  timeout 200 bench/side_by_side.sh .gpu/old . 3 python3 -m bench throughput --device cuda:0 --sizes 1e8,1e9 \
    --numpy-max 0 --repeats 5 2>&1 | grep "N=" | tee "$out/throughput-side-by-side.txt"
  timeout 100 bench/side_by_side.sh .gpu/old . 2 python3 -m bench throughput --device cuda:0 --sizes 1e8 \
    --numpy-max 0 --repeats 5 --precision float64 2>&1 | grep "N=" | tee -a "$out/throughput-side-by-side.txt"
  timeout 200 python3 -m bench.hazard --device cuda:0 --sizes 1e8,1e9 --repeats 5 --copies 64,1 2>&1 | quiet \
    | tee "$out/hazard.txt"
fi
if [[ $what == tallies-collisions ]]; then
  timeout 200 bench/side_by_side.sh .gpu/old . 1 python3 -m bench.collisions throughput --device cuda:0 \
    --shots 10000 2>&1 | grep shots | tee "$out/collisions-side-by-side.txt"
  timeout 60 python3 -m bench.launch_overlaps --device cuda:0 --shots 200 2>&1 | quiet | tee "$out/launch-overlaps.txt"
  timeout 280 python3 examples/safety_study.py --shots 1000 --device cuda:0 --out /tmp/safety 2>&1 | quiet \
    | tee "$out/safety-study.txt"
fi
if [[ $what == interrupts ]]; then
  timeout 300 python3 -m bench.interrupts --device cuda:0 --kinds paper-shots,shot --trials 8 --out "$out" 2>&1 | quiet \
    | tee "$out/interrupts.txt"
fi
if [[ $what == sampling ]]; then  # issue 28: the pattern's cost beside today's jitter and beside the same cone
  timeout 240 python3 -m bench.patterns --device cuda:0 --pellets 1e8 --precisions float32,float64 --repeats 7 --alone 2>&1 | quiet | tee "$out/patterns.txt"
  timeout 120 python3 -m bench.patterns --device cuda:0 --pellets 1e8 --precisions float32 --repeats 5 --per-shot 2>&1 | quiet | tee "$out/patterns-per-shot.txt"
fi
if [[ $what == rest ]]; then  # issue 25: followed to rest, statistics only and 10,000 collision shots
  timeout 240 python3 -m bench.rest throughput --device cuda:0 --sizes 1e6,1e7 --repeats 3 --out "$out/rest" 2>&1 | quiet | tee "$out/rest-throughput.txt"
fi
if [[ $what == rest-collisions ]]; then
  timeout 420 python3 -m bench.rest collisions --device cuda:0 --shots 10000 --repeats 1 --out "$out/rest" 2>&1 | quiet | tee "$out/rest-collisions.txt"
fi
if [[ $what == rest-kernels ]]; then  # issue 25: each kernel's share of 10,000 shots to rest (collisions, ensemble pass)
  timeout 540 python3 -m bench.rest kernels --device cuda:0 --shots 10000 --out "$out/rest" 2>&1 | quiet | tee "$out/rest-kernels.txt"
fi
if [[ $what == thread-pieces ]]; then  # issue 25: per-shot partials from the core's threads (.gpu/old: the second pass)
  for tree in . .gpu/old . .gpu/old; do  # each tree twice, alternating (the first of each compiles)
    (cd $tree && PYTHONPATH=$PWD:$PYTHONPATH timeout 280 python3 -m bench.rest kernels --device cuda:0 --shots 10000 \
      --only "collisions, air, rest" 2>&1 | quiet | sed "s|^|$tree: |" | tee -a "$out/pieces.txt")
  done
fi
if [[ $what == hazard-example ]]; then  # issue 26: the hazard example whole (2,000 shots of 280 to rest, the map), twice
  for i in 1 2; do
    started=$(date +%s%N)
    python3 -m warp_ricochet.cli run examples/hazard.toml --device cuda:0 -o /tmp/hazard-$i.h5 --overwrite 2>&1 | quiet | tee -a "$out/hazard-example.txt"
    echo "run $i: $((($(date +%s%N) - started) / 1000000)) ms wall" | tee -a "$out/hazard-example.txt"
  done
fi
if [[ $what == rest-layout ]]; then  # issue 25: threads of 16 pellets to rest, sub-pieces of 32 (.gpu/old: the tree before)
  timeout 330 python3 -m bench.rest kernels --device cuda:0 --shots 10000 --only "collisions, air, rest" 2>&1 | quiet | tee "$out/rest-layout-kernels.txt"
  timeout 280 bench/side_by_side.sh .gpu/old . 1 python3 -m bench.rest throughput --device cuda:0 --sizes 1e6,1e7 --repeats 3 \
    --only "air, rest, turf" 2>&1 | tee "$out/rest-layout-throughput.txt"
fi
if [[ $what == terrain ]]; then  # issue 27: a terrain of 1e6 triangles beside the plane
  timeout 150 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 --precision float32 2>&1 | quiet | tee "$out/terrain.txt"
fi
if [[ $what == profile-map ]]; then  # issue 26: the map case's core kernel in Nsight Compute
  timeout 150 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section SpeedOfLight --section LaunchStats \
    --section Occupancy --section WarpStateStats --section SourceCounters --section MemoryWorkloadAnalysis --import-source yes -o "$out/map" \
    python3 -m bench.profile_map --device cuda:0 --n 2e5 2>&1 | tail -5 | tee "$out/profile-map.txt"
  /usr/local/cuda/bin/ncu -i "$out/map.ncu-rep" --page details > "$out/map-details.txt" 2>&1
  /usr/local/cuda/bin/ncu -i "$out/map.ncu-rep" --page source --csv --print-source cuda > "$out/map-source.csv" 2>&1
fi
if [[ $what == meshes ]]; then  # issue 27: a mesh of the plane beside the plane; the box from all sides
  timeout 150 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 2>&1 | quiet | tee "$out/meshes-plane.txt"
  timeout 150 python3 -m bench.meshes box --device cuda:0 --n 1e7 --chunk 1e6 2>&1 | quiet | tee "$out/meshes-box.txt"
fi
if [[ $what == edges ]]; then  # issue 27: edge and corner contacts: the box from all sides, near its edges; the plane as a mesh
  for jitter in 0 1e-5 1e-4; do
    timeout 150 python3 -m bench.meshes box --device cuda:0 --n 1e7 --chunk 1e6 --jitter $jitter 2>&1 | quiet | tee -a "$out/edges-box.txt"
  done
  timeout 150 python3 -m bench.meshes plane --device cuda:0 --n 1e8 --repeats 5 2>&1 | quiet | tee "$out/edges-plane.txt"
fi
if [[ $what == cuda-tests ]]; then  # this session's new tests on the GPU (CUDA only)
  python3 -c "import pytest, scipy; print('pytest', pytest.__version__)" 2>&1 | tee "$out/cuda-tests.txt"
  WARP_RICOCHET_TEST_DEVICES=cuda:0 timeout 540 python3 -m pytest -q -n 6 -p no:cacheprovider -m "not slow" \
    tests/test_thread_pieces.py tests/test_dense_ground.py 2>&1 | tail -15 | tee -a "$out/cuda-tests.txt"
fi
if [[ $what == dask ]]; then  # issue 29: a run through a one-worker cluster against the direct run (wheels in .whl)
  timeout 300 python3 -m bench.dask overhead --device cuda:0 --study collisions --shots 10000 --air --repeats 3 2>&1 | quiet | tee "$out/dask-collisions.txt"
  timeout 120 python3 -m bench.dask overhead --device cuda:0 --pellets 1e9 --repeats 3 2>&1 | quiet | tee "$out/dask-statistics.txt"
fi
if [[ $what == gpus-a || $what == gpus-b || $what == gpus-c ]]; then  # issue 30 (and 29): one and two GPUs through dask-cuda
  nvidia-smi topo -m > "$out/topology.txt" 2>&1
  gpus=$(nvidia-smi -L | wc -l); workers=$(seq -s, 1 "$gpus")  # 1,2 on nvidia-h200-x2; 1 on one GPU
  nvidia-smi --query-gpu=index,utilization.gpu,memory.used --format=csv -l 1 > "$out/smi-$what.csv" 2>&1 &
  smi=$!
fi
if [[ $what == gpus-a ]]; then  # the 1e9 statistics run through one worker; 10,000 collision shots on 1 and 2 GPUs
  timeout 120 python3 -m bench.dask overhead --device cuda:0 --pellets 1e9 --repeats 5 2>&1 | quiet | tee "$out/dask-statistics.txt"
  timeout 400 python3 -m bench.dask scaling --study collisions --shots 10000 --workers $workers --direct --repeats 3 2>&1 | quiet | tee "$out/scaling-collisions.txt"
fi
if [[ $what == gpus-b ]]; then  # a 64-point sweep to rest; 1e10 pellets statistics only (5 runs of 2e9)
  timeout 420 python3 -m bench.dask scaling --study sweep-rest --points 64 --pellets 1e5 --workers $workers --direct --repeats 2 2>&1 | quiet | tee "$out/scaling-sweep-rest.txt"
  timeout 150 python3 -m bench.dask scaling --study statistics --points 5 --pellets 2e9 --workers $workers --direct --repeats 3 2>&1 | quiet | tee "$out/scaling-statistics.txt"
fi
if [[ $what == gpus-c ]]; then  # the exposure map along the path, 2 runs of 1e7
  timeout 500 python3 -m bench.dask scaling --study exposure --points 2 --pellets 1e7 --workers $workers --repeats 1 2>&1 | quiet | tee "$out/scaling-exposure.txt"
fi
if [[ $what == gpus-a || $what == gpus-b || $what == gpus-c ]]; then kill $smi; fi
if [[ $what == mesh-rest ]]; then  # issue 27: the trap field's shot to rest on its terrain beside a level plane (float64)
  timeout 320 python3 -m bench.meshes rest --device cuda:0 --n 30000 --repeats 1 2>&1 | quiet | tee "$out/meshes-rest.txt"
fi
