set -u
out=${OUT:-/tmp/out}; mkdir -p $out; root=$PWD
cd .gpu/b/exp/V && WARP_RICOCHET_TEST_DEVICES=cuda:0 WARP_CACHE_PATH=/tmp/wc_T PYTHONPATH=/tmp/site:$root/.gpu/t/site:$PWD timeout 170 python3 -m pytest -q -x -p no:cacheprovider tests/test_lanes.py tests/test_path_watch.py 2>&1 | tail -6 | tee $out/cuda-tests.txt
