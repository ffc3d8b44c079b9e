"""Per-pellet outputs with the raster walk against the chords' search (grid dropped)."""
import sys, tempfile, numpy as np, h5py, tomllib
from pathlib import Path
import bench.meshes as bm
import warp_ricochet as wr
from warp_ricochet import model as M
from warp_ricochet.scene import terrain as T, scene_from_dict

def scene(n, precision, air, surfaces, bounces=1, until="landing"):
    raw = tomllib.loads((bm.ROOT / "examples" / "paper.toml").read_text())
    raw["shot"]["count"] = n
    raw["numerics"]["precision"] = precision
    raw["output"] = {"fields": ["impact", "landing"]}
    raw["surfaces"] = surfaces
    raw["physics"]["until"] = until
    raw["physics"]["bounces"] = bounces
    if air: raw["air"] = {}
    return scene_from_dict(raw)

orig = T.place_terrain
def nogrid(scene, index, grid=False):
    out = orig(scene, index, grid)
    return out[:2] + (None,) if grid else out

def run(sc, path, walk):
    T.place_terrain = orig if walk else nogrid
    M._cached_model.cache_clear()
    wr.run(sc, path, device=sys.argv[2] if len(sys.argv) > 2 else "cpu", overwrite=True)
    out = {}
    with h5py.File(path) as f:
        f["pellets"].visititems(lambda k, d: out.__setitem__(k, d[()]) if isinstance(d, h5py.Dataset) else None)
    return out

n = int(float(sys.argv[1]))
with tempfile.TemporaryDirectory() as d:
    raster = bm.terrain_raster(d)
    for precision in (sys.argv[3].split(",") if len(sys.argv) > 3 else ("float32", "float64")):
        for air in (False, True):
            for bounces in ((1,) if len(sys.argv) > 3 else (1, 3)):
                sc = scene(n, precision, air, bm.terrain_surfaces(raster), bounces)
                a = run(sc, Path(d) / "a.h5", True)
                b = run(sc, Path(d) / "b.h5", False)
                bad = [k for k in a if not np.array_equal(a[k], b[k], equal_nan=True)]
                print(precision, "air" if air else "vacuum", "bounces", bounces, "datasets", len(a), "differ:", bad, flush=True)
                for k in bad[:3]:
                    diff = np.nonzero(~((a[k] == b[k]) | (np.isnan(a[k]) & np.isnan(b[k]))))
                    print("  ", k, len(np.unique(diff[0])), "pellets differ; e.g.", a[k][diff][:4], b[k][diff][:4])
