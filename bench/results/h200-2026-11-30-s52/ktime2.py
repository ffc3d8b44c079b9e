"""Session 52: where a run's wall time goes besides its kernels (bench.path cost's cases at N): every
GPU operation timed (Warp's TIMING_ALL: kernels, copies, memsets), the host's time stamps at each
chunk's launch and wait (no sync added), and a cProfile of one run."""
import sys, time, collections, cProfile, pstats, io
import warp as wp
import warp_ricochet as wr
from warp_ricochet import pipeline
from bench.air import paper_scene
from bench.path import BASE, CASES
n = int(float(sys.argv[1]))
marks = []
T0 = [0.0]
def stamp(label):
    marks.append((time.perf_counter() - T0[0], label))
for cls in (pipeline.CoreStage,):
    f = cls.compute
    def compute(self, start, rows, f=f):
        stamp(f"compute {start} in"); r = f(self, start, rows); stamp(f"compute {start} out"); return r
    cls.compute = compute
g = pipeline.HostSlot.results
def results(self, g=g):
    stamp("results in"); r = g(self); stamp("results out"); return r
pipeline.HostSlot.results = results
for label, extra in CASES[:2]:
    settings = [*BASE, *extra]
    wr.run(paper_scene(1000, air=True, mu_s=0.5, extra=settings), device="cuda:0")
    scene = paper_scene(n, air=True, mu_s=0.5, extra=settings)
    wr.run(scene, device="cuda:0"); wp.synchronize_device("cuda:0")
    marks.clear()
    wp.timing_begin(cuda_filter=wp.TIMING_ALL)
    T0[0] = t0 = time.perf_counter()
    wr.run(scene, device="cuda:0"); wp.synchronize_device("cuda:0")
    wall = time.perf_counter() - t0
    res = wp.timing_end()
    print(f"== {label}: wall {wall:.4f} s, GPU operations {sum(r.elapsed for r in res) / 1e3:.4f} s in {len(res)}")
    for r in res:
        if r.elapsed > 0.05:
            print(f"   {r.elapsed:9.3f} ms  {r.name[:90]}")
    print("   host marks (s from the run's start):", " | ".join(f"{t:.4f} {l}" for t, l in marks))
    pr = cProfile.Profile(); pr.enable()
    wr.run(scene, device="cuda:0"); wp.synchronize_device("cuda:0")
    pr.disable()
    s = io.StringIO(); pstats.Stats(pr, stream=s).sort_stats("tottime").print_stats(25); print(s.getvalue()[-6000:])
