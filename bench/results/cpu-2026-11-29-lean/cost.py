"""The cost of the leaning side's code in a post scene (CPU): 20,000 pellets dropped onto a vertical
concrete post over turf, float64, to rest; four runs in one process (the first compiles the kernel).
Run from a tree's root: WARP_CACHE_PATH=<fresh> PYTHONPATH=. python bench/results/cpu-2026-11-29-lean/cost.py"""

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, "tests")
from helpers import explicit_scene  # noqa: E402

import warp_ricochet as wr  # noqa: E402
from warp_ricochet.scene import scene_from_dict  # noqa: E402

POST = {"kind": "cylinder", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "radius": 0.06, "length": 1.2}
POST["material"] = "concrete"
GROUND = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "turf"}
rng = np.random.default_rng(0)
n = 20000
x0 = np.c_[rng.uniform(-0.1, 0.1, n), rng.uniform(1.3, 1.6, n), rng.uniform(-0.1, 0.1, n)]
v0 = np.c_[rng.normal(0, 1, n), -rng.uniform(0, 3, n), rng.normal(0, 1, n)]
folder = Path(tempfile.mkdtemp())
physics = {"gravity": [0.0, -9.81, 0.0], "until": "rest"}
scene = explicit_scene(folder, x0, v0, surfaces=[POST, GROUND], physics=physics, precision="float64")
raw = {**scene.to_dict(), "output": {"fields": ["rest"]}}
seconds = []
for _ in range(4):
    t0 = time.time()
    wr.run(scene_from_dict(raw), folder / "o.h5", device="cpu", overwrite=True)
    seconds.append(round(time.time() - t0, 2))
print(seconds)
