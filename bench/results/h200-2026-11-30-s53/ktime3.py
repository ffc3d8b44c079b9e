"""Session 53: GPU time per kernel (summed over chunks) of bench.path cost's cases at N (Warp's timing)."""
import sys, collections, re
import warp as wp
import warp_ricochet as wr
from bench.air import paper_scene
from bench.path import BASE, CASES
n = int(float(sys.argv[1]))
for label, extra in CASES:
    settings = [*BASE, *extra]
    scene = paper_scene(n, air=True, mu_s=0.5, extra=settings)
    wr.run(paper_scene(1000, air=True, mu_s=0.5, extra=settings), device="cuda:0")
    wr.run(scene, device="cuda:0"); wp.synchronize_device("cuda:0")
    wp.timing_begin(cuda_filter=wp.TIMING_KERNEL)
    wr.run(scene, device="cuda:0"); wp.synchronize_device("cuda:0")
    res = wp.timing_end()
    by = collections.defaultdict(float)
    for r in res:
        by[re.sub(r"_[0-9a-f]{6,}", "", r.name)[:70]] += r.elapsed
    print(f"== {label}: kernels {sum(r.elapsed for r in res) / 1e3:.4f} s")
    for k, v in sorted(by.items(), key=lambda kv: -kv[1])[:6]:
        print(f"   {v / 1e3:8.4f} s  {k}")
