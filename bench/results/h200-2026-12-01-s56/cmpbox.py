"""Per-pellet outputs of one tree (on PYTHONPATH) on a device, the closed box over a plane and the
two-triangle mesh of the paper's plane (float32, vacuum, 3 bounces), or two trees' compared:

    python cmpbox.py run N DIR NAME DEVICE        python cmpbox.py compare DIR A B
"""
import sys, tempfile, tomllib
from pathlib import Path
import numpy as np


def scene(n, surfaces):
    import bench.meshes as bm
    from warp_ricochet.scene import scene_from_dict
    raw = tomllib.loads((bm.ROOT / "examples" / "paper.toml").read_text())
    raw["shot"]["count"] = n
    raw["numerics"]["precision"] = "float32"
    raw["output"] = {"fields": ["impact", "landing"]}
    raw["surfaces"] = surfaces
    raw["physics"]["until"] = "landing"
    raw["physics"]["bounces"] = 3
    return scene_from_dict(raw)

def outputs(sc, path, device):
    import h5py
    import warp_ricochet as wr
    wr.run(sc, path, device=device, overwrite=True)
    out = {}
    with h5py.File(path) as f:
        f["pellets"].visititems(lambda k, d: out.__setitem__(k, d[()]) if isinstance(d, h5py.Dataset) else None)
    return out

def compare(folder, a, b):
    for path in sorted(Path(folder).glob(f"{a}-*.npz")):
        key = path.name[len(a) + 1:-4]
        x, y = np.load(path), np.load(Path(folder) / f"{b}-{key}.npz")
        bad = [k for k in x.files if not np.array_equal(x[k], y[k], equal_nan=True)]
        print(key, "datasets", len(x.files), "differ:", bad)
        for k in bad[:4]:
            diff = np.nonzero(~((x[k] == y[k]) | (np.isnan(x[k]) & np.isnan(y[k]))))
            print("  ", k, len(np.unique(diff[0])), "pellets differ; e.g.", x[k][diff][:3], y[k][diff][:3])

if sys.argv[1] == "run":
    import bench.meshes as bm
    n, folder, name, device = int(float(sys.argv[2])), sys.argv[3], sys.argv[4], sys.argv[5]
    with tempfile.TemporaryDirectory() as d:
        bm.plane_mesh(d)
        plane = [{"kind": "mesh", "file": str(Path(d) / "plane.stl"), **tomllib.loads((bm.ROOT / "examples" / "paper.toml").read_text())["surfaces"][0]}]
        plane[0].pop("point", None); plane[0].pop("normal", None)
        box = [{"kind": "box", **bm.BOX, **bm.MATERIAL}, {"point": [0.0, -5.0, 0.0], "normal": [0.0, 1.0, 0.0], **bm.MATERIAL}]
        for label, surfaces in (("box", box), ("plane-mesh", plane)):
            out = outputs(scene(n, surfaces), Path(d) / "a.h5", device)
            np.savez(Path(folder) / f"{name}-{label}.npz", **{k.replace('/', '.'): v for k, v in out.items()})
            print(label, "done", flush=True)
else:
    compare(*sys.argv[2:5])
