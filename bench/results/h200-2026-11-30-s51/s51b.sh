#!/usr/bin/env bash
# session 51, call 2: the replay kernel's occupancy. Caps on registers a thread and the replay's block
# size (warps an SM: 255 regs x 256 = 8; A 168 x 128 = 12; B 128 x 256 = 16; C 80 x 128 = 24; D 64 x 256 = 32)
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD "$@") 2>&1; }
filt() { grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{\|/tmp/wc_\|PrecisionWarning\|return _compute\|warnings.warn"; }
start=$(date +%s)
mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
for v in A:168:128 B:128:256 C:80:128 D:64:256; do
  IFS=: read n cap bd <<< "$v"
  rm -rf $root/.gpu/b/exp/$n; cp -r $root/.gpu/b/exp/M $root/.gpu/b/exp/$n
  python3 - $root/.gpu/b/exp/$n $cap $bd <<'PY'
import sys
p = f"{sys.argv[1]}/warp_ricochet/core/replay.py"
s = open(p).read()
a = '    options.pop("cuda_max_registers", None)\n'
b = "replay_kernel_for(self.spec), dim=rows,"
assert s.count(a) == 1 and s.count(b) == 1
s = s.replace(a, f'    options["cuda_max_registers"] = {sys.argv[2]}\n').replace(b, b + f" block_dim={sys.argv[3]},")
open(p, "w").write(s)
PY
done
for t in M A B C D; do ( inn $t timeout 200 python3 -m bench.path cost --device cuda:0 --sizes 1e5 --repeats 1 > $out/warm-$t.txt ) & done
( cd $root/.gpu/b/exp/B && WARP_CACHE_PATH=/tmp/wc_sB PYTHONPATH=/tmp/site:$PWD timeout 200 python3 $root/.gpu/b/scmp.py /tmp/B.npz > $out/scmp-B.txt 2>&1 ) &
( cd $root/.gpu/b/exp/M && WARP_CACHE_PATH=/tmp/wc_sM PYTHONPATH=/tmp/site:$PWD timeout 200 python3 $root/.gpu/b/scmp.py /tmp/M.npz > $out/scmp-M.txt 2>&1 ) &
wait
echo "warm-up $(( $(date +%s) - start )) s" | tee $out/times.txt
python3 - <<'PY' | tee $out/cmp.txt
import numpy as np
a, b = np.load("/tmp/M.npz"), np.load("/tmp/B.npz")
for k in a.files:
    print(k, "bitwise" if np.array_equal(a[k], b[k], equal_nan=True) else f"{int((a[k] != b[k]).sum())} differ")
PY
for r in 1 2; do for t in M A B C D; do
  inn $t timeout 60 python3 -m bench.path cost --device cuda:0 --sizes 1e8 --repeats 1 | filt | grep "N 1e" | sed "s/^/$r $t: /"
done; done 2>&1 | tee $out/path-1e8.txt
echo "done $(( $(date +%s) - start )) s" | tee -a $out/times.txt
cd $out && tar czf all.tgz *.txt && rm warm-*.txt && ls
