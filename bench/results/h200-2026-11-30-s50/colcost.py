"""Session 50: a run to rest with pair collisions (shots of 200), the reach and the map, statistics only:
seconds of the second of two runs, on one device (the tree on PYTHONPATH)."""
import sys, time, tempfile
from pathlib import Path
from bench.air import paper_scene
from bench.path import BASE, HAZARD, MAP
import warp_ricochet as wr
import warp as wp
shots, dev = int(sys.argv[1]), sys.argv[2]
for name, extra in (("no hazard", BASE), ("reach", (*BASE, *HAZARD)), ("map", (*BASE, *HAZARD, *MAP))):
    scene = paper_scene(200, air=True, mu_s=0.5, fields=(), extra=[*extra, "collisions.enabled=true", f"shot.shots={shots}"])
    p = Path(tempfile.mkdtemp()) / "c.h5"
    wr.run(scene, p, device=dev, overwrite=True)
    wp.synchronize()
    t = time.perf_counter()
    wr.run(scene, p, device=dev, overwrite=True)
    wp.synchronize()
    print(f"collisions, {name:10s} {shots * 200:.0e} pellets: {time.perf_counter() - t:.3f} s", flush=True)
