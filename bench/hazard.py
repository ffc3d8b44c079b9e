"""What the landing tallies cost (issue 15): statistics-only runs of the paper's shot with N pellets,
side by side in one process on one device: without tallies (output.quantiles = false), with the
quantile histograms, with [hazard] thresholds (danger distances) and with a hazard map too.

    python -m bench.hazard [--device cuda:0] [--sizes 1e8,1e9] [--repeats 5] [--copies 64,1]
    python -m bench.hazard --locality [--sizes 131072]

Each configuration is compiled and warmed up first (not timed); each time is the median of
--repeats runs (wall clock of `warp_ricochet.run` without an output file, synchronised at its end).
`--copies`: one table per number of copies of the counts on CUDA (`tallies.counts.CUDA_COPIES`, 256 by
default; the CPU always counts into one). `--locality`: how often a core-kernel thread's consecutive
landings (LANES apart in the chunk) share their map cell or histogram bin (the hit rate of a
one-entry run-length cache per thread) and how many distinct keys a warp's 32 consecutive rows
hold (the addresses of one atomic instruction), from the per-pellet landings of a run with the map (CPU).
"""

from __future__ import annotations

import argparse

from bench.__main__ import SCENE, _timed, _wr, device_info

MAP = ("hazard.map_cell=0.5", "hazard.map_extent=[0.0, 200.0, -50.0, 50.0]")
CONFIGS = {
    "statistics only": ("output.quantiles=false",),
    "+ quantiles": ("output.quantiles=true",),
    "+ hazard thresholds": ("output.quantiles=true", "hazard.fractions=[1e-3, 1e-6]"),
    "+ hazard map": ("output.quantiles=true", "hazard.fractions=[1e-3, 1e-6]") + MAP,
}


def scene(n: int, settings):
    from warp_ricochet.scene import load_scene

    # shots of 450 pellets: shot.count alone is limited to int32; the paper's mu_s = 0.05
    return load_scene(SCENE, [f"shot.count={n}", "output.fields=[]", "surfaces.0.mu_s=0.05", "surfaces.0.mu_d=0.045",
                              *settings])


def measure(device, sizes, repeats):
    wr, wp = _wr()
    rows = []
    for name, settings in CONFIGS.items():
        wr.run(scene(100_000, settings), device=device)  # compile and warm up
    for n in sizes:
        times = {}
        for name, settings in CONFIGS.items():
            sc = scene(n, settings)
            wr.run(sc, device=device)  # warm up at this size (buffers, pinned pools)
            times[name], _ = _timed(lambda sc=sc: (wr.run(sc, device=device), wp.synchronize()), repeats)
        rows.append((n, times))
    return rows


def locality(n: int):
    """{key: share of a thread's landings whose key equals its previous landing's}, and the map's
    distinct cells, from one CPU run of `n` pellets (whole segments) with per-pellet landings."""
    import tempfile

    import h5py
    import numpy as np

    from warp_ricochet.tallies import bins
    from warp_ricochet.tallies.reduce import LANES, PER_THREAD, SEGMENT

    wr, _wp = _wr()
    sc = scene(n, CONFIGS["+ hazard map"] + ('output.fields=["landing", "hazard"]',))
    with tempfile.TemporaryDirectory() as tmp:
        wr.run(sc, f"{tmp}/run.h5", device="cpu")
        with h5py.File(f"{tmp}/run.h5", "r") as f:
            r, p, v = (f[f"pellets/landing/{k}"][()].astype(np.float64) for k in ("range", "position", "velocity"))
            level = np.array([bin(int(x)).count("1") for x in f["pellets/hazard/exceeds"][()]])
            o, ua, va, ue, ve = (f[f"hazard/map/{k}"][()] for k in ("origin", "u_axis", "v_axis", "u_edges", "v_edges"))
    size = ue[1] - ue[0]  # m, the cell
    cell = np.floor(((p - o) @ va - ve[0]) / size) * len(ue) + np.floor(((p - o) @ ua - ue[0]) / size)
    up = -np.asarray(sc.physics.gravity) / np.linalg.norm(sc.physics.gravity)
    d = p - np.asarray(sc.shot.envelope_center)
    keys = {"map (level, cell)": level * 1e9 + cell, "range bin": bins.bin_index(r),
            "speed bin": bins.bin_index(np.linalg.norm(v, axis=1)),
            "distance (level, bin)": level * 1e6 + bins.bin_index(np.linalg.norm(d - np.outer(d @ up, up), axis=1))}
    landed = np.isfinite(r)
    order = (np.arange(n // SEGMENT)[:, None, None] * SEGMENT + np.arange(PER_THREAD)[None, :, None] * LANES
             + np.arange(LANES)[None, None, :]).transpose(0, 2, 1).reshape(-1, PER_THREAD)  # a thread's rows, in order
    rates = {}
    for name, key in keys.items():
        hits = sum(int((k[1:] == k[:-1]).sum()) for k in (key[rows][landed[rows]] for rows in order))
        warps = key[: n // 32 * 32].reshape(-1, 32)  # a warp's atomic: 32 consecutive rows
        rates[name] = (hits / landed[: order.size].sum(), np.mean([len(np.unique(w)) for w in warps]))
    return rates, len(np.unique(cell[landed]))


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.hazard", description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default=None, help="Warp device (default: CUDA if present, else cpu)")
    parser.add_argument("--sizes", default="1e8,1e9", help="pellet counts, comma-separated")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--copies", default=None, help="copies of the counts on CUDA, comma-separated (default: 256)")
    parser.add_argument("--locality", action="store_true", help="hit rates of a per-thread one-entry cache (CPU)")
    args = parser.parse_args(argv)
    if args.locality:
        from warp_ricochet.tallies.reduce import SEGMENT

        n = max(SEGMENT, int(float(args.sizes.split(",")[0])) // SEGMENT * SEGMENT)
        rates, cells = locality(n)
        print(f"{n} pellets, landings in {cells} map cells; hit rate of a one-entry cache per thread, and distinct "
              "addresses per warp atomic (of 32):")
        for name, (rate, distinct) in rates.items():
            print(f"  {name}: {rate:.3f}, {distinct:.1f}")
        return
    wr, wp = _wr()
    from warp_ricochet.tallies import counts

    device = args.device
    sizes = [int(float(s)) for s in args.sizes.split(",")]
    print("device:", device_info(wp, device))
    for copies in [int(c) for c in args.copies.split(",")] if args.copies else [counts.CUDA_COPIES]:
        counts.CUDA_COPIES = copies
        rows = measure(device, sizes, args.repeats)
        names = list(CONFIGS)
        print(f"\ncopies of the counts on CUDA: {copies}")
        print("| N | " + " | ".join(names) + " |")
        print("| ---: |" + " ---: |" * len(names))
        for n, times in rows:
            base = times[names[0]]
            cells = [f"{times[k] * 1e3:.2f} ms" + ("" if k == names[0] else f" ({times[k] / base - 1:+.0%})") for k in names]
            print(f"| {n:.0e} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
