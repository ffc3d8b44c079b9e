#!/bin/bash
# alternating old/new: core throughput (stats only) and collisions throughput, CPU
PY=/work/main/.venv/bin/python
out=/tmp/alt_bench.txt; : > $out
for tree in /tmp/oldtree /work/main; do  # warm both (compile)
  (cd $tree && PYTHONPATH=$tree $PY -m bench throughput --device cpu --sizes 1e5 --repeats 1 --numpy-max 0 --out /tmp/bwarm >/dev/null 2>&1)
  (cd $tree && PYTHONPATH=$tree $PY -m bench.collisions throughput --device cpu --shots 2 --count 450 --repeats 1 >/dev/null 2>&1)
done
for i in 1 2 3 4 5; do
  for tree in /tmp/oldtree /work/main; do
    tag=$([ $tree = /tmp/oldtree ] && echo old || echo new)
    r=$(cd $tree && PYTHONPATH=$tree $PY -m bench throughput --device cpu --sizes 1e6,1e7 --repeats 3 --numpy-max 0 --out /tmp/bwarm 2>&1 | grep "N=" | tr '\n' ' ')
    echo "$i $tag core: $r" >> $out
    r=$(cd $tree && PYTHONPATH=$tree $PY -m bench.collisions throughput --device cpu --shots 1 --count 450 --repeats 5 2>&1 | grep shots | grep -o "in [0-9.]* s\|[0-9.e+]* pellet-steps/s launched, [0-9.e+]* working")
    echo "$i $tag coll1: $r" >> $out
    r=$(cd $tree && PYTHONPATH=$tree $PY -m bench.collisions throughput --device cpu --shots 10 --count 450 --repeats 3 2>&1 | grep shots | grep -o "in [0-9.]* s\|[0-9.e+]* pellet-steps/s launched, [0-9.e+]* working")
    echo "$i $tag coll10: $r" >> $out
  done
done
echo done >> $out
