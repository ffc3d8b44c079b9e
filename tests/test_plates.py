"""Finite plates (docs/geometry.md): rectangles and discs in the core kernel, in vacuum and in air.

A plate as large as the map is the plane; the pellets that hit a plate are those whose launch
parabola (NumPy float64) crosses its plane inside it; a two-sided plate is met from behind; in air
the hit count is SciPy's; along a plate a pellet rolls off its edge; bad plate keys are one line."""

import math

import h5py
import numpy as np
import pytest
from helpers import cli, explicit_scene, make_scene, paper_raw, stats_equal
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from warp_ricochet.api import run
from warp_ricochet.scene import scene_from_dict

RADIUS, DENSITY = 0.00125, 7000.0  # explicit_scene's pellet
GRAVITY = np.array([0.0, 0.0, -9.81])
PRECISIONS = ["float32", "float64"]
MATERIAL = {"restitution": 0.5, "mu_s": 0.3}
LANDING = {"gravity": list(GRAVITY), "until": "landing", "bounces": 1}
GROUND = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], **MATERIAL}


def _first_impacts(scene, tmp_path, name="run.h5"):
    """Per pellet: the surface of its first impact (-1 none), and its rest or landing position."""
    fields = ("impact.surface", "rest.position") if scene.physics.until == "rest" else ("impact.surface", "landing.position")
    scene = scene.replace(output=scene.output.__class__(**{**scene.output.__dict__, "fields": fields}))
    run(scene, tmp_path / name, device="cpu", overwrite=True)
    with h5py.File(tmp_path / name) as f:
        surface = f["pellets/impact/surface"][()]
        where = f["pellets/rest/position" if scene.physics.until == "rest" else "pellets/landing/position"][()]
    return surface.reshape(len(surface), -1)[:, 0], where


def _frame(normal, axis_u):
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    u = np.asarray(axis_u, float) - np.dot(axis_u, n) * n
    u /= np.linalg.norm(u)
    return n, u, np.cross(n, u)


def _inside(plate, x):
    """Whether the points x (N, 3) project onto the plate, and their margin to its edge (m)."""
    other = [1.0, 0.0, 0.0] if abs(plate["normal"][0]) < 0.5 else [0.0, 1.0, 0.0]  # a disc's: any in-plane axis
    n, u, v = _frame(plate["normal"], plate.get("axis_u", np.cross(plate["normal"], other)))
    d = x - np.asarray(plate["point"], float)
    a, b = d @ u, d @ v
    if plate["kind"] == "disc":
        margin = plate["radius"] - np.hypot(a, b)
    else:
        margin = np.minimum(0.5 * plate["size"][0] - np.abs(a), 0.5 * plate["size"][1] - np.abs(b))
    return margin >= 0, np.abs(margin)


def _parabola_hits(plate, x0, v0, gravity=GRAVITY):
    """Eq. (36) against the plate's front face in float64: the closing root of the gap
    n.(x - p) - R (centres in front at launch), and whether its point is on the plate; with the
    distance of that point from the plate's edge (inf: no root)."""
    n = np.asarray(plate["normal"], float) / np.linalg.norm(plate["normal"])
    h0 = (x0 - np.asarray(plate["point"], float)) @ n - RADIUS
    vn, half = v0 @ n, 0.5 * (gravity @ n)
    assert np.all(h0 > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        if half == 0:
            t = np.where(vn < 0, -h0 / vn, np.nan)
        else:
            root = np.sqrt(vn * vn - 4 * half * h0)
            t = np.where(vn >= 0, -(vn + root) / (2 * half), 2 * h0 / (root - vn))
    ok = np.isfinite(t) & (t > 0)
    t = np.where(ok, t, 0.0)
    x = x0 + v0 * t[:, None] + 0.5 * gravity * (t * t)[:, None]
    on, margin = _inside(plate, x)
    return ok & on, np.where(ok, margin, np.inf)


def _shots(rng, n, target, spread, speed=60.0):
    """n pellets from near the origin aimed at `target` with an angular spread (rad)."""
    x0 = rng.uniform(-0.05, 0.05, (n, 3)) + [0.0, 0.0, 1.0]
    aim = np.asarray(target, float) - x0
    aim /= np.linalg.norm(aim, axis=1)[:, None]
    v0 = speed * (aim + rng.normal(0, spread, (n, 3)))
    return x0, v0


def _stats_run(raw, precision):
    return run(make_scene(raw, precision=precision), device="cpu")


@pytest.mark.parametrize("precision", PRECISIONS)
@pytest.mark.parametrize("until", ["landing", "rest"])
def test_a_plate_as_large_as_the_map_lands_as_the_plane(precision, until):
    """The paper's plane and a one-sided rectangle of 2000 km in it: the same statistics, bitwise."""
    plane = paper_raw(until=until, bounces=2)
    plate = paper_raw(until=until, bounces=2)
    plate["surfaces"] = [{**plate["surfaces"][0], "kind": "rectangle", "axis_u": [1.0, 0.0, 0.0], "size": [2e6, 2e6]}]
    a, b = _stats_run(plane, precision), _stats_run(plate, precision)
    assert a["hits"] > 0
    assert stats_equal(a, b)


@pytest.mark.parametrize("precision", PRECISIONS)
@settings(max_examples=6, deadline=None)
@given(
    kind=st.sampled_from(["rectangle", "disc"]),
    tilt=st.floats(-0.6, 0.6),
    turn=st.floats(0.0, 2 * math.pi),
    size=st.tuples(st.floats(0.2, 1.5), st.floats(0.2, 1.5)),
    seed=st.integers(0, 2**16),
)
def test_the_pellets_that_hit_a_plate_are_those_whose_lines_cross_it(tmp_path_factory, precision, kind, tilt, turn, size, seed):
    """Issue 27's count: each pellet's first impact is on the plate exactly when its launch parabola
    crosses the plate's plane inside it (pellets within 1 mm of the edge left out of the draw)."""
    rng = np.random.default_rng(seed)
    normal = [-math.cos(tilt), 0.3 * math.sin(turn), math.sin(tilt)]
    plate = {"point": [8.0, 0.0, 1.0], "normal": normal, **MATERIAL, "kind": kind}
    n, _u, _v = _frame(normal, [0.0, 0.0, 1.0])
    if kind == "disc":
        plate["radius"] = size[0] / 2
    else:
        plate["axis_u"] = list(np.cross(n, [0.0, math.cos(turn), math.sin(turn)]) + 0.0)
        plate["size"] = list(size)
    x0, v0 = _shots(rng, 600, plate["point"], 0.06)
    hits, margin = _parabola_hits(plate, x0, v0)
    keep = margin > 1e-3
    x0, v0, hits = x0[keep], v0[keep], hits[keep]
    assert 0 < hits.sum() < len(hits)
    scene = explicit_scene(tmp_path_factory.mktemp("p"), x0, v0, surfaces=[plate, GROUND], precision=precision, physics=LANDING)
    first, _where = _first_impacts(scene, tmp_path_factory.mktemp("o"))
    np.testing.assert_array_equal(first == 0, hits)


@pytest.mark.parametrize("precision", PRECISIONS)
def test_a_two_sided_plate_is_met_from_behind(tmp_path, precision):
    """Pellets fired at a vertical disc's back hit a two-sided one (and bounce back towards -x: they
    land behind it) and pass a one-sided one; pellets thrown up beside a level two-sided disc from
    below come down on its top (its far face, met after passing its plane beside it)."""
    rng = np.random.default_rng(7)
    x0, v0 = _shots(rng, 40, [8.0, 0.0, 1.0], 0.003)
    back = {"point": [8.0, 0.0, 1.0], "normal": [-1.0, 0.0, 0.0], **MATERIAL, "kind": "disc", "radius": 0.5}
    up_x = np.column_stack([np.full(20, 20.3), np.zeros(20), np.full(20, 0.5)])
    up_v = np.column_stack([rng.uniform(-0.5, -0.3, 20), rng.uniform(-0.1, 0.1, 20), np.full(20, 5.0)])
    level = {"point": [20.0, 0.0, 1.0], "normal": [0.0, 0.0, 1.0], **MATERIAL, "kind": "disc", "radius": 0.25}
    x, v = np.concatenate([x0, up_x]), np.concatenate([v0, up_v])
    for two_sided in (True, False):
        surfaces = [{**back, "normal": [1.0, 0.0, 0.0], "two_sided": two_sided}, {**level, "two_sided": two_sided}, GROUND]
        scene = explicit_scene(tmp_path, x, v, surfaces=surfaces, precision=precision, physics=LANDING)
        first, where = _first_impacts(scene, tmp_path, f"{two_sided}.h5")
        if two_sided:
            np.testing.assert_array_equal(first, [0] * 40 + [1] * 20)
            assert np.all(where[:40, 0] < 8.0)  # bounced back off the disc's back
            landed = np.minimum(np.abs(where[40:, 2] - RADIUS), np.abs(where[40:, 2] - 1.0 - RADIUS))
            assert np.all(landed < 1e-5)  # then off its top onto it again or onto the ground
        else:
            np.testing.assert_array_equal(first, 2)  # through both: the ground
            assert np.all(where[:40, 0] > 8.0)


def _drag_hits(plate, x0, v0, cd, rho):
    """The constant drag law's flight (a = g - q C_D |v| v, q = rho A / (2 m)) by SciPy's DOP853 at
    rtol 1e-12 to the plate plane's contact (n.(x - p) = R, closing): on the plate?, edge margin."""
    mass = DENSITY * 4.0 / 3.0 * math.pi * RADIUS**3
    q = rho * math.pi * RADIUS**2 / (2.0 * mass) * cd
    n = np.asarray(plate["normal"], float) / np.linalg.norm(plate["normal"])
    p = np.asarray(plate["point"], float)

    def rates(_t, y):
        v = y[3:]
        return np.concatenate([v, GRAVITY - q * np.linalg.norm(v) * v])

    def contact(_t, y):
        return (y[:3] - p) @ n - RADIUS

    contact.terminal, contact.direction = True, -1
    hits, margins = [], []
    for x, v in zip(x0, v0):
        sol = solve_ivp(rates, (0.0, 5.0), np.concatenate([x, v]), method="DOP853", rtol=1e-12, atol=1e-12, events=contact)
        if sol.t_events[0].size:
            on, margin = _inside(plate, sol.y_events[0][:, :3])
            hits.append(bool(on[0]))
            margins.append(margin[0])
        else:
            hits.append(False)
            margins.append(np.inf)
    return np.array(hits), np.array(margins)


@pytest.mark.parametrize("precision", PRECISIONS)
def test_in_air_the_pellets_that_hit_a_plate_are_scipys(tmp_path, precision):
    """In air (constant C_D, no lift): a tilted rectangle's hits, pellet by pellet, are those of
    SciPy's float64 flight (pellets within 1 mm of its edge left out of the draw)."""
    rng = np.random.default_rng(11)
    n = np.array([-0.9, 0.2, 0.3]) / np.linalg.norm([-0.9, 0.2, 0.3])
    plate = {"point": [10.0, 0.0, 1.0], "normal": list(n), **MATERIAL, "kind": "rectangle"}
    plate["axis_u"], plate["size"] = list(np.cross(n, [0.0, 0.0, 1.0])), [1.2, 0.7]
    x0, v0 = _shots(rng, 300, [10.0, 0.0, 1.3], 0.08, speed=120.0)
    hits, margin = _drag_hits(plate, x0, v0, cd=0.47, rho=1.225)
    keep = margin > 1e-3
    assert keep.sum() > 250 and 0 < hits[keep].sum() < keep.sum()
    scene = explicit_scene(tmp_path, x0[keep], v0[keep], surfaces=[plate, GROUND], precision=precision, physics=LANDING)
    air = {"density": 1.225, "drag": "constant", "drag_coefficient": 0.47, "magnus": False, "spin_decay": False}
    scene = scene_from_dict({**scene.to_dict(), "air": air})
    first, _where = _first_impacts(scene, tmp_path)
    np.testing.assert_array_equal(first == 0, hits[keep])


@pytest.mark.parametrize("precision", PRECISIONS)
@pytest.mark.parametrize("air", [False, True], ids=["vacuum", "air"])
def test_a_pellet_rolls_off_a_plates_edge_and_flies_on(tmp_path, precision, air):
    """until = "rest": pellets landing on a level 2 m square 1 m up roll off its edge at x = 1 m
    and come to rest on the ground beyond it; on a plane in its place they rest on that plane."""
    n = 8
    x0 = np.column_stack([np.linspace(-0.4, 0.4, n), np.zeros(n), np.full(n, 1.2)])
    v0 = np.column_stack([np.full(n, 3.0), np.zeros(n), np.full(n, -0.5)])
    top = {"point": [0.0, 0.0, 1.0], "normal": [0.0, 0.0, 1.0], "restitution": 0.1, "mu_s": 0.3, "rolling_resistance": 0.01}
    ground = {**GROUND, "restitution": 0.1, "mu_s": 0.5, "rolling_resistance": 0.3}
    physics = {"gravity": list(GRAVITY), "until": "rest"}
    ends = []
    for plate in ({**top, "kind": "rectangle", "axis_u": [1.0, 0.0, 0.0], "size": [2.0, 2.0]}, top):
        scene = explicit_scene(tmp_path, x0, v0, surfaces=[plate, ground], precision=precision, physics=physics)
        if air:
            scene = scene_from_dict({**scene.to_dict(), "air": {"density": 1.225}})
        first, where = _first_impacts(scene, tmp_path, f"{len(ends)}.h5")
        np.testing.assert_array_equal(first, 0)
        ends.append(where)
    off, on = ends
    assert np.all(off[:, 0] > 1.0) and np.allclose(off[:, 2], RADIUS, atol=1e-5)
    assert np.allclose(on[:, 2], 1.0 + RADIUS, atol=1e-5) and np.all(on[:, 0] > 1.0)


@pytest.mark.parametrize(
    ("surface", "key"),
    [
        ({"kind": "cone"}, "surfaces.0.kind"),
        ({"kind": "cylinder"}, "surfaces.0.radius"),
        ({"kind": "rectangle", "size": [1.0, 1.0]}, "surfaces.0.axis_u"),
        ({"kind": "rectangle", "axis_u": [0.0, 1.0, 0.0], "size": [0.0, 1.0]}, "surfaces.0.size"),
        ({"kind": "rectangle", "axis_u": [0.0, 1.0, 0.0], "size": [1.0]}, "surfaces.0.size"),
        ({"kind": "rectangle", "axis_u": [1.0, 0.0, 0.1], "size": [1.0, 1.0]}, "surfaces.0.axis_u"),
        ({"kind": "disc", "radius": 0.0}, "surfaces.0.radius"),
        ({"kind": "disc"}, "surfaces.0.radius"),
        ({"kind": "disc", "radius": 1.0, "size": [1.0, 1.0]}, "surfaces.0.size"),
        ({"size": [1.0, 1.0]}, "surfaces.0.size"),
        ({"two_sided": True}, "surfaces.0.two_sided"),
        ({"kind": "disc", "radius": 1.0, "two_sided": 1}, "surfaces.0.two_sided"),
    ],
)
def test_bad_plate_keys_are_one_line_errors_before_any_work(tmp_path, surface, key):
    rc, _out, err = _cli_run(tmp_path, {**GROUND, "normal": [1.0, 0.0, 0.0], **surface})
    assert rc == 2 and err.count("\n") == 1 and err.startswith(f"warp-ricochet: error: {key} = "), err
    assert not (tmp_path / "out.h5").exists()


def _cli_run(tmp_path, surface, **tables):
    from warp_ricochet.scene.toml_out import toml_lines

    raw = {
        "shot": {"count": 4, "diameter": 0.0025, "density": 7000.0, "speed": 50.0, "direction": [1.0, 0.0, 0.0]},
        "surfaces": [surface],
        **tables,
    }
    path = tmp_path / "scene.toml"
    path.write_text("\n".join(toml_lines(raw, "")))
    return cli(["run", path, "--device", "cpu", "-o", tmp_path / "out.h5"])


def test_a_plate_is_refused_as_the_hazards_ground(tmp_path):
    disc = {**GROUND, "kind": "disc", "radius": 1.0}
    rc, _out, err = _cli_run(tmp_path, disc, hazard={"speed": {"fast": 50.0}})
    assert rc == 2 and "hazard.map_surface" in err and err.count("\n") == 1, err
    assert not (tmp_path / "out.h5").exists()
    with pytest.raises(ValueError, match="not a plane"):
        from warp_ricochet.physics.geometry import project

        scene = make_scene(paper_raw(), surfaces=[disc])
        project(scene.surfaces[0], np.zeros(3))


def _with_and_without_pairs(tmp_path, raw, precision, fields=None):
    """The run of `raw` without pair collisions and with them (launch overlaps kept): per pellet
    its output fields (its defaults, or `fields`), and the run's statistics."""
    runs = []
    for name, collisions in (("off", {}), ("on", {"collisions": {"enabled": True, "separate": False}})):
        scene = make_scene({**raw, **collisions}, precision=precision)
        if fields is not None:  # (collision fields with collisions only)
            kept = tuple(f for f in fields if collisions or not f.startswith("collisions."))
            scene = scene.replace(output=scene.output.__class__(**{**scene.output.__dict__, "fields": kept}))
        stats = run(scene, tmp_path / f"{name}.h5", device="cpu", overwrite=True)
        with h5py.File(tmp_path / f"{name}.h5") as f:
            runs.append(({k: f["pellets/" + k.replace(".", "/")][()] for k in scene.output.fields}, stats))
    return runs


@pytest.mark.parametrize("precision", PRECISIONS)
def test_with_collisions_a_sparse_cloud_meets_plates_as_without(tmp_path, precision):
    """Pellets metres apart (no pair can meet) through the dense phase and then the core: the
    same bits, pellet by pellet, and the same statistics as the core alone, with a two-sided
    rectangle facing down that some meet on its back (its normal turned up) and some pass by
    onto the ground below it."""
    raw = paper_raw()
    raw["shot"].update(count=200, envelope_radius=20.0)
    plate = {**raw["surfaces"][0], "kind": "rectangle", "point": [1.0, 0.0, 0.0], "normal": [0.0, -1.0, 0.0]}
    plate.update(axis_u=[1.0, 0.0, 0.0], size=[20.0, 30.0], two_sided=True)  # met on its back face, from above
    raw["surfaces"] = [plate, {**raw["surfaces"][0], "point": [0.0, -1.0, 0.0]}]
    (off, stats_off), (on, stats) = _with_and_without_pairs(tmp_path, raw, precision)
    assert stats["pair_collisions"] == 0
    first = on["impact.surface"][:, 0]
    assert (first == 0).sum() > 20 and (first == 1).sum() > 20
    for name, value in off.items():
        np.testing.assert_array_equal(on[name], value, err_msg=name)
    # (the first impacts' sums from the release: its normals.) Followed to rest with collisions, a
    # core thread sums 16 consecutive pellets (`RunSpec.thread_pieces`); the core alone strides its
    # threads' pellets 4,096 apart: float32's per-thread sums round otherwise (3.5e-8 relative here)
    rel = 1e-12 if precision == "float64" else 1e-6
    for key, value in stats_off.items():
        assert stats[key] == pytest.approx(value, rel=rel, abs=1e-12, nan_ok=True), key


@pytest.mark.parametrize(("precision", "bound"), [("float32", 1e-3), ("float64", 1e-5)])
def test_in_air_a_sparse_cloud_lands_on_plates_as_without_collisions(tmp_path, precision, bound):
    """The sparse cloud of the test above in air (spinning, two ricochets): each pellet's first
    surface is the collisions-off run's, and it lands within `bound` of the distance it flew
    from where that run lands it (the dense phase's kicks against the core's integrated flight,
    as for planes: docs/collisions.md). float32: 5.1e-4 at most, a 2 m flight with two grazing
    ground bounces; the same cloud with the ground alone gives 5.5e-4 there (1e-4 is
    tests/test_air_dense.py's bound on a scene of longer flights)."""
    raw = paper_raw(until="landing", bounces=2)
    raw["shot"].update(count=120, envelope_radius=15.0, spin=[0.0, 0.0, 2000.0])
    raw["air"] = {"density": 1.225}
    plate = {**raw["surfaces"][0], "kind": "rectangle", "point": [1.0, 0.0, 0.0], "normal": [0.0, -1.0, 0.0]}
    plate.update(axis_u=[1.0, 0.0, 0.0], size=[20.0, 30.0], two_sided=True)
    raw["surfaces"] = [plate, {**raw["surfaces"][0], "point": [0.0, -1.0, 0.0]}]
    fields = ["initial.position", "impact.surface", "landing.position"]
    (off, _), (on, stats) = _with_and_without_pairs(tmp_path, raw, precision, fields)
    assert stats["pair_collisions"] == 0 and stats["dense_steps_mean"] > 100
    first = off["impact.surface"][:, 0]
    assert (first == 0).sum() > 10 and (first == 1).sum() > 10
    np.testing.assert_array_equal(on["impact.surface"][:, 0], first)
    flown = np.linalg.norm(off["landing.position"] - off["initial.position"], axis=1).astype(float)
    landed = np.isfinite(flown)
    assert landed.sum() > 20
    error = np.linalg.norm((on["landing.position"] - off["landing.position"]).astype(float), axis=1)[landed] / flown[landed]
    assert error.max() < bound, error.max()


@pytest.mark.parametrize("precision", PRECISIONS)
def test_with_collisions_a_small_plate_is_hit_as_the_lines_cross_it(tmp_path, precision):
    """The paper's shot in an envelope of 10 cm (launch overlaps kept: pair collisions in flight
    and between rebounds and the pellets still coming) at a disc of 10 cm radius across its path: a pellet that never collided meets it exactly when its launch
    parabola crosses it (those within 0.1 mm of its edge left out) and passes by onto the ground
    otherwise, as without collisions; the hit count moves by at most the pellets that collided."""
    raw = paper_raw(until="landing", bounces=1)
    raw["shot"]["envelope_radius"] = 0.1
    axis = np.array([-1.0, 1.0, 0.0]) / math.sqrt(2.0)
    disc = {**raw["surfaces"][0], "kind": "disc", "point": [0.5, 0.5, 0.0], "normal": list(axis), "radius": 0.1}
    raw["surfaces"] = [disc, raw["surfaces"][0]]
    fields = ["initial.position", "initial.velocity", "impact.surface", "collisions.count"]
    (off, _), (on, stats) = _with_and_without_pairs(tmp_path, raw, precision, fields)
    assert stats["pair_collisions"] > 20
    calm = on["collisions.count"] == 0
    first_on, first_off = on["impact.surface"][:, 0], off["impact.surface"][:, 0]
    x0, v0 = on["initial.position"].astype(float), on["initial.velocity"].astype(float)
    hits, margin = _parabola_hits(disc, x0, v0, gravity=np.array([0.0, -9.81, 0.0]))
    clear = calm & (margin > 1e-4)
    assert 20 < hits[clear].sum() < clear.sum() - 20
    np.testing.assert_array_equal(first_on[clear] == 0, hits[clear])
    np.testing.assert_array_equal(first_on[clear & ~hits], 1)  # passed by, onto the ground
    np.testing.assert_array_equal(first_on[calm], first_off[calm])
    assert abs(int((first_on == 0).sum()) - int((first_off == 0).sum())) <= (~calm).sum()


def test_a_leap_ends_before_a_pellet_behind_a_one_sided_plate_can_come_onto_it(device):
    """dense.leap's plane_leap: a pellet below a level one-sided disc, beside it, rising, may pass
    its plane and fall back onto its top: the leap ends no later than its centre can be R above
    the plane (gravity, and the air's bound pushing it up); below a plane, or falling, never."""
    import dataclasses

    import warp as wp
    from test_air_leaps import _physics, _spec

    from warp_ricochet.dense.leap import make_leap
    from warp_ricochet.physics.types import surfaces_of, types_for
    from warp_ricochet.scene.schema import Air

    t = types_for("float64")
    plane_leap = make_leap(dataclasses.replace(_spec(Air()), plates=True)).plane_leap

    @wp.kernel(enable_backward=False, module="unique")
    def planes(
        x: wp.array(dtype=wp.vec3d),
        v: wp.array(dtype=wp.vec3d),
        bound: wp.array(dtype=wp.float64),
        surfaces: t.Surfaces,
        physics: t.Physics,
        out: wp.array(dtype=wp.float64),
    ):
        i = wp.tid()
        out[i] = plane_leap(x[i], v[i], bound[i], surfaces, physics)

    x = np.array([[0.4, 0.5, 0.0], [0.4, 0.5, 0.0], [0.4, 0.5, 0.0]])
    v = np.array([[0.0, 5.0, 0.0], [0.0, 5.0, 0.0], [0.0, -5.0, 0.0]])
    bound = np.array([0.0, 3.0, 0.0])
    delays = {}
    for kind, plate in (("disc", ("disc", (1.0, 0.0, 0.0), 0.25, 0.25, False)), ("plane", None)):
        surfaces = surfaces_of("float64", [[0.0, 1.0, 0.0]], [[0.0, 1.0, 0.0]], [[0.5, 0.5, 0.5]], device, plates=[plate])
        out = wp.zeros(3, dtype=wp.float64, device=device)
        arrays = [wp.array(a, dtype=wp.vec3d, device=device) for a in (x, v)] + [wp.array(bound, dtype=wp.float64, device=device)]
        wp.launch(planes, dim=3, inputs=[*arrays, surfaces, _physics(Air(), "float64", device), out], device=device)
        delays[kind] = out.numpy()
    rise = 1.0 + RADIUS - 0.5  # (centre from 0.5 to R above the plane at 1)
    for k in (0, 1):
        a = 9.81 - bound[k]  # net downward acceleration
        exact = (5.0 - math.sqrt(25.0 - 2.0 * a * rise)) / a
        assert 0.0 < delays["disc"][k] <= exact * (1 + 1e-12)
    assert delays["disc"][1] < delays["disc"][0]
    assert delays["disc"][2] >= 1e30 and (delays["plane"] >= 1e30).all()  # NEVER
