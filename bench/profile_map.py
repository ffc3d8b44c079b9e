"""One run of `bench.path`'s map case (the paper's scene in sea-level air to rest, float32, the reach
and a 0.5 m map) for Nsight Compute, with line information compiled in:

    ncu -k regex:ricochet_kernel -c 1 --set full --import-source yes -o OUT/map \
        python3 -m bench.profile_map --device cuda:0 --n 2e5 [--case "to rest, reach"]

`--case "air, rest, turf"`: `bench.rest`'s scene of the same name (no hazard), for issue 25.

Figures: bench/RESULTS.md ("The hazard along the path: cost").
"""

import argparse

from bench.__main__ import _wr
from bench.air import paper_scene
from bench.path import BASE, CASES
from bench.rest import CASES as REST_CASES

TURF = next(case for case in REST_CASES if case[0] == "air, rest, turf")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--n", type=float, default=2e5)
    parser.add_argument("--case", default=CASES[-1][0], choices=[label for label, _ in CASES] + [TURF[0]])
    args = parser.parse_args(argv)
    wr, wp = _wr()
    wp.config.lineinfo = True
    extra = dict(CASES)[args.case] if args.case != TURF[0] else ()
    base = BASE if args.case != TURF[0] else ('physics.until="rest"', *TURF[3])
    stats = wr.run(paper_scene(int(args.n), air=True, mu_s=0.5, extra=[*base, *extra]), device=args.device)
    wp.synchronize_device(args.device)
    print(f"{args.case}: {stats['pellets']} pellets")


if __name__ == "__main__":
    main()
