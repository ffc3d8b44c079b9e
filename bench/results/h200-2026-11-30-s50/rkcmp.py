"""Session 50: on one device, the rough-ground reach replayed by kind (lines, then flights) against the
same records replayed in order (HACK_ORDERED in core/replay.py), and both against the watch at once."""
import os, sys, tempfile, numpy as np, h5py
from pathlib import Path
from bench.air import paper_scene
from bench.path import BASE, HAZARD, MAP, _differences
import warp_ricochet as wr
from warp_ricochet.tallies import path_replay
from warp_ricochet.core import replay
n = int(sys.argv[1]); dev = sys.argv[2]
folder = Path(tempfile.mkdtemp())
cases = {"rough": (*BASE, *HAZARD, "surfaces.0.roughness=0.3"), "reach": (*BASE, *HAZARD)}
for case, extra in cases.items():
    out = {}
    for way, mode, ordered in (("at once", "never", ""), ("kind", "always", ""), ("ordered", "always", "1")):
        path_replay.REPLAY = mode
        os.environ["HACK_ORDERED"] = ordered
        replay.replay_kernels_for.cache_clear()
        p = folder / f"{case}-{way}.h5"
        wr.run(paper_scene(n, air=True, mu_s=0.5, fields=("hazard", "rest"), extra=list(extra)), p, device=dev, overwrite=True)
        with h5py.File(p) as f:
            out[way] = {k: f[k][()] for k in ("pellets/hazard/reach", "pellets/rest/position")}
    for a, b in (("at once", "kind"), ("at once", "ordered"), ("ordered", "kind")):
        print(case, f"{b} vs {a}:", _differences(out[a], out[b]), flush=True)
    d = np.abs(out["at once"]["pellets/hazard/reach"].astype(float) - out["kind"]["pellets/hazard/reach"])
    d = d[np.isfinite(d)]
    print(case, "kind vs at once |d| > 1e-3:", int((d > 1e-3).sum()), "> 1e-2:", int((d > 1e-2).sum()), "of", d.size, flush=True)
    np.savez(os.environ.get("OUT", "/tmp") + f"/rk-{case}.npz", **{f"{w}:{k}": v for w, d_ in out.items() for k, v in d_.items()})
