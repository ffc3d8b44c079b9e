import sys, time, json
import warp as wp; wp.config.quiet = True
sys.path.insert(0, sys.argv[1])
sys.path.insert(0, sys.argv[1] + "/bench")
from bench.__main__ import scene_for
import warp_ricochet as wr
assert wr.__file__.startswith(sys.argv[1]), wr.__file__
out = {}
for prec in ("float32", "float64"):
    scene = scene_for(4_000_000, precision=prec)
    wr.run(scene, None, device="cpu")
    ts = []
    for _ in range(5):
        t = time.perf_counter(); wr.run(scene, None, device="cpu"); ts.append(time.perf_counter() - t)
    out[prec] = sorted(ts)
print(json.dumps(out))
