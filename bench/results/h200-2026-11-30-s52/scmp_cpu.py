"""Session 50: one tree's replay outputs on the GPU (bench.path's map scene and rough ground, 20,000
pellets, hazard and rest fields) saved for a comparison between trees."""
import sys, tempfile, numpy as np, h5py
from pathlib import Path
from bench.air import paper_scene
from bench.path import LOG_CASES, LOG_KEYS
import warp_ricochet as wr
out = {}
for case in ("map", "rough, reach"):
    settings, _ = LOG_CASES[case]
    p = Path(tempfile.mkdtemp()) / "x.h5"
    wr.run(paper_scene(int(sys.argv[3]), air=True, mu_s=0.5, fields=("hazard", "rest"), extra=list(settings)), p, device=sys.argv[2], overwrite=True)
    with h5py.File(p) as f:
        for k in LOG_KEYS:
            if k in f:
                out[f"{case}:{k}"] = f[k][()]
np.savez(sys.argv[1], **out)
