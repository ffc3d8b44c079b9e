"""The dense phase of pellet-pellet collisions against boxes, meshes, terrain and posts (issue 27,
section 3; docs/collisions.md "Boxes, meshes, terrain and posts"): a pellet that never meets
another ends where the same pellet ends in a run without collisions, on every kind of solid; no
pellet of dense shots fired at a closed box ends inside it, and no impact gains energy."""

import h5py
import numpy as np
import pytest
from helpers import assert_same_run, interrupt_after, paper_raw

import warp_ricochet as wr
from warp_ricochet.dense.schedule import shot_granule
from warp_ricochet.scene import scene_from_dict

trimesh = pytest.importorskip("trimesh")

R = 0.00125  # m, the paper's pellet
LOSSY = {"restitution": 0.3, "mu_s": 0.4, "rolling_resistance": 0.3}  # pellets come to rest within metres
GROUND = {"name": "ground", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], **LOSSY}
BOX = {"kind": "box", "point": [10.0, 1.0, 0.0], "normal": [0.0, 1.0, 0.0], "axis_u": [1.0, 0.0, 0.0], "size": [6.0, 4.0, 2.0]}
POST = {"kind": "cylinder", "point": [10.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "radius": 0.5, "length": 2.0}
LEVEL = {"speed": 60.0, "direction": [1.0, 0.0, 0.0], "envelope_center": [0.0, 1.0, 0.0]}  # at the box's front face
DROPPED = {"speed": 8.0, "direction": [0.05, -1.0, 0.0], "envelope_center": [10.0, 2.6, 0.0]}  # onto its top


def _plane_mesh(tmp_path):
    """Two triangles of the plane y = 0 (400 m square), facing up."""
    vertices = [[-200.0, 0.0, -200.0], [-200.0, 0.0, 200.0], [200.0, 0.0, 200.0], [200.0, 0.0, -200.0]]
    path = tmp_path / "plane.stl"
    trimesh.Trimesh(vertices=vertices, faces=[[0, 1, 2], [0, 2, 3]], process=False).export(path)
    return {**GROUND, "name": "mesh", "kind": "mesh", "file": str(path)}


def _terrain(tmp_path):
    """A small synthetic ESRI ASCII raster (24 x 16 cells of 1 m, a slope and waves, 0.6 m high at
    most) under the shot: its north along +x, its east (axis_u) along -z, from x = -1.5, z = 7.5."""
    east, north = np.meshgrid(np.arange(17) * 1.0, np.arange(25)[::-1] * 1.0)
    z = 0.01 * north + 0.2 * (1.0 + np.sin(0.9 * north) * np.cos(0.7 * east))
    path = tmp_path / "terrain.asc"
    header = "ncols 17\nnrows 25\nxllcenter 0.0\nyllcenter 0.0\ncellsize 1.0\nNODATA_value -9999\n"
    path.write_text(header + "\n".join(" ".join(f"{h:.4f}" for h in row) for row in z) + "\n")
    terrain = {"name": "terrain", "kind": "terrain", "file": str(path), "point": [-2.0, 0.0, 8.0], "axis_u": [0.0, 0.0, -1.0]}
    return {**terrain, **LOSSY}


def _scene(surfaces, shot, collisions, until="rest", air=None, count=8, shots=3, fields=("rest", "landing")):
    """The scene of `_raw`."""
    return scene_from_dict(_raw(surfaces, shot, collisions, until, air, count, shots, fields))


def _raw(surfaces, shot, collisions, until="rest", air=None, count=8, shots=3, fields=("rest", "landing")):
    """The paper's pellets, `count` a shot spread over 0.4 m (they never meet: checked by the
    tests), aimed by `shot`, on `surfaces`, float64, with or without collisions (the same launches:
    collisions.separate false)."""
    raw = paper_raw(until=until, bounces=3)
    raw["shot"] |= {"count": count, "shots": shots, "envelope_radius": 0.4, "direction_jitter": [0.0, 0.02, 0.02], **shot}
    raw["surfaces"] = surfaces
    raw["numerics"] = {"precision": "float64"}
    raw["collisions"] = {"enabled": collisions, "separate": False}
    fields = [*fields, "impact.surface"] + (["collisions.count"] if collisions else [])
    raw["output"] = {"fields": fields}
    if air:
        raw["air"] = air
    return raw


def _read(path, groups):
    with h5py.File(path) as f:
        return {f"{g}/{k}": f[f"pellets/{g}/{k}"][()] for g in groups for k in f[f"pellets/{g}"]}


def _alone_and_without(tmp_path, name, surfaces, shot, until="rest", air=None):
    """(with collisions, without) per-pellet outputs of the scene; no pair collided."""
    groups = ("rest", "landing", "impact") if until == "rest" else ("landing", "impact")
    out = []
    for collisions in (True, False):
        path = tmp_path / f"{name}-{collisions}.h5"
        stats = wr.run(_scene(surfaces, shot, collisions, until, air, fields=groups[:-1]), path, device="cpu")
        out.append(_read(path, groups + (("collisions",) if collisions else ())))
        if collisions:
            assert stats["pair_collisions"] == 0 and (out[0]["collisions/count"] == 0).all()
    return out


def _same_ends(dense, core, solid, tolerance):
    """The same surfaces met, the solid met by some; landing (and rest) positions within
    `tolerance` (m) of each other."""
    np.testing.assert_array_equal(dense["impact/surface"], core["impact/surface"])
    assert (core["impact/surface"] == solid).any()
    for name in ("landing/position", "rest/position"):
        if name in core:
            assert np.isfinite(core[name]).all(), name
            np.testing.assert_allclose(dense[name], core[name], rtol=0, atol=tolerance, err_msg=name)
    if "rest/state" in core:
        np.testing.assert_array_equal(dense["rest/state"], core["rest/state"])


@pytest.mark.parametrize(
    ("name", "surfaces", "shot", "solid"),
    [
        ("box front", [GROUND, {**BOX, **LOSSY}], LEVEL, 1),
        ("box top", [GROUND, {**BOX, **LOSSY}], DROPPED, 1),
        ("post", [GROUND, {**POST, **LOSSY}], LEVEL, 1),
        ("post top", [GROUND, {**POST, **LOSSY}], DROPPED, 1),
    ],
)
def test_pellets_alone_end_on_a_box_or_a_post_as_without_collisions(tmp_path, name, surfaces, shot, solid):
    """Fired level at a box's front face or a post's side (back onto the ground, to rest), dropped
    onto the box's top or the post's top cap (to rest there, on its triangles or its cap: the core
    follows the released pellets): the run without collisions' ends, within 1e-9 m (the exact
    flights of both phases, float64; measured 0)."""
    dense, core = _alone_and_without(tmp_path, name.replace(" ", "_"), surfaces, shot)
    _same_ends(dense, core, solid, 1e-9)
    at = core["rest/position"]
    if name == "box top":  # at rest on the box's top, R above it
        np.testing.assert_allclose(at[:, 1], 2.0 + R, atol=1e-9)
    if name == "post top":  # at rest on its cap (y = 2, r = 0.5), R above it, or rolled off its rim onto the ground
        on_cap = at[:, 1] > 1.0
        np.testing.assert_allclose(at[:, 1], np.where(on_cap, 2.0 + R, R), atol=1e-9)
        assert on_cap.mean() > 0.75 and (np.hypot(at[on_cap, 0] - 10.0, at[on_cap, 2]) <= 0.5).all()  # (measured 20 of 24)


def test_pellets_alone_end_on_a_mesh_of_a_plane_and_on_terrain_as_without_collisions(tmp_path):
    """The paper's shot slowed to 30 m/s, to rest on two triangles of its plane, and on a small
    terrain raster above a plane: the ends of the run without collisions within 1e-9 m."""
    slow = {"speed": 30.0}
    dense, core = _alone_and_without(tmp_path, "mesh", [_plane_mesh(tmp_path)], slow)
    _same_ends(dense, core, 0, 1e-9)
    dense, core = _alone_and_without(tmp_path, "terrain", [_terrain(tmp_path), {**GROUND, "point": [0.0, -1.0, 0.0]}], slow)
    _same_ends(dense, core, 0, 1e-9)


def test_pellets_alone_end_on_a_box_in_air_as_without_collisions(tmp_path):
    """In sea-level air the dense phase splits the air from the flight (kicks) and leaps by the
    box's clearance: the core's ends within 1e-4 m (measured 1.8e-5 m of rest position after 12 m;
    as on the plane: tests/test_dense_ground.py)."""
    air = {"density": 1.225}
    dense, core = _alone_and_without(tmp_path, "air", [GROUND, {**BOX, **LOSSY}], LEVEL, air=air)
    _same_ends(dense, core, 1, 1e-4)


def test_the_clearance_of_a_box_and_a_post_bounds_their_distance():
    """`geometry.clearance`, which bounds the dense phase's leaps and air steps near solids: a
    box's is its distance within 1e-4 m (the float32 BVH's slack: 4e-5 m here), never more; a post's at most
    its distance (that of its bounding box)."""
    import warp as wp

    from warp_ricochet.model import Model
    from warp_ricochet.physics.geometry import MESHES, make_geometry
    from warp_ricochet.physics.types import types_for

    geo = make_geometry("float64", plates=MESHES)
    solids = [GROUND, {**BOX, **LOSSY}, {**POST, **LOSSY, "point": [0.0, 0.0, 5.0]}]
    scene = _scene(solids, LEVEL, False, until="landing", fields=("landing",))
    model = Model.from_scene(scene, wp.get_device("cpu"))

    @wp.kernel(module="unique", enable_backward=False)
    def clearances(
        k: wp.int32, x: wp.array(dtype=wp.vec3d), surfaces: types_for("float64").Surfaces, out: wp.array(dtype=wp.float64)
    ):
        i = wp.tid()
        out[i] = geo.clearance(surfaces, k, x[i])

    rng = np.random.default_rng(3)
    x = rng.uniform([-5.0, -1.0, -5.0], [20.0, 6.0, 10.0], (4000, 3))
    box = np.linalg.norm(np.maximum(np.abs(x - BOX["point"]) - [3.0, 1.0, 2.0], 0.0), axis=1)  # (its axes: x, y, z)
    d = x - [0.0, 0.0, 5.0]
    post = np.hypot(np.maximum(np.hypot(d[:, 0], d[:, 2]) - 0.5, 0.0), np.maximum(np.maximum(-d[:, 1], d[:, 1] - 2.0), 0.0))
    found = []
    for k in (1, 2):
        out = wp.zeros(len(x), dtype=wp.float64, device="cpu")
        wp.launch(clearances, len(x), inputs=[k, wp.array(x, dtype=wp.vec3d, device="cpu"), model.surfaces, out], device="cpu")
        found.append(out.numpy())
    outside = box > 0.0
    assert outside.sum() > 3000 and (found[0][outside] <= box[outside]).all()
    np.testing.assert_allclose(found[0][outside], box[outside], rtol=0, atol=1e-4)
    assert (found[1] <= post + 1e-12).all() and (found[1] > 0.5 * post - 0.5).all()


def _clouds(rng, box, per_shot=120, speed=150.0):
    """(x0, v0) of five dense clouds (a jittered 3 mm lattice each: the pellets touch within a few
    diameters of travel) whose centres reach, AHEAD s later, a face centre, an edge, two vertices
    and another face of `box`, each coming in from outside along the outward direction there."""
    from bench.meshes import GRAVITY, aimed, box_axes

    axes, half = box_axes(box)
    marks = np.array([[0, 0, 1], [1, -1, 0], [1, 1, 1], [-1, 0, 0], [-1, -1, 1]], dtype=float)
    lattice = 0.003 * np.stack(np.meshgrid(np.arange(5), np.arange(6), np.arange(4), indexing="ij"), -1).reshape(-1, 3)
    lattice = lattice[:per_shot] - lattice[:per_shot].mean(axis=0)
    x, v = [], []
    for mark in marks:
        target = np.asarray(box["point"]) + (mark * half) @ axes
        way = (mark / np.linalg.norm(mark)) @ axes
        centre_v = -speed * way - GRAVITY * 0.05
        spread = rng.normal(scale=0.01 * speed, size=(per_shot, 3))  # 1 % of the speed: they converge
        x.append(aimed(target, centre_v) + lattice + rng.uniform(-2e-4, 2e-4, lattice.shape))
        v.append(centre_v + spread)
    return np.concatenate(x), np.concatenate(v)


def test_dense_clouds_fired_at_a_closed_box_never_end_inside_it(tmp_path, device):
    """Issue 27: five clouds of 120 pellets, with collisions, at a closed box's face, edge and
    vertices from all around: they collide (with each other and the rebounds), no centre is inside
    the box at an impact or the landing, and no impact gains kinetic energy (translation and spin)."""
    from bench.meshes import BOX, inside_box

    x, v = _clouds(np.random.default_rng(7), BOX)
    np.savez(tmp_path / "clouds.npz", position=x, velocity=v)
    raw = {
        "shot": {"file": str(tmp_path / "clouds.npz"), "shots": 5, "diameter": 2 * R, "density": 7000.0},
        "surfaces": [{"kind": "box", **BOX, "restitution": 0.5, "mu_s": 0.3}, {"point": [0, 0, 0], "normal": [0, 0, 1], **LOSSY}],
        "physics": {"until": "landing", "gravity": [0.0, 0.0, -9.81], "bounces": 4},
        "numerics": {"precision": "float64"},
        "collisions": {"enabled": True},
        "output": {"fields": ["impact", "landing", "collisions.count"]},
    }
    stats = wr.run(scene_from_dict(raw), tmp_path / "clouds.h5", device=device)
    out = _read(tmp_path / "clouds.h5", ("impact", "landing", "collisions"))
    assert stats["pair_collisions"] > 500 and (out["collisions/count"] > 0).sum() > 300  # (measured 933, 566)
    first = out["impact/surface"][:, 0]
    assert (first == 0).sum() > 590  # (measured 597 of 600: at the edge and the vertices a few miss it)
    met = out["impact/surface"] >= 0
    assert not inside_box(out["impact/position"][met], BOX, 1e-9).any()
    landed = np.isfinite(out["landing/position"]).all(axis=1)
    assert landed.sum() > 300 and not inside_box(out["landing/position"][landed], BOX, 1e-9).any()

    def energy(v, w):  # per unit mass, doubled: v^2 + (2/5) R^2 w^2
        return (v**2).sum(axis=-1) + 0.4 * R**2 * (w**2).sum(axis=-1)

    before = energy(out["impact/velocity_before"], out["impact/angular_velocity_before"])[met]
    after = energy(out["impact/velocity"], out["impact/angular_velocity"])[met]
    assert (after <= before * (1.0 + 1e-12)).all(), (after / before).max()


COUNT = 5
CHUNK = COUNT * shot_granule(COUNT)  # pellets per chunk (whole shots, whole statistics segments)
FIELDS = ("landing/position", "impact/surface", "impact/velocity", "collisions/count", "release/velocity")


def _chunked(chunk):
    """Two whole chunks and a short one of 5-pellet shots with collisions at the box's front face
    (2 cm clouds: some collide), until landing; `chunk` pellets a chunk."""
    shot = {**LEVEL, "shots": 2 * shot_granule(COUNT) + 3, "envelope_radius": 0.02, "direction_jitter": [0.0, 0.05, 0.05]}
    shot["envelope_center"] = [6.0, 1.0, 0.0]  # a metre before the face
    raw = _raw([GROUND, {**BOX, "restitution": 0.5, "mu_s": 0.3}], shot, True, "landing", count=COUNT, fields=())
    raw["collisions"] |= {"separate": True, "time_step": 5e-4, "rounds": 1}  # (as tests/test_resume_collisions.py)
    raw["output"]["fields"] = ["landing.position", "impact.surface", "impact.velocity", "collisions.count", "release.velocity"]
    raw["numerics"]["chunk_size"] = chunk
    return scene_from_dict(raw)


@pytest.mark.slow
def test_a_box_run_is_the_same_bits_in_one_chunk_and_after_a_resume(tmp_path):
    """Three chunks, one chunk, and Ctrl-C after the first of three then --resume: the same file
    (15 s on the CPU)."""
    reference = tmp_path / "three.h5"
    stats = wr.run(_chunked(CHUNK), reference, device="cpu")
    with h5py.File(reference) as f:
        assert f["progress/chunk_rows"][()] == CHUNK and f["progress/rows"][()] > 2 * CHUNK
        counts, first = f["pellets/collisions/count"][()], f["pellets/impact/surface"][:, 0]
    assert stats["pair_collisions"] > 0 and counts[CHUNK:].sum() > 0 and (first == 1).mean() > 0.9
    wr.run(_chunked(3 * CHUNK), tmp_path / "one.h5", device="cpu")
    assert_same_run(tmp_path / "one.h5", reference, FIELDS)
    interrupt_after(1, _chunked(CHUNK), tmp_path / "resumed.h5")
    wr.run(_chunked(CHUNK), tmp_path / "resumed.h5", device="cpu", resume=True)
    assert_same_run(tmp_path / "resumed.h5", reference, FIELDS)


def test_first_impact_statistics_of_pellets_met_on_a_box_then_the_ground_in_the_dense_phase(tmp_path):
    """Two pellets hit the box's front face and then the ground while two others, lobbed high, keep
    the shot in the dense phase: the first impacts' statistics (normal and tangential speeds before
    and after) are those of the run without collisions. The first impact's normal is kept at that
    impact: the box's face, not the box's triangle nearest the last impact's point on the ground."""
    x = [[0.0, 1.0, 0.3], [0.0, 1.0, -0.3], [0.0, 1.0, -5.0], [0.0, 1.0, 5.0]]
    v = [[60.0, 0.0, 0.0], [60.0, 1.0, 0.0], [0.0, 20.0, 3.0], [1.0, 20.0, -3.0]]
    np.savez(tmp_path / "four.npz", position=np.array(x), velocity=np.array(v))
    stats, surfaces = [], []
    for collisions in (True, False):
        raw = {
            "shot": {"file": str(tmp_path / "four.npz"), "diameter": 2 * R, "density": 7000.0},
            "surfaces": [GROUND, {**BOX, **LOSSY}],
            "physics": {"until": "landing", "bounces": 3, "impact_duration": 1e-5},
            "numerics": {"precision": "float64"},
            "collisions": {"enabled": collisions, "separate": False},
            "output": {"fields": ["impact.surface", "landing"] + (["release.position"] if collisions else [])},
        }
        stats.append(wr.run(scene_from_dict(raw), tmp_path / f"four-{collisions}.h5", device="cpu"))
        surfaces.append(_read(tmp_path / f"four-{collisions}.h5", ("impact",))["impact/surface"])
    with h5py.File(tmp_path / "four-True.h5") as f:
        released = f["pellets/release/position"][:2]
    assert (released[:, 1] < 0.01).all() and (surfaces[0][:2, :2] == [1, 0]).all()  # box, then ground: in the dense phase
    np.testing.assert_array_equal(surfaces[0], surfaces[1])
    assert stats[0]["pair_collisions"] == 0
    first = [k for k in stats[1] if k.startswith(("pre_", "post_"))]
    assert len(first) >= 4
    for k in first:
        assert stats[0][k] == pytest.approx(stats[1][k], rel=1e-9, abs=1e-9), k
