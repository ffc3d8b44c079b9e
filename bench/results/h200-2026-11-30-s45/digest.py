"""Digests of runs to rest (per-pellet rest, reach, maps) for a bitwise comparison of two trees."""
import hashlib, sys, tempfile, os
sys.path.insert(0, os.getcwd())
import h5py, numpy as np
import warp_ricochet as wr
from bench.air import paper_scene
from bench.path import BASE, HAZARD, MAP
from bench.rest import CASES as REST
cases = {
    "path-map-f32": paper_scene(3000, air=True, mu_s=0.5, fields=("hazard", "rest"), extra=[*BASE, *HAZARD, *MAP]),
    "path-map-f64": paper_scene(1500, "float64", air=True, mu_s=0.5, fields=("hazard", "rest"), extra=[*BASE, *HAZARD, *MAP]),
}
for label, air, until, extra in REST:
    if until == "rest":
        cases[label] = paper_scene(2000, air=air, mu_s=0.5, fields=("rest",), extra=['physics.until="rest"', *extra])
cases["soil-f64"] = paper_scene(1000, "float64", air=True, mu_s=0.5, fields=("rest",), extra=['physics.until="rest"', 'surfaces.0.material="packed_soil"'])
d = tempfile.mkdtemp()
for name, scene in cases.items():
    path = os.path.join(d, name + ".h5")
    wr.run(scene, path, device="cpu", overwrite=True)
    h = hashlib.sha256()
    with h5py.File(path, "r") as f:
        def visit(n, o):
            if isinstance(o, h5py.Dataset) and ("pellets" in n or "map" in n or "danger" in n):
                h.update(n.encode()); h.update(np.ascontiguousarray(o[()]).tobytes())
        f.visititems(visit)
    print(f"{name:32s} {h.hexdigest()[:16]}", flush=True)
