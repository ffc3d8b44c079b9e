"""CPU seconds of the post scene and turf alone (`bench.meshes.hazard_shot`), best of 2; run from a tree's root:
PYTHONPATH=. python bench/results/h200-2026-11-29-s41/cpupost.py . 1e4"""

import sys
import time

import warp_ricochet as wr
from bench.meshes import hazard_shot
from warp_ricochet.scene import scene_from_dict

n = int(float(sys.argv[2]))
for label, post in (("turf", False), ("post", True)):
    wr.run(scene_from_dict(hazard_shot(280, post)), None, device="cpu")  # compiles
    best = 1e9
    for _ in range(2):
        start = time.process_time()
        stats = wr.run(scene_from_dict(hazard_shot(n, post)), None, device="cpu")
        best = min(best, time.process_time() - start)
    print(f"{sys.argv[1]} {label}: {best:.2f} CPU s, {stats['rest_steps_mean']:.2f} steps, rest mean {stats['rest_distance_mean']:.4f} m")
