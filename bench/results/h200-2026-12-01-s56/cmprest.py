"""Per-pellet outputs with the raster walk against the chords' search (grid dropped), on a device:
the bench terrain in sea-level air, followed to its landing or to rest (`until`), float32.

    python cmprest.py N DEVICE UNTIL[,UNTIL]
"""
import sys, tempfile, numpy as np, h5py, tomllib
from pathlib import Path
import bench.meshes as bm
import warp_ricochet as wr
from warp_ricochet import model as M
from warp_ricochet.scene import terrain as T, scene_from_dict

def scene(n, until):
    raw = tomllib.loads((bm.ROOT / "examples" / "paper.toml").read_text())
    raw["shot"]["count"] = n
    raw["numerics"]["precision"] = "float32"
    raw["output"] = {"fields": ["impact", "landing"]}
    raw["surfaces"] = surfaces
    raw["physics"]["until"] = until
    raw["air"] = {}
    return scene_from_dict(raw)

orig = T.place_terrain
def nogrid(scene, index, grid=False):
    out = orig(scene, index, grid)
    return out[:2] + (None,) if grid else out

def run(sc, path, walk):
    T.place_terrain = orig if walk else nogrid
    M._cached_model.cache_clear()
    wr.run(sc, path, device=sys.argv[2], overwrite=True)
    out = {}
    with h5py.File(path) as f:
        f["pellets"].visititems(lambda k, d: out.__setitem__(k, d[()]) if isinstance(d, h5py.Dataset) else None)
    return out

n = int(float(sys.argv[1]))
with tempfile.TemporaryDirectory() as d:
    surfaces = bm.terrain_surfaces(bm.terrain_raster(d))
    for until in sys.argv[3].split(","):
        sc = scene(n, until)
        a = run(sc, Path(d) / "a.h5", True)
        b = run(sc, Path(d) / "b.h5", False)
        bad = [k for k in a if not np.array_equal(a[k], b[k], equal_nan=True)]
        s = a["impact/surface"] if "impact/surface" in a else None
        print(until, "datasets", len(a), "differ:", bad, "| met the terrain first:", None if s is None else float((s.reshape(n, -1)[:, 0] == 0).mean()), flush=True)
        for k in bad[:4]:
            diff = np.nonzero(~((a[k] == b[k]) | (np.isnan(a[k]) & np.isnan(b[k]))))
            print("  ", k, len(np.unique(diff[0])), "pellets differ; e.g.", a[k][diff][:4], b[k][diff][:4])
