"""What sampling collision shots without overlaps (`dense.separation`) does to the launch:
overlapping pairs before and after, redraws, the radial distribution against uniform in the sphere
(Kolmogorov-Smirnov), and the time it takes, for the paper's envelope and denser ones.

    nice python -m bench.launch_overlaps [--shots 200] [--device cpu]
"""

import argparse
import time
import warnings

import numpy as np


def launches(count, shots, envelope_radius, device):
    """Launch positions (m) of `shots` shots (float64), sampled as a collision run does."""
    import warp as wp

    from warp_ricochet.dense.phase import DensePhase
    from warp_ricochet.launch.source import PelletSource
    from warp_ricochet.model import Model, State
    from warp_ricochet.scene import load_scene
    from warp_ricochet.spec import RunSpec

    scene = load_scene(
        "examples/paper.toml",
        [
            f"shot.count={count}",
            f"shot.shots={shots}",
            f"shot.envelope_radius={envelope_radius}",
            'numerics.precision="float64"',
            "collisions.enabled=true",
            'output.fields=["initial.position"]',
        ],
    )
    dev = wp.get_device(device)
    model = Model.from_scene(scene, dev)
    spec = RunSpec.of(scene)
    dense = DensePhase(model, scene, spec, count * shots)
    source = PelletSource(scene, "float64", dev, count * shots)
    state = State(model, count * shots, spec.core_fields)
    dense.sampled = False  # today's sampling, unseparated (a run without collisions)
    dense.launch_shots(0, shots, source.struct, state.outputs)
    before = dense.cloud.state.position.numpy()[: count * shots].copy()
    dense.sampled = True
    wp.synchronize_device(dev)
    start = time.perf_counter()
    dense.launch_shots(0, shots, source.struct, state.outputs)
    after = dense.cloud.state.position.numpy()[: count * shots].copy()
    elapsed = time.perf_counter() - start
    redraws = dense.redraws.numpy()[:shots].copy()
    return before, after, redraws, elapsed, scene


def overlapping_pairs(positions, count, diameter):
    from scipy.spatial import cKDTree

    shots = len(positions) // count
    return [len(cKDTree(positions[s * count : (s + 1) * count]).query_pairs(diameter)) for s in range(shots)]


def main():
    import warp as wp
    from scipy import stats

    wp.config.quiet = True
    warnings.simplefilter("ignore")
    parser = argparse.ArgumentParser()
    parser.add_argument("--shots", type=int, default=200)
    parser.add_argument("--device", default="cpu")
    args = parser.parse_args()
    diameter = 0.0025
    print(
        "| envelope radius (mm) | pellets | packing | overlapping pairs a shot, before -> after | pellets redrawn | "
        "most redraws of a pellet | KS D of r/R^e vs uniform in the sphere, before -> after (p after) | "
        "mean r/R^e (uniform: 0.75), before -> after | launch and separation, s a shot |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for count, radius in ((450, 0.025), (450, 0.02), (450, 0.0153), (2000, 0.025)):
        from warp_ricochet.launch.packing import packing_fraction

        shots = args.shots if count * args.shots <= 400_000 else 400_000 // count
        before, after, redraws, elapsed, scene = launches(count, shots, radius, args.device)
        centre = np.asarray(scene.shot.envelope_center)
        pairs_before = np.mean(overlapping_pairs(before, count, diameter))
        pairs_after = np.mean(overlapping_pairs(after, count, diameter))
        moved = np.mean(np.any(before != after, axis=1))
        ks_before = stats.kstest(np.linalg.norm(before - centre, axis=1) / radius, lambda x: np.clip(x, 0, 1) ** 3)
        r_before = np.linalg.norm(before - centre, axis=1) / radius
        r_after = np.linalg.norm(after - centre, axis=1) / radius
        ks_after = stats.kstest(r_after, lambda x: np.clip(x, 0, 1) ** 3)
        print(
            f"| {radius * 1e3:g} | {count} | {packing_fraction(count, diameter, radius):.3f} | {pairs_before:.1f} -> "
            f"{pairs_after:.1f} | {moved:.3f} | {redraws.max()} | {ks_before.statistic:.4f} -> "
            f"{ks_after.statistic:.4f} (p {ks_after.pvalue:.2g}) | {r_before.mean():.4f} -> {r_after.mean():.4f} | "
            f"{elapsed / shots:.2g} |"
        )
    print(f"({args.shots} shots of 450, fewer of 2000; device {args.device}; positions float64)")


if __name__ == "__main__":
    main()
