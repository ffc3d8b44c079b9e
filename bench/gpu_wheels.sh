#!/usr/bin/env bash
# The packages the lent GPU machine lacks (it has numpy, h5py, matplotlib, rich, tqdm, typer and no
# registry), downloaded here as wheels into .whl/ (ignored: `echo /.whl/ >> .git/info/exclude`):
# rasterio (terrain), trimesh (meshes), distributed (Dask studies), at this venv's versions; `dask`:
# only the Dask stack and dask-cuda (LocalCUDACluster: one worker a GPU, with its CUDA 12 bindings).
#   bash bench/gpu_wheels.sh [all|dask]  # here, once (41 MB / 22 MB: carry it alone, not with .gpu/b)
# then on the machine, after stage1/stage2, in a call carrying [".whl"] (which removes .gpu/b there):
#   test -s /tmp/site/warp/bin/warp.so && export PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 &&
#   python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
set -euo pipefail
cd "$(dirname "$0")/.."
pip=.venv/bin/pip
names="distributed dask cloudpickle jinja2 click markupsafe locket msgpack packaging psutil pyyaml sortedcontainers tblib
  toolz tornado zict fsspec partd"
[[ ${1:-all} == dask ]] || names="$names rasterio affine attrs certifi cligj click-plugins pyparsing trimesh"
pins=""
[[ ${1:-all} == dask ]] && pins="dask-cuda nvidia-ml-py cuda-core cuda-bindings<13 cuda-pathfinder"
for name in $names; do
  version=$($pip show "$name" 2>/dev/null | awk '/^Version/{print $2}')
  pins="$pins $name${version:+==$version}"
done
rm -rf .whl && mkdir -p .whl
python3 -m pip download --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
  --platform manylinux2014_x86_64 --platform manylinux_2_5_x86_64 --platform manylinux1_x86_64 -d .whl $pins -q
ls .whl | wc -l
du -sh .whl
