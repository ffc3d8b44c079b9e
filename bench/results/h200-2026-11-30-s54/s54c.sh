#!/usr/bin/env bash
# session 54, call 3: the walk ascending after every block again (W3, the working tree: the contact
# normal's and the air step's candidates from the cells) against main (M), bench.meshes terrain 1e7
# alternated twice; then Nsight Compute's source counters of W3's core kernel over the terrain in
# vacuum and in air (bench.mesh_profile, 1e6 pellets), per line (bench.ncu_lines).
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
nvidia-smi --query-gpu=name,driver_version --format=csv > $out/gpu.txt
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M W3; do
  ( inn $t timeout 250 python3 -m bench.meshes terrain --device cuda:0 --n 1e4 --repeats 1 --cells 64 > $out/warm-$t.txt ) &
done
for c in terrain terrain-air; do
  ( inn W3 timeout 250 python3 -m bench.mesh_profile --case $c --n 1e4 --repeats 1 > $out/warm-prof-$c.txt ) &
done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in M W3; do
  inn $t timeout 60 python3 -m bench.meshes terrain --device cuda:0 --n 1e7 --repeats 3 | filt | grep "vacuum\|air" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/terrain.txt
echo "terrain $(( $(date +%s) - start )) s" | tee -a $out/times.txt
for c in terrain terrain-air; do
  mkdir -p $out/ncu-$c
  inn W3 timeout 150 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \
    --section LaunchStats --section Occupancy --section SpeedOfLight --import-source yes -o $out/ncu-$c/rep \
    python3 -m bench.mesh_profile --case $c --n 1e6 --repeats 0 | filt | tail -5
  inn W3 /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page source --csv --print-source cuda,sass > $out/ncu-$c/source.csv
  inn W3 /usr/local/cuda/bin/ncu -i $out/ncu-$c/rep.ncu-rep --page details > $out/ncu-$c/details.txt
  inn W3 python3 -m bench.ncu_lines $out/ncu-$c/source.csv > $out/ncu-$c/lines.txt
  rm -f $out/ncu-$c/source.csv
  echo "ncu $c $(( $(date +%s) - start )) s" | tee -a $out/times.txt
done
cd $out && tar czf all.tgz *.txt ncu-*/*.txt
