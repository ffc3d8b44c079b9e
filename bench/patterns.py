"""What drawing directions from a choke's pattern (`launch.pattern`) costs beside today's jitter
(issue 28: at most 10% on a GPU at 1e8 pellets), figures, not tests.

The paper's scene (examples/paper.toml), statistics only, run twice per precision in one process:
as it is (d = direction + jitter u) and with `shot.choke = "modified"` in place of the jitter (the
only difference: the compiled-in pattern draw); in vacuum, where the rest of a pellet's work is the
least and the sampling's share the largest, and with --air in sea-level air too. Each is compiled
first (a small run, not timed); then the two alternate, `--repeats` times, and the median of each
is reported with the device named. The pattern's cone (spread 0.0077 a side) is 13x narrower than the
paper's jitter (0.1 a component), so its pellets take other branches; "jitter, pattern's width" is
today's sampler drawing a cone of the pattern's covariance, the baseline with the same physics. With
--alone, a kernel that only samples (and keeps one number a pellet) is timed with each sampler too:
the sampling's own cost, as a share of today's whole run.

With --per-shot every run is made of shots of SHOT pellets (with their per-shot statistics, as a
range study's), and a third sampling adds [[stations]] (two, at the paper's launch point, aims drawn
over 2 degrees of azimuth and elevation per shot: `launch.stations`) to the pattern.

    python -m bench.patterns [--device cuda:0] [--pellets 1e8] [--precisions float32,float64] [--repeats 5] [--air] [--per-shot] [--alone]

Figures: bench/RESULTS.md ("Shot patterns: sampling cost").
"""

import argparse
import functools
import time

import numpy as np

from bench.__main__ import SCENE, _wr, device_info

SAMPLINGS = {
    "jitter (today)": (),
    # today's sampler drawing the pattern's cone: per-component jitter of the same covariance
    "jitter, pattern's width": ("WIDTH",),
    "pattern (modified choke)": ("shot.direction_jitter=0", 'shot.choke="modified"'),
    # two stations at the paper's launch point, aims within 1 degree of its direction, and the pattern
    "stations + pattern": ("shot.direction_jitter=0", 'shot.choke="modified"', "STATIONS"),
}
SHOT = 500  # pellets a shot of the --per-shot runs (stations need shots: a station fires whole shots)
STATIONS = [  # [[stations]] of the third sampling: the paper's envelope centre, 45 degrees down
    {"name": name, "position": [0.0, 1.0, 0.0], "azimuth": [-1.0, 1.0], "elevation": [-46.0, -44.0]} for name in ("a", "b")
]


def matched_jitter(precision: str) -> float:
    """The per-component jitter J whose uniform draw on [-J, J] (standard deviation J / sqrt 3, an
    angle of J / (sqrt 3 |d|) across the unnormalised aim d) has the modified choke's spread sigma per
    axis: J = sigma sqrt(3) |d|."""
    pattern = scene(1000, precision, SAMPLINGS["pattern (modified choke)"], False)
    return pattern.shot.pattern_spread * np.sqrt(3.0) * float(np.linalg.norm(pattern.shot.direction))


def scene(n: int, precision: str, sampling, air: bool, per_shot: bool = False):
    """The paper's scene with n pellets, statistics only, in `precision`, with `sampling`'s keys; as
    one shot, or (`per_shot`) as shots of SHOT pellets with their per-shot statistics."""
    import tomllib

    from warp_ricochet.scene import scene_from_dict
    from warp_ricochet.scene.overrides import apply_override

    if "WIDTH" in sampling:
        sampling = (f"shot.direction_jitter={float(matched_jitter(precision))!r}",)
    stations = "STATIONS" in sampling
    count, shots = (SHOT, max(2, n // SHOT)) if per_shot else (n, 1)
    sets = [f"shot.count={count}", f"shot.shots={shots}", f'numerics.precision="{precision}"', "output.fields=[]"]
    sets += [s for s in sampling if s != "STATIONS"] + (["air.density=1.225"] if air else [])
    raw = tomllib.loads(SCENE.read_text())
    for assignment in sets:
        raw = apply_override(raw, assignment)
    if stations:  # a station's position replaces the envelope's centre
        del raw["shot"]["envelope_center"]
        raw["stations"] = STATIONS
    return scene_from_dict(raw, SCENE.parent)


def compare(device: str, n: int, precision: str, repeats: int, air: bool, per_shot: bool) -> dict:
    """Median seconds of each sampling's run (alternating, after a compile run) and their ratio."""
    wr, wp = _wr()
    samplings = {k: v for k, v in SAMPLINGS.items() if per_shot or "STATIONS" not in v}
    scenes = {name: scene(n, precision, keys, air, per_shot) for name, keys in samplings.items()}
    for keys in samplings.values():
        wr.run(scene(1000, precision, keys, air, per_shot), device=device)  # compile
    times = {name: [] for name in scenes}
    for _ in range(repeats):
        for name, s in scenes.items():
            wp.synchronize_device(device)
            start = time.perf_counter()
            stats = wr.run(s, device=device)
            wp.synchronize_device(device)
            times[name].append(time.perf_counter() - start)
            assert stats["pellets"] == (n if not per_shot else SHOT * max(2, n // SHOT))
    median = {name: float(np.median(t)) for name, t in times.items()}
    today, width = median["jitter (today)"], median["jitter, pattern's width"]
    ratios = {f"{k} / today": v / today for k, v in median.items()}
    return {"precision": precision, "air": air, "N": n, **median, **ratios, "pattern / same width": median[PATTERN] / width}


PATTERN = "pattern (modified choke)"


@functools.cache
def alone_kernel(precision: str, pattern: bool):
    """A kernel that only samples pellets (`launch.sampling`) and keeps one number of each."""
    wp = _wr()[1]
    from warp_ricochet.launch.sampling import make_sampler
    from warp_ricochet.physics.types import types_for

    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    sample_pellet = make_sampler(precision, pattern)

    @wp.kernel(module="unique", enable_backward=False)
    def sample_only(
        seed: wp.int32,
        speed: scalar,
        direction: vec3,
        jitter: vec3,
        center: vec3,
        radius: scalar,
        spin: vec3,
        spread: scalar,
        out: wp.array(dtype=scalar),
    ):
        i = wp.tid()
        p, v, w = sample_pellet(seed, i, speed, direction, jitter, center, radius, spin, spread)
        out[i] = p[0] + p[1] + p[2] + v[0] + v[1] + v[2] + w[0]

    return sample_only


def sampling_alone(device: str, n: int, precision: str, repeats: int) -> dict:
    """Median seconds of a launch that only samples n pellets, with today's jitter and with the pattern."""
    wr, wp = _wr()
    from warp_ricochet.physics.types import types_for

    t = types_for(precision)
    out = wp.empty(n, dtype=t.scalar, device=device)
    times = {}
    for name, keys in (("jitter (today)", ()), (PATTERN, SAMPLINGS[PATTERN])):
        shot = scene(1000, precision, keys, False).shot
        unit = np.asarray(shot.direction, float) / np.linalg.norm(shot.direction)
        aim = unit if (shot.pattern_spread or 0.0) > 0 else np.asarray(shot.direction, float)
        args = [shot.seed, t.scalar(shot.speed), t.vec3(*aim), t.vec3(*shot.direction_jitter)]
        args += [t.vec3(*shot.envelope_center), t.scalar(shot.envelope_radius), t.vec3(*shot.spin)]
        args += [t.scalar(shot.pattern_spread or 0.0), out]
        kernel = alone_kernel(precision, (shot.pattern_spread or 0.0) > 0)
        wp.launch(kernel, dim=n, inputs=args, device=device)  # compile
        wp.synchronize_device(device)
        runs = []
        for _ in range(repeats):
            start = time.perf_counter()
            wp.launch(kernel, dim=n, inputs=args, device=device)
            wp.synchronize_device(device)
            runs.append(time.perf_counter() - start)
        times[name] = float(np.median(runs))
    return times


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default=None, help="a Warp device (default: CUDA if present, else the CPU)")
    parser.add_argument("--pellets", type=float, default=1e8)
    parser.add_argument("--precisions", default="float32,float64")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--air", action="store_true", help="in sea-level air too")
    parser.add_argument("--per-shot", action="store_true", help=f"shots of {SHOT} pellets (per-shot statistics), and stations")
    parser.add_argument("--alone", action="store_true", help="also time a kernel that only samples (vacuum rows)")
    args = parser.parse_args(argv)
    _, wp = _wr()
    device = args.device or ("cuda:0" if wp.is_cuda_available() else "cpu")
    info = device_info(wp, device)
    print(f"device: {info['name']} ({info['device']}), Warp {info['warp']}, host {info['host']}, {info['cpu_count']} cores")
    names = [k for k, v in SAMPLINGS.items() if args.per_shot or "STATIONS" not in v]
    alone = ["alone: jitter, ns", "alone: pattern, ns", "(pattern - jitter) alone / today's run"] if args.alone else []
    heads = [f"{k}, s" for k in names] + [f"{k} / today" for k in names[1:]] + ["pattern / same width"] + alone
    print("| flight | precision | N | " + " | ".join(heads) + " |")
    print("| --- | --- | ---: |" + " ---: |" * len(heads))
    for air in (False, True) if args.air else (False,):
        for precision in args.precisions.split(","):
            n = int(args.pellets)
            row = compare(device, n, precision, args.repeats, air, args.per_shot)
            cells = [f"{row[k]:.4g}" for k in names] + [f"{row[f'{k} / today']:.3f}" for k in names[1:]]
            cells.append(f"{row['pattern / same width']:.3f}")
            if args.alone and not air:
                t = sampling_alone(device, n, precision, args.repeats)
                extra = (t[PATTERN] - t["jitter (today)"]) / row["jitter (today)"]
                cells += [f"{1e9 * t['jitter (today)'] / n:.3g}", f"{1e9 * t[PATTERN] / n:.3g}", f"{extra:+.3f}"]
            print(f"| {'air' if air else 'vacuum'} | {precision} | {row['N']:.3g} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
