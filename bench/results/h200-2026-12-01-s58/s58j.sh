#!/usr/bin/env bash
# session 58, call 10: tests/test_flat_mesh.py on CUDA (the flat search against the triangles one by
# one, kernels and runs), with tests/test_warp_rules.py and tests/test_path_calls.py, limited to CUDA.
set -u
out=${OUT:-/tmp/out}; mkdir -p $out
root=$PWD
inn() { local t=$1; shift; (cd $root/.gpu/b/exp/$t && WARP_CACHE_PATH=/tmp/wc_$t PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 "$@") 2>&1; }
rm -rf $root/.gpu/b/exp; mkdir -p $root/.gpu/b/exp && tar xJf $root/.gpu/b/exp.tar.xz -C $root/.gpu/b/exp
inn K env WARP_RICOCHET_TEST_DEVICES=cuda:0 timeout 400 python3 -m pytest -q -p no:cacheprovider -rs tests/test_flat_mesh.py tests/test_warp_rules.py tests/test_path_calls.py 2>&1 | tail -12 | tee $out/tests.txt
