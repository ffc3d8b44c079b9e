"""What the landing tallies cost (issue 15): statistics-only runs of the paper's shot with N pellets,
side by side in one process on one device: without tallies (output.quantiles = false), with the
quantile histograms, with [hazard] thresholds (danger distances) and with a hazard map too.

    python -m bench.hazard [--device cuda:0] [--sizes 1e8,1e9] [--repeats 5] [--copies 64,1]

Each configuration is compiled and warmed up first (not timed); each time is the median of
--repeats runs (wall clock of `warp_ricochet.run` without an output file, synchronised at its end).
A run returns its counts as their nonzero elements; the host's time to make them answers (dense
histograms and maps, quantiles, danger distances: `quantiles.summarize`) is timed apart, after it.
`--copies`: one table per number of copies of the counts on CUDA (`tallies.counts.CUDA_COPIES`, 256 by
default; the CPU always counts into one).
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

    # one shot of n pellets, the paper's mu_s = 0.05 (slip ricochets)
    return load_scene(SCENE, [f"shot.count={n}", "output.fields=[]", "surfaces.0.mu_s=0.05", "surfaces.0.mu_d=0.045", *settings])


def summarize_time(wr, sc, device, repeats) -> float:
    """Median seconds the host takes to turn a fresh run's counts into answers (`quantiles.summarize`:
    the dense counts, quantiles, tails, danger distances and map layers)."""
    import time

    from warp_ricochet.tallies.quantiles import summarize

    times = []
    for _ in range(repeats):
        stats = wr.run(sc, device=device)
        t0 = time.perf_counter()
        summarize(stats.tally, int(stats["landed"]))
        times.append(time.perf_counter() - t0)
    return sorted(times)[len(times) // 2]


def measure(device, sizes, repeats):
    wr, wp = _wr()
    rows, answers = [], []
    for name, settings in CONFIGS.items():
        wr.run(scene(100_000, settings), device=device)  # compile and warm up
    for n in sizes:
        times = {}
        for name, settings in CONFIGS.items():
            sc = scene(n, settings)
            wr.run(sc, device=device)  # warm up at this size (buffers, pinned pools)
            times[name], _ = _timed(lambda sc=sc: (wr.run(sc, device=device), wp.synchronize()), repeats)
        rows.append((n, times))
        answers.append(
            (
                n,
                {
                    name: summarize_time(wr, scene(n, settings), device, repeats)
                    for name, settings in CONFIGS.items()
                    if name != "statistics only"
                },
            )
        )
    return rows, answers


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.hazard", description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default=None, help="Warp device (default: CUDA if present, else cpu)")
    parser.add_argument("--sizes", default="1e8,1e9", help="pellet counts, comma-separated")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--copies", default=None, help="copies of the counts on CUDA, comma-separated (default: tallies.counts.CUDA_COPIES)"
    )
    args = parser.parse_args(argv)
    wr, wp = _wr()
    from warp_ricochet.tallies import counts

    device = args.device
    sizes = [int(float(s)) for s in args.sizes.split(",")]
    print("device:", device_info(wp, device))
    for copies in [int(c) for c in args.copies.split(",")] if args.copies else [counts.CUDA_COPIES]:
        counts.CUDA_COPIES = copies
        rows, answers = measure(device, sizes, args.repeats)
        names = list(CONFIGS)
        print(f"\ncopies of the counts on CUDA: {copies}")
        print("| N | " + " | ".join(names) + " |")
        print("| ---: |" + " ---: |" * len(names))
        for n, times in rows:
            base = times[names[0]]
            cells = [f"{times[k] * 1e3:.2f} ms" + ("" if k == names[0] else f" ({times[k] / base - 1:+.0%})") for k in names]
            print(f"| {n:.0e} | " + " | ".join(cells) + " |")
        print("\nthen, on the host, the counts turned into answers (`quantiles.summarize`, median):")
        for n, times in answers:
            print(f"| {n:.0e} | " + " | ".join(f"{k}: {v * 1e3:.2f} ms" for k, v in times.items()) + " |")


if __name__ == "__main__":
    main()
