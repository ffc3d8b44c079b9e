"""Prints the per-pellet outcomes of the pellets-starting-on-a-plane test scene (tests/test_pipeline.py)
on a device, beside the NumPy reference: for chasing CPU/GPU differences at knife edges."""
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from helpers import explicit_scene  # noqa: E402
from test_pipeline import TWO_FLOORS, read_pellets  # noqa: E402

import warp_ricochet as wr  # noqa: E402
from warp_ricochet import reference  # noqa: E402

R = 0.00125
position = np.array([[0.0, R, 0.0], [0.0, 0.0005, 0.0], [0.0, 0.001, 0.0], [0.0, R, 0.0]])
velocity = np.array([[1.0, 0.0, 0.0], [1.0, 0.1, 0.0], [1.0, 1.0, 0.0], [1.0, -2.0, 0.0]])
device = sys.argv[1] if len(sys.argv) > 1 else "cuda:0"
for precision in ("float64", "float32"):
    tmp = Path(tempfile.mkdtemp())
    scene = explicit_scene(tmp, position, velocity, surfaces=TWO_FLOORS, precision=precision, physics={"bounces": 2})
    wr.run(scene, tmp / "o.h5", device=device)
    p = read_pellets(tmp / "o.h5")
    ref, _ = reference.simulate(scene, position, velocity, np.zeros((4, 3)))
    np.set_printoptions(precision=17)
    for name in ("impact.surface", "impact.time", "impact.velocity_before", "landing.surface", "landing.time"):
        print(precision, name, "warp:", p[name].tolist(), "\n   ref:", ref[name].tolist())
