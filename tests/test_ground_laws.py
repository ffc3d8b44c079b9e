"""The ground's laws at an impact (warp_ricochet.physics.ground) in small CPU kernels, both
precisions: rough ground's draws (keyed by (seed, pellet, impact), their distributions, facing unit
normals, bitwise unchanged without roughness), embedding against a float64 reference, water's
critical angle through the model's surfaces, the skip's speed loss, and no energy gained."""

import math

import numpy as np
import pytest
import warp as wp
from scipy import stats

from warp_ricochet.launch.sampling import reference_uniforms
from warp_ricochet.model import Model
from warp_ricochet.physics.geometry import make_geometry
from warp_ricochet.physics.ground import ABOVE_MODE, make_ground, reference_ground_uniforms
from warp_ricochet.physics.types import types_for
from warp_ricochet.scene import scene_from_dict

PRECISIONS = ("float32", "float64")
EPS = {"float32": 1.2e-7, "float64": 2.3e-16}
N = 100_000


@pytest.fixture(scope="module", autouse=True)
def _warp():
    wp.init()


def material(precision, **values):
    t = types_for(precision)
    m = t.Material()
    defaults = {"restitution": 0.5, "mu_s": 0.5, "mu_d": 0.4, "critical_angle": 0.5 * math.pi}
    for key, value in {**defaults, **values}.items():
        setattr(m, key, wp.int32(value) if key == "liquid" else t.scalar(value))
    return m


def _kernels(precision):
    """The test kernels of one precision (a function of its own: the closures bind its t and g)."""
    t, g = types_for(precision), make_ground(precision)

    @wp.kernel
    def draw_kernel(
        m: t.Material,
        normal: t.vec3,
        velocity: t.vec3,
        seed: wp.int32,
        pellets: wp.array(dtype=wp.int32),
        impacts: wp.array(dtype=wp.int32),
        normals: wp.array(dtype=t.vec3),
        values: wp.array2d(dtype=t.scalar),
    ):
        i = wp.tid()
        drawn, n = g.draw(m, normal, velocity, seed, pellets[i], impacts[i])
        normals[i] = n
        values[i, 0] = drawn.restitution
        values[i, 1] = drawn.mu_s
        values[i, 2] = drawn.mu_d
        values[i, 3] = drawn.rolling_resistance
        values[i, 4] = drawn.critical_angle

    @wp.kernel
    def law_kernel(
        m: t.Material,
        velocities: wp.array(dtype=t.vec3),
        normal: t.vec3,
        embedded: wp.array(dtype=wp.int32),
        skipped: wp.array(dtype=t.vec3),
        sunk: wp.array(dtype=wp.int32),
    ):
        i = wp.tid()
        embedded[i] = g.embeds(m, velocities[i], normal)
        v, _spin = g.skip(m, velocities[i], normal, t.vec3())
        skipped[i] = v
        sunk[i] = g.sinks(m)

    return t, draw_kernel, law_kernel


@pytest.fixture(scope="module")
def kernels():
    return {precision: _kernels(precision) for precision in PRECISIONS}


def draw(kernels, precision, m, normal, velocity, pellets, impacts, seed=11):
    t, kernel, _ = kernels[precision]
    pellets, impacts = np.asarray(pellets, dtype=np.int32), np.asarray(impacts, dtype=np.int32)
    normals = wp.zeros(len(pellets), dtype=t.vec3, device="cpu")
    values = wp.zeros((len(pellets), 5), dtype=t.scalar, device="cpu")
    inputs = [m, t.vec3(*normal), t.vec3(*velocity), seed, wp.array(pellets, device="cpu"), wp.array(impacts, device="cpu")]
    wp.launch(kernel, len(pellets), inputs=[*inputs, normals, values], device="cpu")
    return normals.numpy().astype(np.float64), values.numpy().astype(np.float64)


def laws(kernels, precision, m, velocities, normal):
    t, _, kernel = kernels[precision]
    n = len(velocities)
    embedded, sunk = wp.zeros(n, dtype=wp.int32, device="cpu"), wp.zeros(n, dtype=wp.int32, device="cpu")
    skipped = wp.zeros(n, dtype=t.vec3, device="cpu")
    velocities = wp.array(np.asarray(velocities, dtype=np.dtype(precision)), dtype=t.vec3, device="cpu")
    wp.launch(kernel, n, inputs=[m, velocities, t.vec3(*normal), embedded, skipped, sunk], device="cpu")
    return embedded.numpy(), skipped.numpy().astype(np.float64), sunk.numpy()


@pytest.mark.parametrize("precision", PRECISIONS)
def test_without_roughness_the_inputs_come_back_bitwise(kernels, precision):
    m = material(precision, rolling_resistance=0.1, critical_angle=0.3)
    normal = (0.6, 0.8, 0.0)
    normals, values = draw(kernels, precision, m, normal, (3.0, -7.0, 1.0), range(100), range(100))
    assert (normals == np.asarray(normal, dtype=precision).astype(np.float64)).all()
    want = np.asarray([0.5, 0.5, 0.4, 0.1, 0.3], dtype=precision).astype(np.float64)
    assert (values == want).all()


@pytest.mark.parametrize("precision", PRECISIONS)
def test_draws_depend_only_on_seed_pellet_and_impact(kernels, precision):
    m = material(precision, roughness=0.1, restitution_scatter=0.3, friction_scatter=0.2)
    rng = np.random.default_rng(5)
    pellets, impacts = rng.integers(0, 2**31 - 1, 2000), rng.integers(0, 1000, 2000)
    args = (m, (0.0, 1.0, 0.0), (5.0, -5.0, 0.0))
    whole = draw(kernels, precision, *args, pellets, impacts)
    for start, stop in ((0, 7), (7, 1500), (1500, 2000)):  # any chunking of the same keys
        part = draw(kernels, precision, *args, pellets[start:stop], impacts[start:stop])
        assert (part[0] == whole[0][start:stop]).all() and (part[1] == whole[1][start:stop]).all()
    reversed_ = draw(kernels, precision, *args, pellets[::-1], impacts[::-1])
    assert (reversed_[0][::-1] == whole[0]).all()
    other_seed = draw(kernels, precision, *args, pellets, impacts, seed=12)
    assert (other_seed[1][:, 0] != whole[1][:, 0]).mean() > 0.99
    next_impact = draw(kernels, precision, *args, pellets, impacts + 1)
    assert (next_impact[1][:, 1] != whole[1][:, 1]).mean() > 0.99


def test_the_stream_is_the_documented_one_and_not_the_launchs(kernels):
    sigma = 0.1
    m = material("float64", roughness=sigma)
    pellets, impacts = list(range(50)), [7 * p for p in range(50)]
    normals, _ = draw(kernels, "float64", m, (0.0, 0.0, 1.0), (0.0, 0.0, -1.0), pellets, impacts, seed=3)
    tilts = np.arccos(np.clip(normals[:, 2], -1, 1))
    want = [sigma * math.sqrt(-2.0 * math.log(reference_ground_uniforms(3, p, i)[0])) for p, i in zip(pellets, impacts)]
    np.testing.assert_allclose(tilts, want, rtol=1e-6)
    launch = np.asarray([reference_uniforms(3, p)[:2] for p in pellets])
    ground = np.asarray([reference_ground_uniforms(3, p, 0)[:2] for p in pellets])
    assert not np.isclose(launch, ground, atol=1e-6).any()


@pytest.mark.parametrize("precision", PRECISIONS)
def test_the_draws_follow_their_documented_distributions(kernels, precision):
    sigma, e, s_e, s_mu = math.radians(6.0), 0.5, 0.2, 0.2
    m = material(precision, roughness=sigma, restitution_scatter=s_e, friction_scatter=s_mu, restitution=e)
    normals, values = draw(kernels, precision, m, (0.0, 1.0, 0.0), (0.0, -10.0, 0.0), np.arange(N), np.full(N, 2))
    tilt = np.arccos(np.clip(normals[:, 1], -1, 1))
    assert stats.kstest(tilt, stats.rayleigh(scale=sigma).cdf).pvalue > 1e-3
    azimuth = np.arctan2(normals[:, 2], normals[:, 0])
    assert stats.kstest(azimuth, stats.uniform(-math.pi, 2 * math.pi).cdf).pvalue > 1e-3
    below, above = s_e * e, s_e * e * ABOVE_MODE
    mode = e + below - above
    p_below = below / (below + above)

    def cdf(x):  # the two-sided exponential (Montaine et al.) of mean e
        return np.where(x < mode, p_below * np.exp((x - mode) / below), 1 - (1 - p_below) * np.exp(-(x - mode) / above))

    restitution = values[:, 0]
    assert abs(np.mean(restitution) - e) < 2e-3  # (the clip at 0 adds p_below below exp(-mode/below) = 2.6e-4)
    assert stats.kstest(restitution, cdf).pvalue > 1e-3  # (clipped at 0: that atom is cdf(0), as the test sees it)
    log_factor = np.log(values[:, 1] / 0.5)
    assert stats.kstest(log_factor, stats.norm(-0.5 * s_mu**2, s_mu).cdf).pvalue > 1e-3
    np.testing.assert_allclose(values[:, 2] / values[:, 1], 0.8, rtol=10 * EPS[precision])  # mu_d <= mu_s kept


@pytest.mark.parametrize("precision", PRECISIONS)
def test_tilted_normals_are_unit_and_face_the_pellet_even_grazing(kernels, precision):
    m = material(precision, roughness=math.radians(15.0))
    normal = np.array([0.0, 0.6, 0.8])
    velocity = np.array([100.0, 0.0, 0.0]) - 2.0 * normal  # 1.1 deg from the surface
    normals, _ = draw(kernels, precision, m, normal, velocity, np.arange(N), np.zeros(N))
    assert np.abs(np.linalg.norm(normals, axis=1) - 1.0).max() < 8 * EPS[precision]
    assert (normals @ velocity < 0.0).all()
    assert (np.arccos(np.clip(normals @ normal, -1, 1)) > math.radians(5)).mean() > 0.5  # tilted indeed


@pytest.mark.parametrize("precision", PRECISIONS)
def test_scattered_restitution_stays_in_0_1(kernels, precision):
    m = material(precision, restitution=0.95, restitution_scatter=1.0)
    _, values = draw(kernels, precision, m, (0.0, 1.0, 0.0), (1.0, -1.0, 0.0), np.arange(N), np.ones(N))
    assert values[:, 0].max() <= 1.0 and values[:, 0].min() >= 0.0 and (values[:, 0] == 1.0).any()


@pytest.mark.parametrize("precision", PRECISIONS)
def test_embeds_against_a_float64_reference(kernels, precision):
    theta0, rise, top = math.radians(8.0), math.radians(3.0), 6.0
    m = material(precision, critical_angle=theta0, critical_angle_rise=rise, critical_speed=top)
    rng = np.random.default_rng(9)
    speed = rng.uniform(0.1, 200.0, N)
    angle = rng.uniform(0.0, 0.5 * math.pi, N)
    azimuth = rng.uniform(0.0, 2 * math.pi, N)
    normal = np.array([0.0, 0.0, 1.0])
    v = np.stack([np.cos(angle) * np.cos(azimuth), np.cos(angle) * np.sin(azimuth), -np.sin(angle)], 1) * speed[:, None]
    v = v.astype(precision).astype(np.float64)
    embedded, _, sunk = laws(kernels, precision, m, v, normal)
    speed64 = np.linalg.norm(v, axis=1)
    steepness = np.arcsin(np.clip(-v[:, 2] / speed64, 0, 1))
    critical = theta0 + rise * np.minimum(speed64, top)
    clear = np.abs(steepness - critical) > 1e-5
    assert clear.mean() > 0.99
    np.testing.assert_array_equal(embedded[clear], (steepness > critical)[clear])
    assert embedded.any() and not embedded.all() and not sunk.any()
    never = material(precision)  # critical angle pi/2: no law
    assert not laws(kernels, precision, never, [[0.0, 0.0, -5.0], [1.0, 0.0, -1e3]], normal)[0].any()


@pytest.mark.parametrize("precision", PRECISIONS)
def test_water_critical_angle_and_sinking_through_the_models_surfaces(precision):
    t, geo, g = types_for(precision), make_geometry(precision), make_ground(precision)

    @wp.kernel
    def water_kernel(surfaces: t.Surfaces, velocities: wp.array(dtype=t.vec3), out: wp.array2d(dtype=wp.int32)):
        i = wp.tid()
        m = geo.material(surfaces, 0, t.vec3())
        out[i, 0] = g.embeds(m, velocities[i], geo.normal(surfaces, 0, t.vec3()))
        out[i, 1] = g.sinks(m)

    for density, theta_c in ((11340.0, 5.345), (7850.0, 6.424)):
        raw = {
            "shot": {"count": 1, "diameter": 0.0025, "density": density, "speed": 100.0},
            "surfaces": [{"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "water"}],
            "numerics": {"precision": precision},
        }
        model = Model.from_scene(scene_from_dict(raw), wp.get_device("cpu"))
        angles = np.radians([theta_c - 0.01, theta_c + 0.01, 45.0])
        v = np.stack([np.cos(angles), -np.sin(angles), np.zeros(3)], 1) * 300.0
        out = wp.zeros((3, 2), dtype=wp.int32, device="cpu")
        wp.launch(
            water_kernel, 3, inputs=[model.surfaces, wp.array(v.astype(precision), dtype=t.vec3, device="cpu"), out], device="cpu"
        )
        np.testing.assert_array_equal(out.numpy(), [[0, 1], [1, 1], [1, 1]])


@pytest.mark.parametrize("precision", PRECISIONS)
def test_a_skip_mirrors_the_velocity_and_keeps_exp_minus_2_theta_k_of_the_speed(kernels, precision):
    k = 1.3
    m = material(precision, skip_loss=k, liquid=1, restitution=0.0, mu_s=0.0, mu_d=0.0)
    rng = np.random.default_rng(2)
    angle = rng.uniform(0.0, math.radians(10.0), 1000)
    v = np.stack([np.cos(angle), -np.sin(angle), np.zeros_like(angle)], 1) * rng.uniform(1, 400, (1000, 1))
    v = v.astype(precision).astype(np.float64)
    _, out, sunk = laws(kernels, precision, m, v, (0.0, 1.0, 0.0))
    theta = np.arcsin(-v[:, 1] / np.linalg.norm(v, axis=1))
    keep = np.exp(-2.0 * theta * k)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), keep * np.linalg.norm(v, axis=1), rtol=20 * EPS[precision])
    np.testing.assert_allclose(out[:, 1] / out[:, 0], -v[:, 1] / v[:, 0], rtol=20 * EPS[precision])
    assert (np.linalg.norm(out, axis=1) <= np.linalg.norm(v, axis=1)).all() and sunk.all()
