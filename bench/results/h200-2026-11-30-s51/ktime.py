"""Session 51: each kernel's GPU time (Warp's activity timing, CUDA events) in bench.path cost's cases."""
import sys, time, collections
import warp as wp
import warp_ricochet as wr
from bench.air import paper_scene
from bench.path import BASE, CASES
n = int(float(sys.argv[1]))
for label, extra in CASES:
    settings = [*BASE, *extra]
    wr.run(paper_scene(1000, air=True, mu_s=0.5, extra=settings), device="cuda:0")
    scene = paper_scene(n, air=True, mu_s=0.5, extra=settings)
    wp.synchronize_device("cuda:0")
    wp.timing_begin(cuda_filter=wp.TIMING_KERNEL)
    t0 = time.perf_counter()
    wr.run(scene, device="cuda:0"); wp.synchronize_device("cuda:0")
    wall = time.perf_counter() - t0
    res = wp.timing_end()
    by = collections.defaultdict(lambda: [0.0, 0])
    for r in res:
        name = r.name.split("_locals__")[-1][:60] if "_locals__" in r.name else r.name[:60]
        by[name][0] += r.elapsed; by[name][1] += 1
    tot = sum(v[0] for v in by.values())
    print(f"{label}: wall {wall:.3f} s, kernels {tot/1e3:.3f} s")
    for k, (ms, c) in sorted(by.items(), key=lambda kv: -kv[1][0])[:12]:
        print(f"   {ms/1e3:8.3f} s  {c:5d} launches  {k}")
