"""Chokes and shot patterns (scene.patterns, launch.pattern, docs/scenes.md "Chokes and patterns"):
the published percentage inside 30 inches at 40 yards in air, the kernel's draws against the
NumPy reference and against the law, and bad input in one line."""

import functools
import math
import tomllib

import h5py
import numpy as np
import pytest
import warp as wp
from helpers import cli
from scipy import stats

import warp_ricochet as wr
from warp_ricochet.errors import SceneError
from warp_ricochet.launch.source import PelletSource, make_source
from warp_ricochet.physics.types import types_for
from warp_ricochet.reference import launch as reference
from warp_ricochet.report.html_data import scene_words
from warp_ricochet.scene import scene_from_dict
from warp_ricochet.scene.patterns import CHOKES, PATTERN_DISTANCE, PATTERN_RADIUS, inside_fraction, pattern_spread

HEIGHT = 5.0  # m: the muzzle's and the board's centre


def shot(**keys):
    return {"count": 1000, "diameter": 0.00241, "density": 11340.0, "speed": 365.76, "direction": [1.0, 0.0, 0.0], **keys}


def board_scene(n, pattern):
    """US 7.5 lead at 1200 ft/s, fired level at a patterning board (a vertical 8 m square, E = 0) 40 yards
    downrange, in the default air; a ground plane far below."""
    return scene_from_dict(
        {
            "shot": shot(count=n, envelope_center=[0.0, HEIGHT, 0.0], seed=40, **pattern),
            "surfaces": [
                {"name": "board", "point": [PATTERN_DISTANCE, HEIGHT, 0.0], "normal": [-1.0, 0.0, 0.0], "kind": "rectangle"}
                | {"axis_u": [0.0, 1.0, 0.0], "size": [8.0, 8.0], "restitution": 0.0, "mu_s": 0.0},
                {"name": "ground", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.0, "mu_s": 0.0},
            ],
            "physics": {"bounces": 1, "until": "landing"},
            "air": {},
            "output": {"fields": ["impact.position", "impact.surface"], "quantiles": False},
        }
    )


# n = 2^15 pellets a choke: the binomial standard error of a percentage is at most 100 sqrt(0.25 / n) = 0.28
# points, so the 2-point tolerance is 7 standard errors: an exact model fails by chance with p < 1e-11, and a
# model 3 points off passes by chance with p < 2e-4
BOARD_PELLETS = 1 << 15


@pytest.mark.parametrize("choke", list(CHOKES))
def test_the_percentage_inside_30_inches_at_40_yards_in_air_is_the_published_one(tmp_path, choke):
    """The board read as a patterning board is: the 30-inch circle centred on the pattern (the mean
    hit), which a gun's sights are regulated to; the aim point of the bore line lies ~9 cm above it,
    the drop over 40 yards (a full choke's count there is 67%, not 70%)."""
    pattern = {"pattern": CHOKES[choke]} if choke == "modified" else {"choke": choke}  # (either key)
    path = tmp_path / "board.h5"
    wr.run(board_scene(BOARD_PELLETS, pattern), path, device="cpu", sidecar=False)
    with h5py.File(path) as f:
        hits = f["pellets/impact/position"][:, 0].astype(np.float64)
        on_board = f["pellets/impact/surface"][:, 0] == 0
        assert f["constants/pattern"][()] == CHOKES[choke] and f["constants/pattern"].attrs["units"] == "percent"
        launch = scene_words(f, tomllib.loads(f.attrs["scene_toml"]), {})["launch"]  # the HTML report's words
        assert f"{CHOKES[choke]:g}% in a 30-inch circle at 40 yards" in launch and "jitter" not in launch
        assert (f"{choke} choke" in launch) == ("choke" in pattern)
    assert on_board.all()  # the board holds the whole pattern: the percentage is of every pellet
    yz = hits[:, 1:]
    centre = yz.mean(axis=0)
    assert 0.05 < HEIGHT - centre[0] < 0.15  # the drop
    inside = np.linalg.norm(yz - centre, axis=1) <= PATTERN_RADIUS
    percent = 100.0 * inside.mean()
    assert abs(percent - CHOKES[choke]) <= 2.0, (choke, percent)


def test_the_fit_is_the_closed_form_inverse_of_the_model():
    for percent in (*CHOKES.values(), 0.5, 99.5):
        s = pattern_spread(percent)
        assert inside_fraction(s, PATTERN_RADIUS, PATTERN_DISTANCE) == pytest.approx(percent / 100.0, rel=1e-12)
    assert pattern_spread(70.0) < pattern_spread(40.0) < 0.0105  # ~ rad; a full choke's pattern is the tightest


@functools.cache
def launch_kernel(precision):
    """A kernel writing `launch_state` of global indices, as the core kernel draws them (pattern compiled in)."""
    src, vec3 = make_source(precision, False, True), types_for(precision).vec3

    @wp.kernel(module="unique", enable_backward=False)
    def launch(source: src.Source, index: wp.array(dtype=wp.int32), velocity: wp.array(dtype=vec3)):
        i = wp.tid()
        _position, v, _spin = src.launch_state(source, index[i], i)
        velocity[i] = v

    return launch


AIMS = ([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.0, -1.0, 0.0], [1e-30, -1e-30, 0.0], [1.0, -1.0, 1e-9], [-3.0, 0.5, -2.0])


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_the_kernels_pattern_draws_are_the_references_for_any_seed_aim_and_index(precision):
    """`launch.pattern` against `reference.launch`, pellet by pellet: random seeds, the poles, tiny
    and arbitrary aims, and indices across the int32 range (the draw depends on (seed, index) only)."""
    rng = np.random.default_rng(28)
    kernel, vec3 = launch_kernel(precision), types_for(precision).vec3
    tolerance = 1e-13 if precision == "float64" else 1e-6  # of the speed
    for aim in AIMS:
        seed, percent = int(rng.integers(0, 2**31)), float(rng.uniform(1.0, 99.0))
        scene = scene_from_dict(
            {"shot": shot(direction=aim, pattern=percent, seed=seed), "surfaces": [], "numerics": {"precision": precision}}
        )
        index = np.concatenate([[0, 1, 65_535, 65_536, 2**31 - 1], rng.integers(0, 2**31, 2000)]).astype(np.int32)
        velocity = wp.empty(len(index), dtype=vec3, device="cpu")
        source = PelletSource(scene, precision, "cpu", 0).struct
        wp.launch(kernel, dim=len(index), inputs=[source, wp.array(index, dtype=wp.int32, device="cpu"), velocity], device="cpu")
        _p, expected, _w = reference.launch_states(scene.shot, index)
        np.testing.assert_allclose(velocity.numpy(), expected, rtol=0, atol=tolerance * scene.shot.speed, err_msg=str(aim))


def test_a_runs_polar_angles_follow_the_law_and_do_not_depend_on_the_chunks(tmp_path):
    """70,000 pellets in two chunks (float64): each launch velocity is the reference's for its global
    index, and their polar angles follow the inverse-CDF law P(tan theta <= x) = 1 - exp(-x^2 / 2 s^2)
    (Kolmogorov-Smirnov), their azimuths uniform."""
    aim = np.array([1.0, -0.3, 0.2])
    raw = {
        "shot": shot(count=70_000, direction=aim.tolist(), choke="improved cylinder", seed=7),
        "surfaces": [{"point": [0.0, -1.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.0, "mu_s": 0.0}],
        "numerics": {"precision": "float64", "chunk_size": 65_536},
        "output": {"fields": ["initial.velocity"], "quantiles": False},
    }
    scene = scene_from_dict(raw)
    wr.run(scene, tmp_path / "l.h5", device="cpu", sidecar=False)
    with h5py.File(tmp_path / "l.h5") as f:
        velocity = f["pellets/initial/velocity"][()]
    _p, expected, _w = reference.launch_states(scene.shot, np.arange(70_000))
    np.testing.assert_allclose(velocity, expected, rtol=0, atol=1e-13 * scene.shot.speed)
    a = aim / np.linalg.norm(aim)
    along = velocity @ a
    across = velocity - along[:, None] * a
    s = scene.shot.pattern_spread
    law = stats.kstest(np.linalg.norm(across, axis=1) / along, lambda x: -np.expm1(-(x**2) / (2 * s * s)))
    assert law.pvalue > 1e-3, law
    e1 = np.cross(a, [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1)
    azimuth = np.arctan2(across @ np.cross(a, e1), across @ e1)
    assert stats.kstest(azimuth, stats.uniform(-math.pi, 2 * math.pi).cdf).pvalue > 1e-3


@pytest.mark.parametrize(
    "keys, key, says",
    [
        ({"choke": "modifed"}, "shot.choke", "did you mean modified?"),
        ({"choke": "extra full"}, "shot.choke", "'cylinder', 'skeet', 'improved cylinder'"),
        ({"pattern": 0}, "shot.pattern", "(0, 100)"),
        ({"pattern": 100}, "shot.pattern", "(0, 100)"),
        ({"pattern": "60 m"}, "shot.pattern", "(percent)"),
        ({"choke": "full", "pattern": 70}, "shot.pattern", "not allowed together with shot.choke"),
        ({"choke": "full", "direction_jitter": [0.1, 0.1, 0.1]}, "shot.direction_jitter", "must be 0 with shot.choke"),
        ({"pattern": 55, "direction_jitter": 0.01}, "shot.direction_jitter", "must be 0 with shot.pattern"),
        ({"choke": "full", "file": "pellets.npz"}, "shot.choke", "not allowed together with shot.file"),
    ],
)
def test_bad_chokes_and_patterns_are_one_line_errors(keys, key, says):
    with pytest.raises(SceneError) as exc:
        scene_from_dict({"shot": shot(**keys), "surfaces": []})
    assert exc.value.key == key and says in str(exc.value) and "\n" not in str(exc.value)


def test_the_cli_refuses_a_bad_choke_before_any_work(tmp_path):
    rc, out, err = cli(["run", "examples/paper.toml", "--device", "cpu", "-o", tmp_path / "o.h5", "--set", 'shot.choke="full"'])
    assert rc == 2 and out == "" and len(err.splitlines()) == 1 and "shot.direction_jitter" in err
    assert not (tmp_path / "o.h5").exists()
