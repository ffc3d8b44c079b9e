#!/usr/bin/env bash
# session 52, call 5: main c11a32e (walk, unroll, levels, empty log): gpucheck chunks (examples/hazard.toml:
# chunks of 2 and 5 segments, Ctrl-C and --resume), and where the reach's wall time goes besides kernels (ktime2.py)
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
start=$(date +%s)
( WARP_CACHE_PATH=/tmp/wc_k PYTHONPATH=/tmp/site:$PWD timeout 200 python3 .gpu/b/ktime2.py 1e8 > $out/ktime2.txt 2>&1; echo "rc $?" >> $out/ktime2.txt )
echo "ktime2 $(( $(date +%s) - start )) s" | tee $out/times.txt
( WARP_CACHE_PATH=/tmp/wc_g PYTHONPATH=/tmp/site:$PWD/.gpu/t/site:$PWD timeout 250 python3 .gpu/b/gpucheck.py chunks > $out/chunks.txt 2>&1; echo "rc $?" >> $out/chunks.txt )
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
grep "same bits\|rc " $out/chunks.txt
grep -v "^Warp\|^Module" $out/ktime2.txt | head -120
cd $out && tar czf all.tgz *.txt
