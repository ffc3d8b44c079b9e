"""On CUDA: the post scene's (`bench.meshes.hazard_shot`) run times and its core kernel's (registers, local bytes)
(`bench.mesh_profile._attributes`); run from a tree's root: python .../regs.py 1e6"""

import sys
import time

import warp_ricochet as wr
from bench.mesh_profile import _attributes
from bench.meshes import hazard_shot
from warp_ricochet.scene import scene_from_dict

scene = scene_from_dict(hazard_shot(int(float(sys.argv[1])), True))
wr.run(scene, None, device="cuda:0")
runs = []
for _ in range(3):
    start = time.perf_counter()
    stats = wr.run(scene, None, device="cuda:0")
    runs.append(time.perf_counter() - start)
print(f"post: runs {[round(x * 1e3) for x in runs]} ms, {stats['rest_steps_mean']:.2f} steps; (registers, local bytes) {_attributes(scene)}")
