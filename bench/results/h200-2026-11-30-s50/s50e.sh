#!/usr/bin/env bash
# Session 50, call 5: the merged main's replay end to end on examples/hazard.toml (gpucheck.py: chunk
# sizes, Ctrl-C and --resume, every pellet rerun, the watch in the core against the replay), then
# bench.path cost at 1e8 of main M against perf/steps S (a STEP's words read with its tag), alternated.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for w in chunks rerun never; do
  ( WARP_CACHE_PATH=/tmp/wc_$w PYTHONPATH=/tmp/site:$PWD/.gpu/t/site:$PWD timeout 250 python3 .gpu/b/gpucheck.py $w > $out/$w.txt 2>&1; echo "rc $?" >> $out/$w.txt ) &
done
for t in M S; do ( inn $t timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-$t.txt ) & done
wait
echo "checks + warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
for w in chunks rerun never; do grep -v "^Warp\|^Module\|CUDA Toolkit\|Devices\|Kernel cache\|cuda:0\"\|\"cpu\"" $out/$w.txt | grep -v "^always map\|^never map\|hazard_references\|^always place\|^never place" | tail -32; done
for r in 1 2; do for t in M S; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path-1e8.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt && ls
