import sys, pickle, numpy as np
import warp_ricochet as wr
from warp_ricochet.tallies import path_replay
from warp_ricochet.physics import line_log
from bench.air import paper_scene
from bench.path import BASE, CASES
n, chunk, limit, out = int(float(sys.argv[1])), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
path_replay.REPLAY = "always"
if limit:
    line_log.INDEX_LIMIT = limit
extra = [*BASE, *CASES[-1][1]] + ([f"numerics.chunk_size={chunk}"] if chunk else [])
s = wr.run(paper_scene(n, air=True, mu_s=0.5, extra=extra), device="cpu")
flat = {k: np.asarray(s[k]) for k in s.keys() if not isinstance(s[k], dict)}
pickle.dump(flat, open(out, "wb"))
print(len(flat), flat["pellets"], flat["range_slip_max"], flat["range_slip_mean"])
