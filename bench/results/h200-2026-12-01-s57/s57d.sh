#!/usr/bin/env bash
# session 57, call 4: main H (419d12e) on CUDA: the Warp rule, the meshes' edges and the meshes'
# tests (WARP_RICOCHET_TEST_DEVICES=cuda:0); Nsight Compute source counters of the two-triangle mesh
# of the paper's plane in vacuum (1e7), with the edge search out of line.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
c=mesh; mkdir -p $out/ncu-$c
( inn H timeout 200 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \
  --section LaunchStats --section Occupancy --section SpeedOfLight --import-source yes -o $out/ncu-$c/rep \
  python3 -m bench.mesh_profile --case $c --n 1e7 --repeats 0 | filt | tail -3 > $out/ncu-run.txt ) &
inn H env WARP_RICOCHET_TEST_DEVICES=cuda:0 timeout 330 python3 -m pytest -q -p no:cacheprovider tests/test_warp_rules.py tests/test_path_calls.py tests/test_edges.py tests/test_meshes.py 2>&1 | tail -8 > $out/tests.txt
wait
echo "tests, ncu $(( $(date +%s) - start )) s" | tee $out/times.txt
inn H /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page source --csv --print-source cuda,sass > $out/ncu-$c/source.csv
inn H /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page details > $out/ncu-$c/details.txt
inn H python3 -m bench.ncu_lines $out/ncu-$c/source.csv --top 80 > $out/ncu-$c/lines.txt
rm -f $out/ncu-$c/source.csv $out/ncu-$c/rep.ncu-rep
cat $out/tests.txt
cd $out && tar czf all.tgz *.txt ncu-*/*.txt
