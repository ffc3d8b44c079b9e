import sys, tempfile, numpy as np, h5py
from pathlib import Path
from bench.air import paper_scene
from bench.path import LOG_CASES
import warp_ricochet as wr
out = {}
settings, _ = LOG_CASES["map"]
for prec in ("float32", "float64"):
    p = Path(tempfile.mkdtemp()) / "x.h5"
    wr.run(paper_scene(20000, prec, air=True, mu_s=0.5, fields=("hazard", "rest"), extra=list(settings)), p, device="cpu", overwrite=True)
    with h5py.File(p) as f:
        for k in ("hazard/map/passes", "hazard/map/exposure"):
            out[f"{prec}:{k}"] = f[k][()]
np.savez(sys.argv[1], **out)
