"""Does a low berm contain a shot that skips off gravel, and do pellet-pellet collisions change it?
(issue 27; docs/collisions.md, "Boxes, meshes, terrain and posts"). 100 pellets of #7.5 lead at
400 m/s fired 6 degrees down (+-1.7 degrees) from 1.5 m over gravel, which they meet about 14 m out;
a berm (a box 1 m high, 4 m deep, 30 m wide, packed soil) whose front face is 20 m out. Followed
over two contacts (`until = "landing"`, float64, vacuum). Each shot's fraction of pellets landing
beyond the berm's back face is one sample: the ensembles' means with 95% intervals over shots,
collisions off and on, each ensemble its own seed (ensembles compared, never shot against shot).

    python examples/berm_collisions_study.py [--shots 400] [--device cpu]
"""

import argparse
import tempfile
from pathlib import Path

import numpy as np

import warp_ricochet as wr
from warp_ricochet.scene import scene_from_dict

FRONT, DEPTH, HEIGHT = 20.0, 4.0, 1.0  # m: the berm's front face down range, its depth and height
AIM = np.radians(6.0)  # below the horizontal


def scene(shots: int, collisions: bool, seed: int):
    """The study's scene: `shots` shots of 100 pellets, pellet-pellet collisions on or off."""
    shot = {"count": 100, "shots": shots, "diameter": 0.0024, "density": 11_340.0, "speed": 400.0, "seed": seed}
    shot |= {"direction": [float(np.cos(AIM)), float(-np.sin(AIM)), 0.0], "direction_jitter": [0.0, 0.03, 0.03]}
    shot |= {"envelope_radius": 0.01, "envelope_center": [0.0, 1.5, 0.0]}
    berm = {"name": "berm", "kind": "box", "point": [FRONT + DEPTH / 2, HEIGHT / 2, 0.0], "normal": [0.0, 1.0, 0.0]}
    berm |= {"axis_u": [1.0, 0.0, 0.0], "size": [DEPTH, 30.0, HEIGHT], "material": "packed_soil"}
    return scene_from_dict(
        {
            "shot": shot,
            "surfaces": [{"name": "gravel", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "gravel"}, berm],
            "physics": {"gravity": [0.0, -9.81, 0.0], "until": "landing", "bounces": 2},
            "numerics": {"precision": "float64"},
            "collisions": {"enabled": collisions},
            "output": {"fields": ["landing.position"]},
        }
    )


def beyond(shots: int, collisions: bool, seed: int, device: str, folder: Path):
    """Per shot: the fraction of its pellets landing beyond the berm's back face; and the run's statistics."""
    import h5py

    path = folder / f"berm-{collisions}.h5"
    stats = wr.run(scene(shots, collisions, seed), path, device=device, overwrite=True)
    with h5py.File(path) as f:
        x = f["pellets/landing/position"][:, 0]
    return (np.nan_to_num(x, nan=0.0) > FRONT + DEPTH).reshape(shots, -1).mean(axis=1), stats


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--shots", type=int, default=400)
    parser.add_argument("--device", default="cpu")
    args = parser.parse_args(argv)
    means = {}
    with tempfile.TemporaryDirectory() as tmp:
        for collisions, seed in ((False, 1), (True, 2)):
            fraction, stats = beyond(args.shots, collisions, seed, args.device, Path(tmp))
            half = 1.96 * fraction.std(ddof=1) / np.sqrt(args.shots)
            means[collisions] = (fraction.mean(), half)
            pairs = f", {stats['pair_collisions'] / args.shots:.0f} pair collisions a shot" if collisions else ""
            print(
                f"collisions {'on ' if collisions else 'off'}: {100 * fraction.mean():.1f}% +- {100 * half:.1f}% beyond the berm{pairs}"
            )
    (off, h0), (on, h1) = means[False], means[True]
    print(f"on - off: {100 * (on - off):+.1f}% +- {100 * np.hypot(h0, h1):.1f}% (95%, {args.shots} shots each)")


if __name__ == "__main__":
    main()
