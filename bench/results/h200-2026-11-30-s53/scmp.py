"""One tree's outputs on a device saved for a bitwise comparison between trees (session 53):
bench.path's map and rough-ground scenes (hazard and rest fields), and the steel-plate bay, trap
field (terrain) and hazard examples, every dataset of each run file.
    python3 scmp.py OUT.npz DEVICE N [a|b]  (a: bench.path's scenes only, b: the examples only)"""
import sys, tempfile, numpy as np, h5py
from pathlib import Path
from bench.air import paper_scene
from bench.path import LOG_CASES
import warp_ricochet as wr
from warp_ricochet.scene import load_scene
out = {}
n = int(sys.argv[3])
part = sys.argv[4] if len(sys.argv) > 4 else "ab"
def grab(name, p):
    with h5py.File(p) as f:
        def visit(k, obj):
            if isinstance(obj, h5py.Dataset) and obj.dtype.kind in "fiub" and "time" not in k:
                out[f"{name}:{k}"] = obj[()]
        f.visititems(visit)
for case in ("map", "rough, reach") if "a" in part else ():
    settings, _ = LOG_CASES[case]
    p = Path(tempfile.mkdtemp()) / "x.h5"
    wr.run(paper_scene(n, air=True, mu_s=0.5, fields=("hazard", "rest"), extra=list(settings)), p, device=sys.argv[2], overwrite=True)
    grab(case, p)
for ex in ("steel_plate_bay", "trap_field", "hazard", "steel_plate_air") if "b" in part else ():
    p = Path(tempfile.mkdtemp()) / "x.h5"
    scene = load_scene(Path("examples") / f"{ex}.toml", ["shot.count=2000"] if ex == "steel_plate_air" else [])
    wr.run(scene, p, device=sys.argv[2], overwrite=True)
    grab(ex, p)
np.savez(sys.argv[1], **out)
print("saved", len(out), "datasets")
