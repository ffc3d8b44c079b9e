import sys, tempfile, numpy as np, h5py
from pathlib import Path
from bench.air import paper_scene
from bench.path import BASE, HAZARD, MAP, _differences, LOG_KEYS
import warp_ricochet as wr
from warp_ricochet.tallies import path_replay
import os
if os.environ.get("SPILL"): path_replay.COLUMN_WORDS = int(os.environ["SPILL"])
cases = {"reach": (*BASE, *HAZARD), "map": (*BASE, *HAZARD, *MAP), "rough": (*BASE, *HAZARD, "surfaces.0.roughness=0.3"),
         "places": (*BASE, *HAZARD, *MAP, 'hazard.points=[{name="p", position=[100.0, 0.0, 0.0], area=0.7}]'),
         "collisions": (*BASE, *HAZARD, *MAP, "collisions.enabled=true", "shot.shots=10")}
want = sys.argv[1].split(",") if len(sys.argv) > 1 else list(cases)
n = int(sys.argv[2]) if len(sys.argv) > 2 else 2000
dev = sys.argv[3] if len(sys.argv) > 3 else "cpu"
folder = Path(tempfile.mkdtemp())
for case in want:
    extra = list(cases[case])
    count = 200 if case == "collisions" else n
    out = {}
    for mode in ("never", "always"):
        path_replay.REPLAY = mode
        p = folder / f"{case}-{mode}.h5"
        wr.run(paper_scene(count, air=True, mu_s=0.5, fields=("hazard", "rest"), extra=extra), p, device=dev, overwrite=True)
        with h5py.File(p) as f:
            d = {}
            def grab(name, obj):
                if isinstance(obj, h5py.Dataset) and (name.startswith("hazard") or name.startswith("pellets")) and obj.dtype.kind in "fiu":
                    d[name] = obj[()]
            f.visititems(grab)
            out[mode] = d
    out = {m: {k: v for k, v in d.items() if v is not None} for m, d in out.items()}
    print(case, "replay vs at once:", _differences(out["never"], out["always"]), "| reach mean", np.nanmean(out["always"]["pellets/hazard/reach"], axis=0), flush=True)
