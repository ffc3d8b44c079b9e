"""The core's continuation to rest (core/rest.py) against the float64 SciPy reference
(reference/surface_motion.py `follow`): flight, impacts with the separation criterion, sliding,
rolling, ploughing, lift-off and rest over one plane, on seeded random cases in both precisions,
in vacuum and in air; and the invariants (never below the plane, energy never rises)."""

import functools
import math

import numpy as np
import pytest
import warp as wp

from warp_ricochet.core.rest import FLIGHT, make_to_rest
from warp_ricochet.ends import AT_REST, ESCAPED, NOT_FINISHED
from warp_ricochet.model import Model
from warp_ricochet.physics.types import types_for
from warp_ricochet.reference import surface_motion as ref
from warp_ricochet.scene import scene_from_dict
from warp_ricochet.scene.schema import Air
from warp_ricochet.spec import RunSpec

wp.config.log_level = wp.LOG_WARNING
PRECISIONS = ["float64", "float32"]
# the rest position against the reference's, relative to its path length (the issue asks for 1e-4):
CLOSE = {"float64": 1e-5, "float32": 1e-4}  # integrated phases at the default tolerance (1e-6)
STATES = {AT_REST: "rest", ESCAPED: "escaped", NOT_FINISHED: "moving"}


def _scene(precision, normal, surface, air):
    raw = {
        "shot": {"count": 1, "speed": 100.0, "direction": [1.0, 0.0, 0.0], "diameter": 0.0025, "density": 7000.0},
        "surfaces": [{"point": [0.0, 0.0, 0.0], "normal": list(normal), **surface}],
        "physics": {"impact_duration": 0.0, "until": "rest", "rest_speed": 0.2},
        "numerics": {"precision": precision},
    }
    if air:
        raw["air"] = {"density": 1.225} if air is True else {"density": 1.225, "wind": list(air)}
    return scene_from_dict(raw)


@functools.cache
def _kernel(spec):
    """A kernel following pellets from a flight (no surface left) with `to_rest` of `spec`."""
    fns = make_to_rest(spec)
    to_rest, start, Tally = fns.to_rest, fns.start, fns.Tally  # (the hazard's watch: none here)
    t = types_for(spec.precision)
    vec3, scalar, Surfaces, Physics = t.vec3, t.scalar, t.Surfaces, t.Physics

    @wp.kernel(enable_backward=False, module="unique")
    def follow_kernel(
        x_in: wp.array(dtype=vec3),
        v_in: wp.array(dtype=vec3),
        w_in: wp.array(dtype=vec3),
        surfaces: Surfaces,
        physics: Physics,
        end_out: wp.array(dtype=wp.int32),
        x_out: wp.array(dtype=vec3),
        path_out: wp.array(dtype=scalar),
        impacts_out: wp.array(dtype=wp.int32),
    ):
        i = wp.tid()
        end, x, _v, _w, _t, impacts, path, _steps, _track = to_rest(
            FLIGHT, -1, x_in[i], v_in[i], w_in[i], scalar(0.0), 0, 1, i, surfaces, physics, start(), Tally()
        )
        end_out[i] = end
        x_out[i] = x
        path_out[i] = path
        impacts_out[i] = impacts

    return follow_kernel


def _cases(rng, n, normal):
    """Launch states a few cm to a metre above the plane, heading down at 1-20 deg, 5-120 m/s."""
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    e1 = np.cross(normal, [0.3, 0.1, 0.9])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    cases = []
    for _ in range(n):
        speed, angle, turn = rng.uniform(5, 120), math.radians(rng.uniform(1, 20)), rng.uniform(0, 2 * math.pi)
        along = math.cos(turn) * e1 + math.sin(turn) * e2
        v = speed * (math.cos(angle) * along - math.sin(angle) * normal)
        x = (0.00125 + rng.uniform(0.01, 1.0)) * normal
        w = rng.normal(0, 2000, 3)
        cases.append((x, v, w))
    return cases


def _run(precision, normal, surface, air, cases):
    scene = _scene(precision, normal, surface, air)
    spec = RunSpec.of(scene, with_output=False)
    model = Model.from_scene(scene, wp.get_device("cpu"))
    t = model.types
    arrays = [wp.array(np.array([c[j] for c in cases]), dtype=t.vec3, device="cpu") for j in range(3)]
    n = len(cases)
    end, x = wp.zeros(n, dtype=wp.int32, device="cpu"), wp.zeros(n, dtype=t.vec3, device="cpu")
    path, impacts = wp.zeros(n, dtype=t.scalar, device="cpu"), wp.zeros(n, dtype=wp.int32, device="cpu")
    wp.launch(
        _kernel(spec), dim=n, inputs=[*arrays, model.surfaces, model.physics], outputs=[end, x, path, impacts], device="cpu"
    )
    return end.numpy(), x.numpy().astype(float), path.numpy().astype(float), impacts.numpy()


GROUNDS = [
    {"restitution": 0.3, "mu_s": 0.5, "mu_d": 0.45, "rolling_resistance": 0.05},
    # ploughing: Poncelet's c2 (kg/m^3) over a fraction of the cross-section: b = 3 c2 f / (4 rho R) = 5 / m
    {"restitution": 0.1, "mu_s": 0.4, "mu_d": 0.35, "rolling_resistance": 0.1, "ploughing": 1750.0 / 3, "ploughing_area": 0.1},
]


def _b(surface):
    """The ploughing b (1/m) of a surface for the 2.5 mm, 7000 kg/m^3 pellet."""
    return 3 * surface.get("ploughing", 0.0) * surface.get("ploughing_area", 0.0) / (4 * 7000.0 * 0.00125)


@pytest.mark.parametrize("precision", PRECISIONS)
@pytest.mark.parametrize("air", [False, True], ids=["vacuum", "air"])
def test_rests_where_the_reference_does(precision, air):
    rng = np.random.default_rng(25 + air)
    normal = (0.0, 1.0, 0.0) if not air else (0.02, 1.0, -0.01)  # tan(slope) 0.022 < c: it can rest
    for surface in GROUNDS:
        cases = _cases(rng, 6, normal)
        end, x, path, impacts = _run(precision, normal, surface, air, cases)
        ground = ref.Ground(surface["restitution"], surface["mu_s"], surface["mu_d"], surface["rolling_resistance"], _b(surface))
        compared = 0
        for i, (x0, v0, w0) in enumerate(cases):
            r = ref.follow(
                x0, v0, w0, radius=0.00125, normal=normal, ground=ground, rest_speed=0.2, air=Air(density=1.225) if air else None
            )
            assert STATES[int(end[i])] == r.state, (i, surface, r.state, end[i])
            if r.state != "rest":
                continue
            scale = max(r.path_length, 1e-3)
            assert np.linalg.norm(x[i] - r.x) <= CLOSE[precision] * scale, (i, surface, x[i], r.x, r.path_length)
            assert impacts[i] == r.impacts
            compared += 1
        assert compared == len(cases)  # every case rests (c > 0, slopes below atan(c)): all positions compared


@pytest.mark.parametrize("precision", PRECISIONS)
def test_never_below_the_plane(precision):
    rng = np.random.default_rng(7)
    normal = (0.0, 1.0, 0.0)
    cases = _cases(rng, 40, normal)
    end, x, _path, _impacts = _run(precision, normal, GROUNDS[0], False, cases)
    assert (end == AT_REST).all()
    eps = 1e-12 if precision == "float64" else 1e-5
    assert (x[:, 1] >= 0.00125 - eps * (1 + np.abs(x).max(axis=1))).all()


@pytest.mark.parametrize("precision", PRECISIONS)
def test_the_wind_does_not_blow_along_the_ground(precision):
    """Along a surface the air is still (core/rest.py): pellets rolling on a plane of c = 0.01 under a
    4 m/s wind (drag ~0.4 m/s^2 on them, above 5/7 c g) rest where they rest without it; with the
    wind felt they would roll on until their budget ran out."""
    rng = np.random.default_rng(3)
    surface = {"restitution": 0.3, "mu_s": 0.5, "mu_d": 0.45, "rolling_resistance": 0.01}
    cases = [
        (np.array([0.0, 0.00125, 0.0]), np.array([rng.uniform(1, 30), 0.0, rng.uniform(-5, 5)]), np.zeros(3)) for _ in range(8)
    ]
    calm = _run(precision, (0.0, 1.0, 0.0), surface, True, cases)
    windy = _run(precision, (0.0, 1.0, 0.0), surface, (4.0, 0.0, 3.0), cases)
    assert (calm[0] == AT_REST).all() and (windy[0] == AT_REST).all()
    np.testing.assert_array_equal(windy[1], calm[1])


def test_water_embeds_steep_pellets_and_skips_shallow_ones():
    """Runs to rest over water (`material = "water"`: Johnson's 18 deg / sqrt(SG), 6.8 deg for
    7000 kg/m^3): the paper's 45 deg shot enters at its first impact; a shot 2 deg down skips,
    losing speed at every skip, until it can no longer leave the surface and sinks: embedded."""
    import warp_ricochet as wr

    def run(direction, jitter):
        raw = {
            "shot": {
                "count": 400,
                "speed": 300.0,
                "direction": direction,
                "direction_jitter": jitter,
                "diameter": 0.0025,
                "density": 7000.0,
            },
            "surfaces": [{"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "water"}],
            "physics": {"until": "rest"},
            "output": {"fields": []},
        }
        raw["shot"]["envelope_center"] = [0.0, 1.0, 0.0]
        return wr.run(scene_from_dict(raw), device="cpu")

    steep = run([1.0, -1.0, 0.0], [0.1, 0.1, 0.1])
    assert steep["rest_embedded"] == 400 and steep["rest_impacts_mean"] == 1.0
    assert steep["entered"] == 400 and steep["missed"] == 0 and steep["hits"] == 0  # it hit, without a ricochet
    shallow = run([1.0, -0.035, 0.0], [0.0, 0.002, 0.002])
    assert shallow["entered"] == 0 and shallow["hits"] == 400
    assert shallow["rest_embedded"] == 400 and shallow["rest_impacts_mean"] > 2.0
    assert shallow["rest_distance_min"] > 28.0  # beyond the first contact, about 1 / tan(2 deg) = 28.6 m out
