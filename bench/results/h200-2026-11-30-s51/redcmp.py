import sys, numpy as np, warp as wp
sys.path.insert(0, "/tmp/lead")
wp.init()
import reduce_old
from warp_ricochet.tallies import reduce as new
from warp_ricochet.tallies.sums import NUM_SUMS, NUM_EXTREMES
rng = np.random.default_rng(1)
for lanes in (256, 4096, 5, 13, 24):
    segs = 3
    cols = segs * lanes
    ps = rng.standard_normal((NUM_SUMS, cols)) * 10 ** rng.uniform(-3, 6, (NUM_SUMS, 1))
    ps[ps < -5] = 0.0
    counts = rng.integers(0, 5, (NUM_SUMS, cols)).astype(float)
    ps = np.where(rng.random((NUM_SUMS, cols)) < 0.3, counts, ps)
    pmin = rng.standard_normal((NUM_EXTREMES, cols)); pmax = rng.standard_normal((NUM_EXTREMES, cols))
    outs = []
    for mod in (reduce_old, new):
        a = [wp.array(x, dtype=wp.float64) for x in (ps, pmin, pmax)]
        out = wp.zeros((segs, new.SEGMENT_WIDTH), dtype=wp.float64)
        wp.launch(mod.reduce_kernel(lanes), dim=(segs, NUM_SUMS + NUM_EXTREMES), inputs=[*a, 1, lanes, 0], outputs=[out])
        outs.append(out.numpy())
    print(lanes, "bitwise" if np.array_equal(outs[0], outs[1], equal_nan=True) else f"DIFFER {np.abs(outs[0]-outs[1]).max()}")
