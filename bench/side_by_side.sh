#!/usr/bin/env bash
# One benchmark command in two source trees, alternating, so a speed change is measured in one
# session on one machine (machines drift by tens of percent from minute to minute).
#   usage: bench/side_by_side.sh OLD_TREE NEW_TREE ROUNDS COMMAND...
#   e.g.   bench/side_by_side.sh /tmp/old . 3 python3 -m bench throughput --device cuda:0 --sizes 1e8
# Each output line is prefixed with the round and the tree ("old"/"new"); a warm-up run of each
# tree (kernel compilation) comes first and is not shown.
set -uo pipefail
old=$(cd "$1" && pwd); new=$(cd "$2" && pwd); rounds=$3; shift 3
run() { local tree=$1; shift; (cd "$tree" && PYTHONPATH="$tree${PYTHONPATH:+:$PYTHONPATH}" "$@") 2>&1; }
for tree in "$old" "$new"; do run "$tree" "$@" > /dev/null; done
for ((i = 1; i <= rounds; i++)); do
  for tag in old new; do
    tree=$([[ $tag == old ]] && echo "$old" || echo "$new")
    run "$tree" "$@" | grep -v "^Warp \|CUDA Toolkit\|Devices:\|Kernel cache\|\.cache/warp\|\"cpu\"\|\"cuda:0\"\|^Module \|^{" | sed "s/^/$i $tag: /"
  done
done
