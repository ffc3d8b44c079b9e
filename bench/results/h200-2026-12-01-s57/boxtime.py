"""Statistics-only run time of the paper's shot on its plane with bench.meshes' box on it (the
kernel_size case "box": 12 triangles with convex edges and corners; the shot mostly passes it),
beside the plane alone: python boxtime.py N DEVICE (medians of 5 after a warm-up)."""
import sys, time, tomllib
import numpy as np
import warp_ricochet as wr
from bench.meshes import BOX, MATERIAL, ROOT, _paper

n, device = int(float(sys.argv[1])), sys.argv[2]
plane = tomllib.loads((ROOT / "examples" / "paper.toml").read_text())["surfaces"]
for label, surfaces in (("plane", plane), ("box", plane + [{"kind": "box", **BOX, **MATERIAL}])):
    scene = _paper(n, "float32", False, surfaces)
    wr.run(scene, None, device=device)
    runs = []
    for _ in range(5):
        start = time.perf_counter()
        stats = wr.run(scene, None, device=device)
        runs.append(time.perf_counter() - start)
    t = float(np.median(runs))
    print(f"{label}: {n / t:.3g} pellets/s ({t * 1e3:.1f} ms), {stats['hits'] / n:.3f} hit")
