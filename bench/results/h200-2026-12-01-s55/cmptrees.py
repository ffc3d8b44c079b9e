"""Per-pellet outputs of one tree (the one on PYTHONPATH) written to DIR/NAME-*.npz, or two such
folders' outputs compared: the two-triangle mesh of the paper's plane, the bench's terrain (vacuum
and air, 1 and 3 bounces) and the closed box, in float32 and float64.

    python cmptrees.py run N DIR NAME [DEVICE]     python cmptrees.py compare DIR A B
"""
import sys, tempfile, numpy as np, h5py, tomllib
from pathlib import Path

def scene(n, precision, air, surfaces, bounces=1):
    import bench.meshes as bm
    from warp_ricochet.scene import scene_from_dict
    raw = tomllib.loads((bm.ROOT / "examples" / "paper.toml").read_text())
    raw["shot"]["count"] = n
    raw["numerics"]["precision"] = precision
    raw["output"] = {"fields": ["impact", "landing"]}
    raw["surfaces"] = surfaces
    raw["physics"]["until"] = "landing"
    raw["physics"]["bounces"] = bounces
    if air: raw["air"] = {}
    return scene_from_dict(raw)

def outputs(sc, path, device):
    import warp_ricochet as wr
    wr.run(sc, path, device=device, overwrite=True)
    out = {}
    with h5py.File(path) as f:
        f["pellets"].visititems(lambda k, d: out.__setitem__(k, d[()]) if isinstance(d, h5py.Dataset) else None)
    return out

def run(n, folder, name, device):
    import bench.meshes as bm
    import tomllib as _t
    with tempfile.TemporaryDirectory() as d:
        raster = bm.terrain_raster(d)
        bm.plane_mesh(d)
        plane = [{"kind": "mesh", "file": str(Path(d) / "plane.stl"), **_t.loads((bm.ROOT / "examples" / "paper.toml").read_text())["surfaces"][0]}]
        plane[0].pop("point", None); plane[0].pop("normal", None)
        box = [{"kind": "box", **bm.BOX, **bm.MATERIAL}, {"point": [0.0, -5.0, 0.0], "normal": [0.0, 1.0, 0.0], **bm.MATERIAL}]
        for precision in ("float32", "float64"):
            for label, surfaces, airs, bounces in (("plane-mesh", plane, (False, True), (1, 3)), ("terrain", bm.terrain_surfaces(raster), (False, True), (1, 3)), ("box", box, (False,), (3,))):
                for air in airs:
                    for b in bounces:
                        key = f"{label}-{precision}-{'air' if air else 'vacuum'}-{b}"
                        out = outputs(scene(n, precision, air, surfaces, b), Path(d) / "a.h5", device)
                        np.savez(Path(folder) / f"{name}-{key}.npz", **{k.replace('/', '.'): v for k, v in out.items()})
                        print(key, "done", flush=True)

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
    run(int(float(sys.argv[2])), sys.argv[3], sys.argv[4], sys.argv[5] if len(sys.argv) > 5 else "cpu")
else:
    compare(*sys.argv[2:5])
