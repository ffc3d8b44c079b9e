"""Session 51: a run's statistics and hazard answers (bench.path's map case, statistics only) saved for a
bitwise comparison between trees that cut it into chunks of different sizes."""
import sys, pickle, numpy as np
import warp_ricochet as wr
from bench.air import paper_scene
from bench.path import BASE, CASES
n = int(float(sys.argv[1]))
s = wr.run(paper_scene(n, air=True, mu_s=0.5, extra=[*BASE, *CASES[-1][1]]), device="cuda:0")
flat = {}
def walk(prefix, v):
    if isinstance(v, dict) or hasattr(v, "keys"):
        for k in v.keys():
            walk(f"{prefix}/{k}", v[k])
    else:
        try:
            flat[prefix] = np.asarray(v)
        except Exception:
            flat[prefix] = repr(v)
walk("", s)
pickle.dump(flat, open(sys.argv[2], "wb"))
print(len(flat), "values", flat.get("/pellets"))
