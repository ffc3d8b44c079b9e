"""Per-pellet outputs of one tree (on PYTHONPATH) on a device for the scenes the air's root finding
and a small mesh's edge search reach (landing and rest kernels), or two trees' compared:

    python cmpgpu.py run N DIR NAME DEVICE [CASES]     python cmpgpu.py compare DIR A B
"""
import sys, tempfile, tomllib
from pathlib import Path
import numpy as np

ROOT = None

def paper(n, surfaces, air, until, bounces, precision="float32"):
    import bench.meshes as bm
    from warp_ricochet.scene import scene_from_dict
    raw = tomllib.loads((bm.ROOT / "examples" / "paper.toml").read_text())
    raw["shot"]["count"] = n
    raw["numerics"]["precision"] = precision
    raw["output"] = {"fields": ["impact", "landing"] + (["rest"] if until == "rest" else [])}
    raw["surfaces"] = surfaces
    raw["physics"]["until"] = until
    raw["physics"]["bounces"] = bounces
    if air:
        raw["air"] = {}
    return scene_from_dict(raw)

def trap(n):
    import bench.meshes as bm
    sys.path.insert(0, str(bm.ROOT / "examples"))
    from trap_field_study import scene as trap_scene
    from warp_ricochet.scene import scene_from_dict
    base = trap_scene(max(1, n // 300), (5.0, 15.0)).to_dict()
    base["physics"] = {**base["physics"], "until": "rest"}
    base["output"] = {"fields": ["impact", "rest"]}
    return scene_from_dict(base)

def outputs(sc, path, device):
    import h5py
    import warp_ricochet as wr
    wr.run(sc, path, device=device, overwrite=True)
    out = {}
    with h5py.File(path) as f:
        f["pellets"].visititems(lambda k, d: out.__setitem__(k, d[()]) if isinstance(d, h5py.Dataset) else None)
    return out

def cases(n, d):
    import bench.meshes as bm
    bm.plane_mesh(d)
    target = tomllib.loads((bm.ROOT / "examples" / "paper.toml").read_text())["surfaces"][0]
    mesh = {"kind": "mesh", "file": str(Path(d) / "plane.stl"), **target}
    mesh.pop("point"); mesh.pop("normal")
    turf = {"name": "turf", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "turf"}
    mesh_turf = {"kind": "mesh", "file": str(Path(d) / "plane.stl"), "name": "turf mesh", "material": "turf"}
    box = {"kind": "box", **bm.BOX, "material": "steel_plate"}
    box_low = {**box, "point": [0.7, 0.35, 0.0], "normal": [0.1, 1.0, 0.05], "axis_u": [1.0, -0.1, 0.0], "size": [0.4, 0.4, 0.3]}
    terrain = bm.terrain_surfaces(bm.terrain_raster(d))
    return {
        "terrain-air": lambda: paper(n, terrain, True, "landing", 1),
        "terrain-air-3": lambda: paper(n, terrain, True, "landing", 3),
        "mesh-air-3": lambda: paper(n, [mesh], True, "landing", 3),
        "mesh-vac-3": lambda: paper(n, [mesh], False, "landing", 3),
        "box-vac-3": lambda: paper(n, [box_low, turf], False, "landing", 3),
        "terrain-vac-3": lambda: paper(n, terrain, False, "landing", 3),
        "paper-air": lambda: paper(n, [target], True, "landing", 1),
        "paper-air-64": lambda: paper(n, [target], True, "landing", 1, "float64"),
        "turf-rest-air": lambda: paper(n // 10, [turf], True, "rest", 1),
        "mesh-rest-air": lambda: paper(n // 10, [mesh_turf], True, "rest", 1),
        "mesh-rest-vac": lambda: paper(n // 10, [mesh_turf], False, "rest", 1),
        "box-rest-air": lambda: paper(n // 10, [box_low, turf], True, "rest", 1),
        "box-rest-vac": lambda: paper(n // 10, [box_low, turf], False, "rest", 1),
        "trap-rest": lambda: trap(n // 10),
    }

if sys.argv[1] == "run":
    n, folder, name, device = int(float(sys.argv[2])), sys.argv[3], sys.argv[4], sys.argv[5]
    with tempfile.TemporaryDirectory() as d:
        table = cases(n, d)
        wanted = sys.argv[6].split(",") if len(sys.argv) > 6 else list(table)
        for label in wanted:
            out = outputs(table[label](), Path(d) / "a.h5", device)
            np.savez(Path(folder) / f"{name}-{label}.npz", **{k.replace('/', '.'): v for k, v in out.items()})
            print(label, "done", {k: v.shape for k, v in list(out.items())[:2]}, flush=True)
else:
    a, b = sys.argv[3], sys.argv[4]
    for path in sorted(Path(sys.argv[2]).glob(f"{a}-*.npz")):
        key = path.name[len(a) + 1:-4]
        other = Path(sys.argv[2]) / f"{b}-{key}.npz"
        if not other.exists():
            print(key, "missing in", b); continue
        x, y = np.load(path), np.load(other)
        bad = [k for k in x.files if not np.array_equal(x[k], y[k], equal_nan=True)]
        print(key, "datasets", len(x.files), "differ:", bad)
        for k in bad[:4]:
            diff = np.nonzero(~((x[k] == y[k]) | (np.isnan(x[k]) & np.isnan(y[k]))))
            print("  ", k, len(np.unique(diff[0])), "pellets differ; e.g.", x[k][diff][:3], y[k][diff][:3])
