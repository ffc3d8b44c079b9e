#!/usr/bin/env bash
# session 51, call 3: S (perf/slim: the recording core's Track and Straight slim) against M (main f0d9cb9)
# at 1e8, alternated; then Nsight Compute source counters of M's core kernel without a hazard and with
# the reach (1e6 pellets), and of S's with the reach: where the watched build's core spends its 28 points
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in M S; do ( inn $t timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-$t.txt ) & done
for t in M S; do ( cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_s$t PYTHONPATH=/tmp/site:$PWD timeout 200 python3 $root/.gpu/b/scmp.py /tmp/$t.npz > $out/scmp-$t.txt 2>&1 ) & done
for c in "to rest, no hazard" "to rest, reach"; do ( inn M timeout 200 python3 -m bench.profile_map --device cuda:0 --n 1e4 --case "$c" > /dev/null ) & done
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
python3 - <<'PY' | tee $out/cmp.txt
import numpy as np
a, b = np.load("/tmp/M.npz"), np.load("/tmp/S.npz")
for k in a.files:
    print(k, "bitwise" if np.array_equal(a[k], b[k], equal_nan=True) else f"{int((a[k] != b[k]).sum())} differ, at most {np.nanmax(np.abs(a[k] - b[k]))}")
PY
for r in 1 2; do for t in M S; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path-1e8.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
prof() { local t=$1 c=$2 name=$3
  inn $t timeout 150 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \
    --section LaunchStats --section Occupancy --import-source yes -o /tmp/rep-$name python3 -m bench.profile_map --device cuda:0 --n 1e6 --case "$c" > $out/ncu-$name.txt 2>&1
  tail -2 $out/ncu-$name.txt
  /usr/local/cuda/bin/ncu -i /tmp/rep-$name.ncu-rep --page source --csv --print-source cuda,sass > /tmp/src-$name.csv 2>&1
  /usr/local/cuda/bin/ncu -i /tmp/rep-$name.ncu-rep --page details > $out/details-$name.txt 2>&1
  xz -6 -c /tmp/src-$name.csv > $out/src-$name.csv.xz
  echo "ncu $name $(( $(date +%s) - start )) s" | tee -a $out/times.txt
}
prof M "to rest, no hazard" none
prof M "to rest, reach" reach
prof S "to rest, reach" slim
cd $out && tar cf ncu.tar src-*.csv.xz details-*.txt ncu-*.txt && rm -f src-*.csv.xz details-*.txt ncu-*.txt && tar czf all.tgz *.txt && rm -f warm-*.txt && ls
