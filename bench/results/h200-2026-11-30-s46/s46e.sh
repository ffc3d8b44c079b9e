#!/usr/bin/env bash
# session 46, call 5: R (main + perf/reachends), S2 (R + a line phase's steps walked as one chord, the reach
# alone as before), H3 (S2, no surface step watched: a hack, the bound of what the steps' watch costs).
# bench.path cost 1e7 alternated twice; Nsight source counters of S2's map case (1e6), tarred.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
for t in R S2 H3; do
  ( inn $t timeout 150 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-path-$t.txt ) &
done
( cd .gpu/b/exp/S2 && WARP_CACHE_PATH=/tmp/wc_S2p PYTHONPATH=/tmp/site:$PWD timeout 150 python3 -m bench.profile_map --device cuda:0 --n 1e4 > /dev/null 2>&1 ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for r in 1 2; do for t in H3 S2 R; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e7 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path.txt
echo "path 1e7 $(( $(date +%s) - start )) s" | tee -a $out/times.txt
( cd .gpu/b/exp/S2 && WARP_CACHE_PATH=/tmp/wc_S2p timeout 200 bash bench/ncu_source.sh /tmp/ncuS2 1e6 > /tmp/ncuS2.log 2>&1 ); rm -f /tmp/ncuS2/rep.ncu-rep
tail -n 5 /tmp/ncuS2.log; head -n 45 /tmp/ncuS2/lines.txt
(cd /tmp && tar czf $out/ncu-S2-map.tgz ncuS2 ncuS2.log)
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
