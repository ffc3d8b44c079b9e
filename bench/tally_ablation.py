"""Where the landing tallies' time goes (issue 15): the statistics-only run of `bench.hazard` with a
hazard map, its landing code cut down part by part, each variant in its own process (run this
module once per variant), with the per-kernel and copy/set times of one run (Warp's CUDA activity
timing) beside the median wall time.

    python -m bench.tally_ablation --device cuda:0 --sizes 1e8,1e9 --variant VARIANT [--copies C]

Variants of the landing code (`tallies.landing.make_add_landing`, patched before any kernel is built):
  as-is     the code as it is
  no-table  no block table: each map landing added to the maps at once
  no-add    the bins, cells and energies computed, nothing added (a condition no landing meets)
  empty     no landing code at all (the thresholds exceeded are still found)
  fixed-level, no-distance, no-map-math
            as-is with one part of the arithmetic a constant: the thresholds exceeded (all of them,
            as in the paper shot), the distance from the shooter (the range instead), the map's
            cell and energy
A variant's numbers are only for finding costs: its counts are wrong by design.
"""

import argparse
from types import SimpleNamespace

from bench.__main__ import _timed, _wr, device_info
from bench.hazard import CONFIGS, scene

VARIANTS = ("as-is", "no-table", "no-add", "empty", "fixed-level", "no-distance", "no-map-math")


def variant_factory(variant: str, table_size: int = 0, table_probes: int = 0):
    """A stand-in for `make_add_landing` with the landing code of `variant`."""
    import functools

    import warp as wp

    from warp_ricochet.tallies import landing
    from warp_ricochet.tallies.bins import BINS, ROW_DISTANCE, ROW_RANGE, ROW_SPEED, make_bin_of
    from warp_ricochet.tallies.block import ADD, PROBES, SLOTS, first_slot_steps, make_block_table

    original = landing.make_add_landing

    @functools.cache
    def make(precision: str, with_map: bool, thresholds: int = 0, slots: int = SLOTS, probes: int = PROBES):
        slots, probes = (0, 0) if variant in ("no-table", "empty") else (table_size or slots, table_probes or probes)
        base = original(precision, with_map, thresholds, slots, probes)
        if variant in ("as-is", "no-table"):
            return base
        fns = landing.make_landing_tally(precision)
        Tally, scalar, vec3, map_cell, horizontal_distance = (
            fns.Tally,
            fns.scalar,
            fns.vec3,
            fns.map_cell,
            fns.horizontal_distance,
        )
        energy_quanta, count_one = fns.energy_quanta, landing.count_one
        bin_of, table, copy_of = make_bin_of(), make_block_table(slots, probes), base.copy_of
        LATTICE, LEVEL_STEP = first_slot_steps(slots)
        EMPTY, NEVER = variant == "empty", variant == "no-add"
        NO_DISTANCE, NO_MAP_MATH = variant == "no-distance", variant == "no-map-math"
        ALL = 15  # fixed-level: every landing above each of the scene's four thresholds (as in the paper shot)

        @wp.func
        def exceeded(tally: Tally, v2: scalar):
            return wp.int32(ALL)

        @wp.func
        def add_landing(
            tally: Tally, row: wp.int32, surface: wp.int32, landing_range: scalar, position: vec3, v2: scalar, mask: wp.int32
        ):
            if not wp.static(EMPTY):
                level = wp.int32(wp.bit_count(mask))
                first = copy_of(row, tally.copy_mask) * tally.hist_stride
                distance = landing_range
                if not wp.static(NO_DISTANCE):
                    distance = horizontal_distance(tally, position)
                b0 = first + ROW_RANGE * BINS + bin_of(wp.float32(landing_range))
                b1 = first + ROW_SPEED * BINS + bin_of(wp.float32(wp.sqrt(v2)))
                b2 = first + (ROW_DISTANCE + level) * BINS + bin_of(wp.float32(distance))
                if row == -7 or not wp.static(NEVER):  # no-add: never (the values computed, not added)
                    count_one(tally.hist, b0)
                    count_one(tally.hist, b1)
                    count_one(tally.hist, b2)
                if wp.static(with_map):
                    column = level
                    energy = wp.int64(1)
                    home = column
                    if not wp.static(NO_MAP_MATH):
                        column, iu, iv = map_cell(tally, surface, position)
                        energy = energy_quanta(tally, v2)
                        home = iu + iv * LATTICE + level * LEVEL_STEP
                    key = level * tally.map_width + column
                    if row == -7 or not wp.static(NEVER):
                        if table(ADD, key, energy, home) == wp.int64(0):
                            wp.atomic_add(tally.map_counts, key, 1)
                            wp.atomic_add(tally.map_energy, column, energy)

        return SimpleNamespace(
            exceeded=exceeded if variant == "fixed-level" else base.exceeded,
            add_landing=add_landing,
            flush=base.flush,
            table=base.table,
            copy_of=copy_of,
        )

    return make


def patch(variant: str, slots: int = 0, probes: int = 0):
    """Build every later kernel with `variant`'s landing code (and a block table of `slots` and
    `probes`, where not 0)."""
    from warp_ricochet.core import kernel, pellet

    make = variant_factory(variant, slots, probes)
    kernel.make_add_landing = pellet.make_add_landing = make
    pellet.make_ricochet_pellet.cache_clear()
    kernel.ricochet_kernel_for.cache_clear()


def profile(wr, wp, sc, device):
    """{activity name: ms} of one run, summed by name (kernels, copies, sets)."""
    wp.timing_begin(cuda_filter=wp.TIMING_KERNEL | wp.TIMING_MEMCPY | wp.TIMING_MEMSET)
    wr.run(sc, device=device)
    totals: dict = {}
    for r in wp.timing_end():
        name = r.name.split("_cuda_kernel")[0][-48:]
        totals[name] = totals.get(name, 0.0) + r.elapsed
    return totals


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.tally_ablation", description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default=None)
    parser.add_argument("--sizes", default="1e8,1e9")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--variant", choices=VARIANTS, default="as-is")
    parser.add_argument("--slots", type=int, default=0, help="slots of the block table (default: tallies.block.SLOTS)")
    parser.add_argument("--probes", type=int, default=0, help="probes of the block table (default: tallies.block.PROBES)")
    parser.add_argument("--cap", default="default", help="register cap of the core kernel: default, none or a number")
    parser.add_argument("--host-profile", action="store_true", help="a cProfile of one run with a map at the last size")
    parser.add_argument(
        "--copies", type=int, default=None, help="copies of the counts on CUDA (default: tallies.counts.CUDA_COPIES)"
    )
    args = parser.parse_args(argv)
    wr, wp = _wr()
    from warp_ricochet.tallies import counts

    if args.copies:
        counts.CUDA_COPIES = args.copies
    patch(args.variant, args.slots, args.probes)
    if args.cap != "default":
        from warp_ricochet.core import kernel

        kernel.CUDA_MAX_REGISTERS = {key: None if args.cap == "none" else int(args.cap) for key in kernel.CUDA_MAX_REGISTERS}
    print("device:", device_info(wp, args.device))
    names = ("statistics only", "+ hazard map")
    for name in names:
        wr.run(scene(100_000, CONFIGS[name]), device=args.device)  # compile and warm up
    for n in [int(float(s)) for s in args.sizes.split(",")]:
        times = {}
        for name in names:
            sc = scene(n, CONFIGS[name])
            wr.run(sc, device=args.device)
            times[name], _ = _timed(lambda sc=sc: (wr.run(sc, device=args.device), wp.synchronize()), args.repeats)
        base = times[names[0]]
        print(
            f"{args.variant} slots={args.slots or 'default'} probes={args.probes or 'default'} cap={args.cap} copies={counts.CUDA_COPIES} N={n:.0e}: statistics only {base * 1e3:.2f} ms, "
            f"with a map {times[names[1]] * 1e3:.2f} ms ({times[names[1]] / base - 1:+.0%})"
        )
        if wp.get_device(args.device).is_cuda:
            for name in names:
                prof = profile(wr, wp, scene(n, CONFIGS[name]), args.device)
                print(f"   {name}: " + ", ".join(f"{k}: {v:.2f} ms" for k, v in sorted(prof.items(), key=lambda kv: -kv[1])[:6]))
    if args.host_profile:
        import cProfile
        import pstats

        for name in names:
            sc = scene(n, CONFIGS[name])
            pr = cProfile.Profile()
            pr.enable()
            for _ in range(3):
                wr.run(sc, device=args.device)
            pr.disable()
            stats = pstats.Stats(pr)
            print(f"host profile, {name}, N={n:.0e}, 3 runs:")
            stats.sort_stats("cumtime").print_stats(25)


if __name__ == "__main__":
    main()
