"""A shot's collision totals (`dense.ends.block_totals`, `shot_totals`) for one shot of N pellets:
one block a shot (one thread over the whole shot, as before the blocks) against blocks of
`dense.constants.FRAME_BLOCK` pellets, on synthetic collision counts and energies (float64, the
paper's scene with collisions; no dense phase is run). Warp's CUDA activity timing (the wall time
on the CPU), median of 5 after a warm-up.

    python -m bench.shot_totals [--device cuda:0] [--pellets 3e6]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bench.__main__ import _wr, device_info


def measure(device: str, n: int):
    wr, wp = _wr()
    from bench.interrupts import COLLISIONS, SCENE
    from warp_ricochet.dense import state
    from warp_ricochet.dense.phase import DensePhase
    from warp_ricochet.model import Model
    from warp_ricochet.scene import load_scene
    from warp_ricochet.spec import RunSpec

    scene = load_scene(SCENE, [f"shot.count={n}", "collisions.separate=false", *COLLISIONS])
    model = Model.from_scene(scene, wp.get_device(device))
    spec = RunSpec.of(scene, with_output=False)
    rng = np.random.default_rng(1)
    counts, lost = rng.integers(0, 4, n).astype(np.int32), rng.random(n) * 1e-3
    default, rows = state.FRAME_BLOCK, []
    try:
        for block in (1 << 30, default):
            state.FRAME_BLOCK = block  # (read when the phase's buffers are made)
            dense = DensePhase(model, scene, spec, n)
            dense.cloud.collisions.count.assign(counts)
            dense.cloud.collisions.energy_lost.assign(lost)
            times = []
            for _ in range(6):
                wp.synchronize()
                wp.timing_begin(cuda_filter=wp.TIMING_KERNEL)
                t0 = time.perf_counter()
                dense._launch("block_totals_kernel", dense.pair.frame_blocks, [dense.pair, dense.cloud, dense.block_totals])
                dense._launch("shot_totals_kernel", 1, [dense.pair, dense.cloud, dense.block_totals, dense.totals])
                wp.synchronize()
                wall = time.perf_counter() - t0
                records = wp.timing_end()
                times.append(sum(r.elapsed for r in records) if records else wall * 1e3)
            totals = dense.totals.numpy()[0]
            rows.append((dense.pair.frame_blocks, float(np.median(times[1:])), totals[:3]))
            del dense
    finally:
        state.FRAME_BLOCK = default
    return rows, ((counts > 0).sum(), counts.sum(), lost.sum())


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.shot_totals", description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--pellets", default="3e6")
    args = parser.parse_args(argv)
    n = int(float(args.pellets))
    print("device:", device_info(_wr()[1], args.device))
    rows, reference = measure(args.device, n)
    print(f"one shot of {n:,} pellets; NumPy: collided {reference[0]}, collisions {reference[1]}, energy lost {reference[2]!r} J")
    for blocks, ms, totals in rows:
        print(
            f"  {blocks} block(s): {ms:.3f} ms; collided {totals[0]:.0f}, collisions {totals[1]:.0f}, energy lost {totals[2]!r} J"
        )


if __name__ == "__main__":
    main()
