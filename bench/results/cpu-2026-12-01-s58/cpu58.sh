set -u
for r in 1 2; do for t in H F6; do
  d=/tmp/treeH; [ $t = F6 ] && d=/tmp/treeF6w
  (cd $d && WARP_CACHE_PATH=/tmp/wc_cpu_$t PYTHONPATH=$d /work/main/.venv/bin/python -m bench.meshes plane --n 1e6 --device cpu --repeats 3 --flights vacuum,air 2>&1 | grep "pellets/s\|plane time" | sed "s/^/$r $t: /")
done; done
