"""`numerics.surface_tolerance` governs the phases along surfaces only (docs/ground.md 9): the
paper's scene in air followed to rest on turf, float32, at 1e-6 and at 1e-4. The flight and its
landing are the same bits; the surface takes fewer steps at the looser tolerance (measured: 57.8
and 35.2 a pellet), and the rest distances stay within what that tolerance allows (bench/RESULTS.md,
"The surface's tolerance": at 1e-4, 99% of rests within 4.5e-4 of their path along the ground)."""

import warp_ricochet as wr
from bench.air import paper_scene

LANDING = ("range_mean", "range_max", "landing_mean_WT", "flight_steps_mean")


def _stats(tolerance):
    extra = ['physics.until="rest"', 'surfaces.0.material="turf"', f"numerics.surface_tolerance={tolerance}"]
    return wr.run(paper_scene(300, air=True, mu_s=0.5, extra=extra), device="cpu")


def test_the_surface_tolerance_moves_the_surface_steps_only():
    tight, loose = _stats(1e-6), _stats(1e-4)
    assert {k: tight[k] for k in LANDING} == {k: loose[k] for k in LANDING}
    assert loose["rest_steps_mean"] < 0.7 * tight["rest_steps_mean"]
    # the mean rest distance (32.6 m; about 8 m of it along the ground) moves by less than 1e-4 of it
    assert abs(loose["rest_distance_mean"] - tight["rest_distance_mean"]) < 1e-4 * tight["rest_distance_mean"]
    assert loose["rest_distance_mean"] != tight["rest_distance_mean"]
