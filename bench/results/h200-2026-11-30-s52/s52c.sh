#!/usr/bin/env bash
# session 52, call 3: W = main 4fea75b (perf/walk merged) against U = perf/unroll (the stretch's two loops
# over thresholds unrolled: lo, hi and the thresholds in registers; bitwise on the CPU): scmp bits,
# bench.path cost 1e8 alternated twice, ktime, U at 1e9, Nsight source counters of U's reach replay
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for t in W U; do ( inn $t timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > /dev/null ) & done
for t in W U; do ( cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_s$t PYTHONPATH=/tmp/site:$PWD timeout 200 python3 $root/.gpu/b/scmp.py /tmp/$t.npz > $out/scmp-$t.txt 2>&1 ) & done
( inn U timeout 200 python3 -m bench.profile_map --device cuda:0 --n 1e4 --case "to rest, reach" > /dev/null ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
python3 - <<'PY' | tee $out/cmp.txt
import numpy as np
a, b = np.load("/tmp/W.npz"), np.load("/tmp/U.npz")
for k in a.files:
    same = np.array_equal(a[k], b[k], equal_nan=True)
    print("U", k, "bitwise" if same else f"{int((a[k] != b[k]).sum())} differ, at most {np.nanmax(np.abs(a[k] - b[k]))}")
PY
for r in 1 2; do for t in W U; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path-1e8.txt
for t in W U; do inn $t timeout 100 python3 $root/.gpu/b/ktime.py 1e8 | filt | grep -v " 0.00[01] s" | sed "s/^/$t /"; done 2>&1 | tee $out/ktime.txt
echo "timed $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn U timeout 150 python3 -m bench.path cost --device cuda:0 --sizes 1e9 --repeats 1 | filt | grep "N 1e" | tee $out/path-1e9.txt
echo "1e9 $(( $(date +%s) - start )) s" | tee -a $out/times.txt
inn U timeout 150 /usr/local/cuda/bin/ncu -k regex:replay_kernel -c 1 --section WarpStateStats --section SourceCounters \
  --import-source yes -o /tmp/rep-u python3 -m bench.profile_map --device cuda:0 --n 1e6 --case "to rest, reach" > /dev/null 2>&1
/usr/local/cuda/bin/ncu -i /tmp/rep-u.ncu-rep --page source --csv --print-source cuda,sass > /tmp/src-u.csv 2>&1
inn U python3 -m bench.ncu_lines /tmp/src-u.csv --top 40 > $out/lines-rreach-U.txt 2>&1
/usr/local/cuda/bin/ncu -i /tmp/rep-u.ncu-rep --page details | grep -A8 "Warp State Statistics" > $out/details-rreach-U.txt 2>&1
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt && ls
