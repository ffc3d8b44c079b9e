"""Session 50: the merged replay on a GPU, end to end on examples/hazard.toml (560,000 pellets to rest):
  chunks  chunks of 2 and 5 segments: the same bits (replay); Ctrl-C after one chunk, --resume: the same bits
  rerun   columns of 64 words (every pellet followed again by the core): chunks of 2 and 5, the same bits
  never   the watch in the core (REPLAY = "never") against the replay: the danger distances side by side
"""
import os, sys, tempfile, numpy as np, h5py
from pathlib import Path
import warp_ricochet as wr
from warp_ricochet.scene import load_scene
from warp_ricochet.tallies import path_replay
from tests.helpers import assert_same_run, interrupt_after

what, dev = sys.argv[1], os.environ.get("DEV", "cuda:0")
tmp = Path(tempfile.mkdtemp())
SEG = 65536
def scene(chunk):
    extra = [f"shot.shots={os.environ['SHOTS']}"] if "SHOTS" in os.environ else []
    return load_scene("examples/hazard.toml", [f"numerics.chunk_size={chunk}", 'output.fields=["landing", "hazard", "rest"]', *extra])
FIELDS = ["hazard/reach", "rest/position", "landing/position"]
if what == "chunks":
    wr.run(scene(2 * SEG), tmp / "two.h5", device=dev)
    wr.run(scene(5 * SEG), tmp / "five.h5", device=dev)
    assert_same_run(tmp / "five.h5", tmp / "two.h5", FIELDS, progress=())
    print("chunks: 2 and 5 segments the same bits", flush=True)
    interrupt_after(1, scene(2 * SEG), tmp / "resumed.h5", device=dev)
    wr.run(scene(2 * SEG), tmp / "resumed.h5", device=dev, resume=True)
    assert_same_run(tmp / "resumed.h5", tmp / "two.h5", FIELDS)
    print("chunks: Ctrl-C after one chunk, --resume: the same bits", flush=True)
elif what == "rerun":
    path_replay.COLUMN_WORDS = 64
    wr.run(scene(2 * SEG), tmp / "two.h5", device=dev)
    wr.run(scene(5 * SEG), tmp / "five.h5", device=dev)
    assert_same_run(tmp / "five.h5", tmp / "two.h5", FIELDS, progress=())
    print("rerun: columns of 64 words, chunks of 2 and 5 segments the same bits", flush=True)
else:
    out = {}
    for mode in ("always", "never"):
        path_replay.REPLAY = mode
        wr.run(scene(5 * SEG), tmp / f"{mode}.h5", device=dev)
        with h5py.File(tmp / f"{mode}.h5") as f:
            out[mode] = f["pellets/hazard/reach"][()]
            found = []
            f["hazard"].visititems(lambda n, o: found.append(n) if isinstance(o, h5py.Dataset) else None)
            for n in found:
                d = f["hazard"][n]
                if d.size <= 64 and d.dtype.kind == "f":
                    print(mode, n, np.array2string(np.asarray(d[()]).ravel()[:16], precision=2), flush=True)
    a, b = out["always"], out["never"]
    both = np.isfinite(a) & np.isfinite(b)
    print("reach: differ", int((a != b).sum()), "max", float(np.abs(a[both] - b[both]).max(initial=0)),
          "finite only one way", int((np.isfinite(a) != np.isfinite(b)).sum()), flush=True)
