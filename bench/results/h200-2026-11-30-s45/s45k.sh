set -u
out=${OUT:-/tmp/out}; mkdir -p $out; root=$PWD
for t in V N; do
(cd .gpu/b/exp/$t && WARP_RICOCHET_TEST_DEVICES=cuda:0 WARP_CACHE_PATH=/tmp/wc_T$t PYTHONPATH=/tmp/site:$root/.gpu/t/site:$PWD timeout 80 python3 -m pytest -q -p no:cacheprovider tests/test_lanes.py tests/test_path_watch.py 2>&1 | grep -v "^  \|^$" | grep "Error\|assert\|Mismatch\|Max\|passed\|failed\|FAILED\|differ" | head -30 | sed "s/^/$t: /" | tee -a $out/cuda-tests.txt)
done
