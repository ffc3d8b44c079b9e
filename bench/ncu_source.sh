#!/usr/bin/env bash
# Nsight Compute's source counters of the core kernel in `bench.profile_map`'s scene, written as the
# per-line CSV that `python -m bench.ncu_lines` reads. On the lent GPU:
#   . .gpu/b/env.sh && bash bench/ncu_source.sh OUT [N] [--case "to rest, reach"]
set -eu
out=$1; n=${2:-1e6}; shift; [ $# -gt 0 ] && shift
mkdir -p "$out"
python3 -m bench.profile_map --device cuda:0 --n 1e4 "$@" > /dev/null  # compiles, outside the profile
/usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \
  --import-source yes -o "$out/rep" python3 -m bench.profile_map --device cuda:0 --n "$n" "$@"
/usr/local/cuda/bin/ncu -i "$out/rep.ncu-rep" --page source --csv --print-source cuda,sass > "$out/source.csv"
/usr/local/cuda/bin/ncu -i "$out/rep.ncu-rep" --page details > "$out/details.txt"
python3 -m bench.ncu_lines "$out/source.csv" > "$out/lines.txt"
