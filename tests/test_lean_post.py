"""Leaning posts followed to rest (issue 27; docs/geometry.md, "Along a leaning side"): a pellet that
stays on a leaning post's side moves on the cylinder r + R about its axis (`physics/side_follow.py`)
until it rests, lifts off (N = 0, its centripetal term included), passes an end or meets another
surface. The analytic cases (the frictionless slide off a level post at cos = 2/3, rolling and
sliding straight down a leaning post's top generator, rest within atan(c) of a level post's top),
the float64 SciPy reference (`reference/side_motion.py`) on seeded random leans, speeds, spins and
frictions, and whole runs: pellets dropped onto a leaning post all end, none inside it, none gaining
energy, in vacuum and in air; chunks and a resume give the same bits. CPU, float32 and float64."""

import math
import warnings

import h5py
import numpy as np
import pytest
from helpers import assert_same_run, explicit_scene, interrupt_after, paper_raw

import warp_ricochet as wr
from bench.surface import follow_pellets
from warp_ricochet.ends import AT_REST
from warp_ricochet.physics.geometry import LEANING, MESHES, NO_EDGES, SMALL
from warp_ricochet.physics.surface_follow import FLIGHT, REST
from warp_ricochet.reference.side_motion import follow_side
from warp_ricochet.scene import scene_from_dict

R = 0.00125  # m, the pellets' radius
G = 9.81  # m/s^2, along -y
K = 0.4  # I = K m R^2
POSTS = MESHES | SMALL | NO_EDGES | LEANING  # the kernels' `plates` for a scene of planes and leaning posts
PRECISIONS = ["float64", "float32"]
CLOSE = {"float64": 1e-7, "float32": 2e-5}  # relative: closed forms against the integrated side
PLACED = {"float64": 1e-14, "float32": 1e-6}  # m: a centre within 2 m of the origin, as rounded


def _on_post(precision, point, axis, radius, length, x, v, w, **kw):
    """`surface_follow.follow` of pellets on the side of a post (surface 1; the ground y = -100 m is 0)."""
    planes = [((0.0, -100.0, 0.0), (0.0, 1.0, 0.0)), (tuple(point), tuple(axis))]
    plates = [None, ("cylinder", (0.0, 0.0, 0.0), radius, length, False)]
    return follow_pellets(precision, planes, x, v, w, radius=R, k=1, plates=plates, compiled=POSTS, **kw)


def _energy(x, v, w):
    """Mechanical energy per unit mass (J/kg): translation, spin and height."""
    return 0.5 * (v**2).sum(axis=-1) + 0.5 * K * R**2 * (w**2).sum(axis=-1) + G * x[..., 1]


def _lean_frame(lean):
    """A post's axis leaning `lean` (rad) from the vertical towards +x, and its top generator's normal."""
    a = np.array([math.sin(lean), math.cos(lean), 0.0])
    return a, np.array([-math.cos(lean), math.sin(lean), 0.0])


# --------------------------------------------------------------------------- analytic cases


def test_the_side_ends_with_surface_follows_codes():
    """physics/side_follow.py repeats `surface_follow`'s end codes (it cannot import them: a cycle)."""
    from warp_ricochet.physics import side_follow, surface_follow

    assert (side_follow.CONTACT, side_follow.UNFINISHED, side_follow.EDGE) == (
        surface_follow.CONTACT,
        surface_follow.UNFINISHED,
        surface_follow.EDGE,
    )
    assert side_follow.STOP == surface_follow.STOP and side_follow.BAND == surface_follow.BAND


@pytest.mark.parametrize("precision", PRECISIONS)
def test_a_frictionless_pellet_slides_off_a_post_where_cos_is_two_thirds(precision):
    """From rest phi0 from the top generator of a level post, and of posts leaning 30 and 60 deg
    (across the axis gravity is g sin(lean); along it the motion is apart), without friction: it
    leaves (N = 0) at cos(phi) = 2/3 cos(phi0), with (v across the axis)^2 = g sin(lean) s cos(phi),
    its centre on the cylinder s = r + R all the way, its energy kept (float32: within the rounding
    of coordinates of up to 7 m, 1e-5 of s)."""
    r, phi0 = 0.1, np.array([1e-3, 0.05, 0.2, 0.5])
    s = r + R
    for lean in (math.pi / 2, math.radians(30.0), math.radians(60.0)):
        a, top = _lean_frame(lean)
        side = np.cross(a, top)
        p = np.array([0.0, 2.0, 0.0]) - 19.5 * a
        n0 = np.cos(phi0)[:, None] * top + np.sin(phi0)[:, None] * side
        x = p + 19.5 * a + s * n0  # 0.5 m below the top end, 19.5 m above the bottom: it leaves the side first
        out = _on_post(precision, p, a, r, 20.0, x, [0, 0, 0], [0, 0, 0], mu_s=0.0, mu_d=0.0)
        assert out["end"].tolist() == [FLIGHT] * 4
        d = out["x"] - p
        across = d - np.outer(d @ a, a)
        rho = np.linalg.norm(across, axis=1)
        np.testing.assert_allclose(rho, s, rtol=CLOSE[precision])
        np.testing.assert_allclose(across @ top / rho, 2 / 3 * np.cos(phi0), atol=5 * CLOSE[precision])
        v_across = out["v"] - np.outer(out["v"] @ a, a)
        want = G * math.sin(lean) * s * 2 / 3 * np.cos(phi0)
        np.testing.assert_allclose((v_across**2).sum(1), want, rtol=10 * CLOSE[precision])
        np.testing.assert_allclose(_energy(out["x"], out["v"], out["w"]), _energy(x, 0 * x, 0 * x), rtol=CLOSE[precision])


@pytest.mark.parametrize("precision", PRECISIONS)
def test_a_pellet_rolls_or_slides_straight_down_a_leaning_posts_top_generator(precision):
    """From rest on the top generator of a post leaning 30 deg, L from its bottom end: with grip
    (mu_s >= 2/7 cot(lean)) it rolls down at 5/7 g cos(lean), else it slides at g (cos(lean) - mu_d
    sin(lean)), and leaves over the bottom end after sqrt(2 L / a) at a t, having run L."""
    lean, r, length = math.radians(30.0), 0.06, 1.2
    a, top = _lean_frame(lean)
    p = np.array([0.0, 0.5, 0.0])
    x = p + length * a + (r + R) * top
    mu_s = np.array([0.8, 0.3])  # 2/7 cot(30 deg) = 0.495
    mu_d = 0.9 * mu_s
    out = _on_post(precision, p, a, r, length, x, [0, 0, 0], [0, 0, 0], mu_s=mu_s, mu_d=mu_d)
    assert out["end"].tolist() == [FLIGHT] * 2
    acc = np.array([5 / 7 * G * math.cos(lean), G * (math.cos(lean) - mu_d[1] * math.sin(lean))])
    t = np.sqrt(2 * length / acc)
    np.testing.assert_allclose(out["elapsed"], t, rtol=CLOSE[precision])
    np.testing.assert_allclose(out["v"], -np.outer(acc * t, a), rtol=CLOSE[precision], atol=CLOSE[precision])
    np.testing.assert_allclose(out["path"], length, rtol=CLOSE[precision])
    np.testing.assert_allclose(out["x"], np.tile(p + (r + R) * top, (2, 1)), atol=length * CLOSE[precision])
    assert (_energy(out["x"], out["v"], out["w"]) <= _energy(x, 0 * x, 0 * x) * (1 + CLOSE[precision])).all()


@pytest.mark.parametrize("precision", PRECISIONS)
def test_a_pellet_rests_on_a_level_posts_top_only_within_atan_c(precision):
    """At rest speed or less phi0 from a level post's top: held by the rolling resistance c where
    tan(phi0) <= c (REST, in place), else it rolls off (FLIGHT); equilibrium at the top is unstable."""
    r, c = 0.05, 0.1
    phi0 = np.array([0.0, 0.5, 0.99, 1.01, 1.5]) * math.atan(c)
    a, top = _lean_frame(math.pi / 2)
    side = np.cross(a, top)
    p = np.array([0.0, 1.0, 0.0]) - 0.5 * a
    x = p + 0.5 * a + (r + R) * (np.cos(phi0)[:, None] * top + np.sin(phi0)[:, None] * side)
    out = _on_post(precision, p, a, r, 1.0, x, [0, 0, 0], [0, 0, 0], mu_s=0.5, mu_d=0.45, c=c, rest=0.01)
    assert out["end"].tolist() == [REST, REST, REST, FLIGHT, FLIGHT]
    np.testing.assert_allclose(out["x"][:3], x[:3], atol=CLOSE[precision])
    assert out["steps"][:3].tolist() == [0, 0, 0]


@pytest.mark.parametrize("precision", PRECISIONS)
def test_a_leaning_posts_top_cap_is_a_tilted_disc_plate(precision):
    """From rest at the centre of the top cap of a post leaning 10 deg (a disc tilted 10 deg): held
    where c >= tan(10 deg) (REST, in place); else it rolls down the cap's fall line at 5/7 g (sin -
    c cos) and leaves over the rim (FLIGHT) after sqrt(2 r / a), r from the centre, at a t."""
    lean, r, length = math.radians(10.0), 0.05, 1.0
    a = np.array([math.sin(lean), math.cos(lean), 0.0])
    p = np.array([0.0, 0.2, 0.0])
    x = p + (length + R) * a
    c = np.array([0.3, 0.05, 0.0])
    out = _on_post(precision, p, a, r, length, x, [0, 0, 0], [0, 0, 0], mu_s=0.5, mu_d=0.45, c=c, rest=0.01)
    assert out["end"].tolist() == [REST, FLIGHT, FLIGHT]
    np.testing.assert_allclose(out["x"][0], x, atol=CLOSE[precision])
    down = np.array([math.cos(lean), -math.sin(lean), 0.0])
    acc = 5 / 7 * G * (math.sin(lean) - c[1:] * math.cos(lean))
    t = np.sqrt(2 * r / acc)
    np.testing.assert_allclose(out["elapsed"][1:], t, rtol=5 * CLOSE[precision])  # (float32: the rim found within its slack)
    np.testing.assert_allclose(out["x"][1:], x + np.outer(np.full(2, r), down), atol=CLOSE[precision])
    np.testing.assert_allclose(out["v"][1:], np.outer(acc * t, down), rtol=5 * CLOSE[precision], atol=CLOSE[precision])


# --------------------------------------------------------------------------- against the reference


def _random_cases(seed, m):
    """Seeded posts leaning 15-90 deg, 2-20 cm thick; pellets on the upper side within 35 deg of the
    top generator, moving any way along it at up to 0.8 sqrt(g s), rolling (with a drilling spin)
    or with any spin; mu_s in [0, 0.6], mu_d = 0.9 mu_s, c in [0, 0.1]."""
    rng = np.random.default_rng(seed)
    cases = []
    for _ in range(m):
        lean, yaw = math.radians(rng.uniform(15, 90)), rng.uniform(0, 2 * math.pi)
        a = np.array([math.sin(lean) * math.cos(yaw), math.cos(lean), math.sin(lean) * math.sin(yaw)])
        r = rng.uniform(0.02, 0.2)
        top = np.array([0.0, 1.0, 0.0]) - a[1] * a
        top /= np.linalg.norm(top)
        phi0 = rng.uniform(-0.6, 0.6)
        n = math.cos(phi0) * top + math.sin(phi0) * np.cross(a, top)
        p = -2.0 * a  # (its middle at the origin: float32 resolves the centre to 1e-7 m)
        x = p + 2.0 * a + (r + R) * n
        speed, heading = rng.uniform(0, 0.8 * math.sqrt(G * (r + R))), rng.uniform(0, 2 * math.pi)
        v = speed * (math.cos(heading) * a + math.sin(heading) * np.cross(n, a))
        w = np.cross(n, v) / R + rng.normal() * 50 * n if rng.uniform() < 0.5 else rng.normal(size=3) * 300
        mu = rng.uniform(0.0, 0.6)
        cases.append(dict(p=p, a=a, r=r, x=x, v=v, w=w, mu_s=mu, mu_d=0.9 * mu, c=rng.uniform(0.0, 0.1)))
    return cases


@pytest.mark.parametrize("precision", PRECISIONS)
def test_the_side_agrees_with_the_scipy_reference_on_random_cases(precision):
    """24 seeded cases: the same end (lift-off, or past an end), the centre and the path within 1e-4
    of the path of the reference's (measured: float64 2.4e-7, float32 5.3e-5), beside the rounding
    of the centre placed on the side (PLACED); the energy not risen, the centre not inside r + R."""
    worst, ends = 0.0, {}
    for case in _random_cases(27, 24):
        out = _on_post(
            precision, case["p"], case["a"], case["r"], 4.0, case["x"], case["v"], case["w"],
            mu_s=case["mu_s"], mu_d=case["mu_d"], c=case["c"],
        )  # fmt: skip
        ref = follow_side(
            case["x"], case["v"], case["w"], radius=R, point=case["p"], axis=case["a"], post_radius=case["r"],
            length=4.0, mu_s=case["mu_s"], mu_d=case["mu_d"], c=case["c"],
        )  # fmt: skip
        ends[ref.state] = ends.get(ref.state, 0) + 1
        assert out["end"][0] == {"flight": FLIGHT, "end": FLIGHT, "rest": REST}[ref.state], ref
        start = _energy(case["x"], case["v"], case["w"])
        assert _energy(out["x"][0], out["v"][0], out["w"][0]) <= start + CLOSE[precision] * (abs(start) + 1.0)  # never rises
        d = out["x"][0] - case["p"]
        assert np.linalg.norm(d - (d @ case["a"]) * case["a"]) >= case["r"] + R - PLACED[precision]  # never inside s
        apart = max(np.linalg.norm(out["x"][0] - ref.x), abs(out["path"][0] - ref.path)) - PLACED[precision]
        worst = max(worst, apart / max(ref.path, 1e-300))
    assert worst < 1e-4, worst
    assert ends.get("flight", 0) >= 10 and ends.get("end", 0) >= 2, ends
    print(precision, worst, ends)


# --------------------------------------------------------------------------- whole runs

LEANING = {"kind": "cylinder", "point": [0.0, 0.0, 0.0], "normal": [0.5, 0.8660254037844386, 0.0], "radius": 0.06}
LEANING |= {"length": 1.2, "restitution": 0.3, "mu_s": 0.4, "mu_d": 0.36, "rolling_resistance": 0.05}  # 30 deg, on the ground
RAIL = {"kind": "cylinder", "point": [-1.0, 0.8, 1.0], "normal": [1.0, 0.0, 0.0], "radius": 0.04, "length": 2.0}
RAIL |= {"restitution": 0.0, "mu_s": 0.6, "mu_d": 0.5, "rolling_resistance": 0.3}  # level, raised: holds within 17 deg
GROUND = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.2, "mu_s": 0.5, "mu_d": 0.45}
GROUND |= {"rolling_resistance": 0.1}


def _dropped(n, seed=30):
    """n pellets dropped 1 mm to 0.3 m onto the leaning post (two thirds) and the rail, over their
    tops to 1.3 radii either side, falling at up to 1 m/s and moving at about 0.2 m/s (the rail's
    third: 1 mm to 1 cm, slowly, so that most stay on it)."""
    rng = np.random.default_rng(seed)
    on_rail = rng.uniform(size=n) < 1 / 3
    a, top = _lean_frame(math.radians(30.0))
    post = np.outer(rng.uniform(0.0, 1.2, n), a) + 0.06 * top
    post[:, 2] += rng.uniform(-0.08, 0.08, n)
    rail = np.c_[rng.uniform(-1.0, 1.0, n), np.full(n, 0.84), 1.0 + rng.uniform(-0.05, 0.05, n)]
    x0 = np.where(on_rail[:, None], rail, post)
    x0[:, 1] += R + np.where(on_rail, rng.uniform(0.001, 0.01, n), rng.uniform(0.001, 0.3, n))
    slow = np.where(on_rail, 0.05, 1.0)
    v0 = np.c_[rng.normal(0.0, 0.2, n) * slow, -rng.uniform(0.0, 1.0, n) * slow, rng.normal(0.0, 0.2, n) * slow]
    return x0, v0


def _drop_run(folder, precision, air, n=1200):
    """{state, position, impacts} at rest of `_dropped` pellets, and their starts."""
    x0, v0 = _dropped(n)
    physics = {"gravity": [0.0, -G, 0.0], "until": "rest"}
    scene = explicit_scene(folder, x0, v0, surfaces=[LEANING, RAIL, GROUND], physics=physics, precision=precision)
    raw = {**scene.to_dict(), "output": {"fields": ["rest"]}}
    if air:
        raw["air"] = {"density": 1.225}
    wr.run(scene_from_dict(raw), folder / "dropped.h5", device="cpu", overwrite=True)
    with h5py.File(folder / "dropped.h5") as f:
        return {key: f[f"pellets/rest/{key}"][()] for key in ("state", "position", "impacts")}, x0, v0


def _axial(x, post):
    """(z along the axis, distance rho from it) of centres x from a post's dict."""
    a = np.asarray(post["normal"]) / np.linalg.norm(post["normal"])
    d = x - np.asarray(post["point"])
    z = d @ a
    return z, np.linalg.norm(d - np.outer(z, a), axis=1)


@pytest.mark.parametrize("air", [False, True], ids=["vacuum", "air"])
@pytest.mark.parametrize("precision", PRECISIONS)
def test_pellets_dropped_on_a_leaning_post_and_a_rail_all_rest_none_inside(tmp_path, precision, air):
    """1,200 pellets dropped onto a post leaning 30 deg on the ground and a level rail: every one at
    rest (none NOT_FINISHED), on the ground (centre R above it), on the rail's side (centre r + R
    from its axis, within atan(c) of its top) or the leaning post's top cap; no centre nearer an axis
    than r + R beside a post; none higher at rest than its start's energy lifts it."""
    end, x0, v0 = _drop_run(tmp_path, precision, air)
    tol = {"float64": 1e-9, "float32": 2e-5}[precision]
    x = end["position"]
    assert (end["state"] == AT_REST).all(), np.bincount(end["state"])
    z_rail, rho_rail = _axial(x, RAIL)
    on_rail = (np.abs(rho_rail - 0.04 - R) <= tol) & (z_rail >= 0) & (z_rail <= 2.0)
    z_post, rho_post = _axial(x, LEANING)
    on_cap = (np.abs(z_post - 1.2 - R) <= tol) & (rho_post <= 0.06 + tol)
    on_ground = np.abs(x[:, 1] - R) <= tol
    assert (on_rail | on_cap | on_ground).all(), x[~(on_rail | on_cap | on_ground)]
    assert on_rail.sum() > 50 and on_ground.sum() > 500, (on_rail.sum(), on_cap.sum(), on_ground.sum())
    up = (x[on_rail, 1] - 0.8) / (0.04 + R)
    assert (up >= math.cos(math.atan(0.3)) - 1e-6).all()  # held by the rolling resistance c = 0.3
    for post, z, rho in ((RAIL, z_rail, rho_rail), (LEANING, z_post, rho_post)):
        beside = (z > 0) & (z < post["length"])
        assert (rho[beside] >= post["radius"] + R - tol).all()
    assert (G * x[:, 1] <= G * x0[:, 1] + 0.5 * (v0**2).sum(1) + tol).all()  # energy never rises
    assert end["impacts"].max() <= 30


BURIED = LEANING | {"point": [-0.05, -0.0866, 0.0], "length": 1.3}  # its base 0.1 m down its axis, below the ground


def test_a_leaning_posts_bottom_cap_above_the_ground_is_warned_about():
    """A leaning post standing on the ground (its bottom cap half above it, tilted 30 deg) warns in one
    line naming it, the plane and how deep to bury it; buried, or until landing, it does not."""
    raw = paper_raw(until="rest")
    raw["surfaces"] = [GROUND, LEANING]
    with pytest.warns(wr.SceneWarning, match=r"^surfaces.1 .*bottom cap .*0.03 m above .*surfaces.0 .*30 degrees.*bury") as seen:
        scene_from_dict(raw)
    assert len(seen) == 1 and "\n" not in str(seen[0].message)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene_from_dict(raw | {"surfaces": [GROUND, BURIED]})
        scene_from_dict(paper_raw(until="landing") | {"surfaces": [GROUND, LEANING]})


@pytest.mark.parametrize("air", [False, True], ids=["vacuum", "air"])
@pytest.mark.parametrize("precision", PRECISIONS)
def test_pellets_rolling_into_a_buried_leaning_posts_foot_all_rest_outside_it(tmp_path, precision, air):
    """1,000 pellets sent along the ground at 0.3-5 m/s into the foot of a post leaning 30 deg, its
    base buried, from all round (onto its upper side, where they may climb it, and under its
    overhang): all at rest (with the base on the ground, 3 of 1,984 in vacuum and 49 of 947 in air
    ended NOT_FINISHED in the crease under its bottom cap), none inside it."""
    rng = np.random.default_rng(5)
    n = 1000
    heading = rng.uniform(0, 2 * np.pi, n)
    aim = np.c_[rng.uniform(-0.15, 0.6, n), np.zeros(n), rng.uniform(-0.1, 0.1, n)]
    out = np.c_[np.cos(heading), np.zeros(n), np.sin(heading)]
    x0 = aim + 0.5 * out
    x0[:, 1] = R + rng.uniform(0.0005, 0.02, n)
    z, rho = _axial(x0, BURIED)
    x0 = x0[(rho > 0.06 + 2 * R) | (z > 1.3 + 2 * R)]  # (starts outside it)
    v0 = -rng.uniform(0.3, 5.0, n)[: len(x0), None] * out[: len(x0)]
    physics = {"gravity": [0.0, -G, 0.0], "until": "rest"}
    scene = explicit_scene(tmp_path, x0, v0, surfaces=[BURIED, GROUND], physics=physics, precision=precision)
    raw = {**scene.to_dict(), "output": {"fields": ["rest", "impact"]}}
    if air:
        raw["air"] = {"density": 1.225}
    wr.run(scene_from_dict(raw), tmp_path / "foot.h5", device="cpu", overwrite=True)
    with h5py.File(tmp_path / "foot.h5") as f:
        state, x, impacts = f["pellets/rest/state"][()], f["pellets/rest/position"][()], f["pellets/impact/surface"][()]
    assert (state == AT_REST).all(), np.bincount(state)
    assert (impacts == 0).any()  # (the post met among a pellet's first impacts)
    z, rho = _axial(x, BURIED)
    assert (np.abs(rho - 0.06 - R) <= 1e-3).any()  # some rest against its foot (4 of them)
    tol = {"float64": 1e-9, "float32": 2e-5}[precision]
    assert (rho[(z > 0) & (z < 1.3)] >= 0.06 + R - tol).all()


COUNT = 5
CHUNK_FIELDS = ("rest/position", "rest/state", "rest/path_length", "impact/surface")


def _chunked(chunk):
    """Two whole chunks and a short one of 5-pellet shots dropped onto the leaning post's upper
    side (2 cm clouds), to rest with pellet-pellet collisions; `chunk` pellets a chunk."""
    from warp_ricochet.dense.schedule import shot_granule

    raw = paper_raw(until="rest", bounces=3)
    shot = {"speed": 0.5, "direction": [0.0, -1.0, 0.0], "envelope_center": [0.2, 0.6, 0.0], "envelope_radius": 0.02}
    raw["shot"] |= {"count": COUNT, "shots": 2 * shot_granule(COUNT) + 3, **shot}
    raw["surfaces"] = [GROUND, LEANING]
    raw["numerics"] = {"precision": "float64", "chunk_size": chunk}
    raw["collisions"] = {"enabled": True, "time_step": 5e-4, "rounds": 1}
    raw["output"] = {"fields": [f.replace("/", ".") for f in CHUNK_FIELDS]}
    return scene_from_dict(raw)


def test_a_leaning_post_run_is_the_same_bits_in_one_chunk_and_after_a_resume(tmp_path):
    """Three chunks, one chunk, and Ctrl-C after the first of three then --resume: the same file."""
    from warp_ricochet.dense.schedule import shot_granule

    chunk = COUNT * shot_granule(COUNT)
    reference = tmp_path / "three.h5"
    wr.run(_chunked(chunk), reference, device="cpu")
    with h5py.File(reference) as f:
        assert f["progress/chunk_rows"][()] == chunk and f["progress/rows"][()] > 2 * chunk
        assert (f["pellets/rest/state"][()] == AT_REST).all() and (f["pellets/rest/path_length"][()] > 0).mean() > 0.5
    wr.run(_chunked(3 * chunk), tmp_path / "one.h5", device="cpu")
    assert_same_run(tmp_path / "one.h5", reference, CHUNK_FIELDS)
    interrupt_after(1, _chunked(chunk), tmp_path / "resumed.h5")
    wr.run(_chunked(chunk), tmp_path / "resumed.h5", device="cpu", resume=True)
    assert_same_run(tmp_path / "resumed.h5", reference, CHUNK_FIELDS)
