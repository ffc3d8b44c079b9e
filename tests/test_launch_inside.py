"""Launches inside a solid are refused (docs/geometry.md, "Launches inside a solid"): a sampled
shot's envelope reaching into a closed mesh, as into a post or a box, and pellets of a file
(`shot.file`) starting inside a post, a box or a closed mesh: one line naming the key, the value,
the solid and what is allowed, exit status 2, nothing written. The closed-mesh test is the
generalized winding number (`scene.solids`), checked here against the analytic inside of a box."""

import dataclasses

import numpy as np
import pytest
from helpers import cli, explicit_scene

from warp_ricochet.errors import SceneError
from warp_ricochet.scene import scene_from_dict
from warp_ricochet.scene.solids import (
    closed_triangles,
    envelope_gap,
    inside_rows,
    solid_gaps,
    winding_level,
    winding_numbers,
)
from warp_ricochet.scene.toml_out import toml_lines
from warp_ricochet.scene.triangles import box_triangles

trimesh = pytest.importorskip("trimesh")  # the mesh extra reads the STL files

MATERIAL = {"restitution": 0.5, "mu_s": 0.3}
GROUND = {"name": "ground", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], **MATERIAL}
TILTED = {"point": [3.0, -1.0, 1.5], "normal": [0.2, 0.1, 1.0], "axis_u": [1.0, 0.5, -0.25], "size": [1.2, 0.8, 0.5]}
POST = {"kind": "cylinder", "point": [-2.0, 2.0, 0.0], "normal": [0.0, 0.0, 1.0], "radius": 0.15, "length": 1.2}


def _box_stl(path, box=TILTED, drop=None, flip=False):
    """`box` as an STL file (its 12 triangles, vertices unmerged as an STL holds them, in scene
    coordinates: the mesh's point stays 0); `drop`: a triangle left out (an open mesh); `flip`:
    wound inwards."""
    tri = box_triangles(box["point"], box["normal"], box["axis_u"], box["size"])
    faces = np.delete(tri.triangles, [] if drop is None else [drop], axis=0)
    faces = faces[:, ::-1] if flip else faces
    trimesh.Trimesh(
        vertices=tri.vertices[faces].reshape(-1, 3), faces=np.arange(faces.size).reshape(-1, 3), process=False
    ).export(path)
    return str(path)


def _mesh(path, **options):
    return {"kind": "mesh", "name": "shed", "file": _box_stl(path, **options), **MATERIAL}


def _sampled(centre, surfaces, radius=0.05):
    shot = {"count": 20, "diameter": 0.0025, "density": 7000.0, "speed": 300.0, "direction": [1.0, 0.0, -0.05]}
    shot |= {"envelope_radius": radius, "envelope_center": [float(c) for c in centre]}
    return {"shot": shot, "surfaces": surfaces, "physics": {"until": "landing", "gravity": [0, 0, -9.81]}}


def _frame(box=TILTED):
    """The box's unit axes (rows u, v, n) and centre, as `box_triangles` builds it."""
    n = np.asarray(box["normal"], float) / np.linalg.norm(box["normal"])
    u = np.asarray(box["axis_u"], float)
    u = (u - (u @ n) * n) / np.linalg.norm(u - (u @ n) * n)
    return np.stack([u, np.cross(n, u), n]), np.asarray(box["point"], float)


def _about_box(rng):
    """20,000 random points about TILTED (within 1.5 times its half sides), a third of them within
    1e-5 m of a face, and the box as a scene surface."""
    axes, centre = _frame()
    half = 0.5 * np.asarray(TILTED["size"])
    local = rng.uniform(-1.5, 1.5, (20000, 3)) * half
    face = rng.integers(0, 3, 20000)
    near = np.arange(20000) % 3 == 0
    local[near, face[near]] = rng.choice([-1.0, 1.0], near.sum()) * half[face[near]] + rng.uniform(-1e-5, 1e-5, near.sum())
    box = scene_from_dict(_sampled([0.0, 0.0, 5.0], [GROUND, {"kind": "box", **TILTED, **MATERIAL}])).surfaces[1]
    return centre + local @ axes, box


def test_the_winding_number_tells_a_closed_boxs_inside_as_its_geometry_does(tmp_path):
    """20,000 random points about a tilted box, a third of them within 1e-5 m of a face: inside
    the closed mesh of its STL (winding number > 1/2) exactly where the box's exact signed
    distance is negative (but for points within 1e-6 m of a face: the STL holds float32
    vertices, 2.4e-7 m apart at 3 m), and its envelope gap equals that distance within 1e-6 m."""
    x, box = _about_box(np.random.default_rng(5))
    mesh = scene_from_dict(_sampled([0.0, 0.0, 5.0], [GROUND, _mesh(tmp_path / "box.stl")])).surfaces[1]
    exact = solid_gaps(box, x)
    sure = np.abs(exact) > 1e-6
    inside = inside_rows(mesh, x)
    assert (inside[sure] == (exact[sure] < 0)).all() and 2000 < inside.sum() < 18000
    for point, gap in zip(x[:300], exact[:300], strict=True):
        assert envelope_gap(mesh, point) == pytest.approx(gap, abs=1e-6)


def test_the_winding_number_tells_a_spheres_inside():
    """A unit icosphere of 1,280 triangles (trimesh) and 4,000 random points in its box: the
    winding number is 1 within 1e-12 inside and 0 within 1e-12 outside, but for points within
    5e-3 of the unit sphere (its facets lie within 1.3e-3 of it)."""
    sphere = trimesh.creation.icosphere(subdivisions=3)
    x = np.random.default_rng(8).uniform(-1.0, 1.0, (4000, 3))
    w = winding_numbers(np.asarray(sphere.vertices, float), np.asarray(sphere.faces, np.int32), x)
    r = np.linalg.norm(x, axis=1)
    assert np.abs(w[r < 0.995] - 1.0).max() < 1e-12 and np.abs(w[r > 1.005]).max() < 1e-12
    assert (r < 0.995).sum() > 1500 and (r > 1.005).sum() > 1500


def test_open_meshes_are_not_solids(tmp_path):
    """A box's STL less one triangle (open) refuses nothing: no volume is met from outside only."""
    open_ = scene_from_dict(_sampled([0, 0, 5], [GROUND, _mesh(tmp_path / "open.stl", drop=3)])).surfaces[1]
    assert closed_triangles(open_) is None and envelope_gap(open_, np.asarray(TILTED["point"], float)) is None
    assert not inside_rows(open_, np.asarray([TILTED["point"], [0.0, 0.0, 5.0]])).any()
    raw = _sampled(TILTED["point"], [GROUND, {"kind": "mesh", "file": str(tmp_path / "open.stl"), **MATERIAL}])
    assert scene_from_dict(raw).shot.envelope_center == tuple(TILTED["point"])


def test_a_mesh_wound_inwards_has_all_outside_it_for_solid(tmp_path):
    """The tilted box's STL wound both ways and 20,000 random points about it (a third within 1e-5 m
    of a face) plus 2,000 beyond its bounding box: wound outwards the winding number is 1 inside
    and 0 outside (level 1/2), wound inwards -1 inside and 0 outside (level -1/2), within 1e-9; the
    solid of the inward mesh (inside_rows) is exactly where the box's exact signed distance is
    positive, that of the outward one where it is negative (but within 1e-6 m of a face: the STL's
    float32 vertices), and the inward mesh's envelope gap is minus that distance within 1e-6 m."""
    rng = np.random.default_rng(11)
    about, box = _about_box(rng)
    centre = np.asarray(TILTED["point"], float)
    beyond = rng.normal(size=(2000, 3))
    beyond *= rng.uniform(2.0, 50.0, (2000, 1)) / np.linalg.norm(beyond, axis=1, keepdims=True)  # |x - centre| >= 2 m
    x = np.r_[about, centre + beyond]
    outward, inward = (
        scene_from_dict(
            _sampled([0.0, 0.0, 5.0] if not flip else centre, [GROUND, _mesh(tmp_path / f"{flip}.stl", flip=flip)])
        ).surfaces[1]
        for flip in (False, True)
    )
    exact = solid_gaps(box, x)
    sure = np.abs(exact) > 1e-6
    for mesh, level, sign in ((outward, 0.5, 1.0), (inward, -0.5, -1.0)):
        tri = closed_triangles(mesh)
        assert winding_level(tri) == level
        w = winding_numbers(tri.vertices, tri.triangles, x[sure])
        np.testing.assert_allclose(w, np.where(exact[sure] < 0, sign, 0.0), rtol=0, atol=1e-9)
        solid = inside_rows(mesh, x)
        assert (solid[sure] == (sign * exact[sure] < 0)).all()
    assert solid[20000:].all() and 2000 < (~solid).sum() < 18000
    for point, gap in zip(x[::70], exact[::70], strict=True):
        assert envelope_gap(inward, point) == pytest.approx(-gap, abs=1e-6)


def test_a_launch_outside_a_mesh_wound_inwards_is_refused_in_one_line(tmp_path):
    """A room (the box's STL wound inwards): the envelope's centre outside it, or 0.01 m from a
    wall inside it with a 0.05 m radius, is refused in one line naming shot.envelope_center, the
    surface, that its solid is all outside it, and the depth (exit status 2, nothing written); at
    the room's centre the scene is read."""
    axes, centre = _frame()
    top = centre + (0.5 * TILTED["size"][2]) * axes[2]
    surfaces = [GROUND, _mesh(tmp_path / "room.stl", flip=True)]
    name = "('shed', a closed mesh wound inwards, whose solid is all outside it)"
    for where, text in (
        ([0.0, 0.0, 5.0], f"is outside surfaces.1 {name}"),
        (np.round(top - 0.01 * axes[2], 6).tolist(), f"is 0.01 m from surfaces.1 {name}"),
    ):
        with pytest.raises(SceneError) as e:
            scene_from_dict(_sampled(where, surfaces))
        message = str(e.value)
        assert message.startswith(f"shot.envelope_center = {list(where)}: {text}") and "\n" not in message, message
        assert message.endswith("outside every post, box and closed mesh (inside a closed mesh wound inwards)")
    assert "reaches 0.04 m into it" in message
    assert scene_from_dict(_sampled(centre, surfaces)).shot.envelope_center == tuple(centre)
    (tmp_path / "scene.toml").write_text("\n".join(toml_lines(_sampled([0.0, 0.0, 5.0], surfaces), "")))
    rc, _out, err = cli(["run", tmp_path / "scene.toml", "--device", "cpu", "-o", tmp_path / "out.h5"])
    assert rc == 2 and err.count("\n") == 1 and "shot.envelope_center" in err and "wound inwards" in err, err
    assert list(tmp_path.glob("out*")) == []


def test_a_launch_envelope_in_a_closed_mesh_is_refused_in_one_line(tmp_path):
    """The envelope's centre inside the closed mesh, or 0.01 m from it with a 0.05 m radius: one
    line naming shot.envelope_center, the surface and the depth, exit status 2, nothing written;
    0.1 m above it: the scene is read."""
    axes, centre = _frame()
    top = centre + (0.5 * TILTED["size"][2]) * axes[2]
    surfaces = [GROUND, _mesh(tmp_path / "box.stl")]
    for where, text in (
        (centre.tolist(), "is inside surfaces.1 ('shed', a closed mesh)"),
        (np.round(top + 0.01 * axes[2], 6).tolist(), "is 0.01 m from"),
    ):
        with pytest.raises(SceneError) as e:
            scene_from_dict(_sampled(where, surfaces))
        message = str(e.value)
        assert message.startswith(f"shot.envelope_center = {list(where)}: {text}") and "\n" not in message, message
        assert "outside every post, box and closed mesh" in message
    assert "reaches 0.04 m into it" in message
    assert scene_from_dict(_sampled(top + 0.1 * axes[2], surfaces)).shot.envelope_radius == 0.05
    (tmp_path / "scene.toml").write_text("\n".join(toml_lines(_sampled(centre, surfaces), "")))
    rc, _out, err = cli(["run", tmp_path / "scene.toml", "--device", "cpu", "-o", tmp_path / "out.h5"])
    assert rc == 2 and err.count("\n") == 1 and "shot.envelope_center" in err and "closed mesh" in err, err
    assert list(tmp_path.glob("out*")) == []


def _pellet_file(path, positions, fortran=False):
    position = np.asarray(positions, dtype=np.float64)
    position = np.asfortranarray(position) if fortran else position
    velocity = np.tile([100.0, 0.0, 0.0], (len(position), 1))
    if str(path).endswith(".h5"):
        import h5py

        with h5py.File(path, "w") as f:
            f["position"], f["velocity"] = position, velocity
    else:
        np.savez(path, position=position, velocity=velocity)
    return str(path)


_AXES, _CENTRE = _frame()
_ABOVE_BOX = (_CENTRE + (0.5 * TILTED["size"][2] + 1e-6) * _AXES[2]).tolist()  # 1e-6 m above the box's top


@pytest.mark.parametrize(
    ("solid", "inside", "above", "name"),
    [
        ({"kind": "box", **TILTED}, TILTED["point"], _ABOVE_BOX, "a box"),
        (POST, [-2.1, 2.05, 1.1], [-2.1, 2.05, 1.2 + 1e-6], "a post (cylinder)"),
        ("mesh", TILTED["point"], _ABOVE_BOX, "a closed mesh"),
    ],
    ids=["box", "post", "mesh"],
)
@pytest.mark.parametrize("suffix", [".npz", "-fortran.npz", ".h5"])
def test_pellets_from_a_file_starting_inside_a_solid_are_refused_in_one_line(tmp_path, solid, inside, above, name, suffix):
    """1,000 pellets outside every solid but pellet 700 inside one and pellet 900 inside another:
    refused in one line naming shot.file:position, pellet 700's position, the file, pellet 700
    (the first), the surface and what is allowed (exit status 2, nothing written); pellet 900
    named without the first solid; pellet 700 1e-6 m above the solid and pellet 900 outside too:
    the scene is read."""
    solid = _mesh(tmp_path / "box.stl") if solid == "mesh" else {"name": "shed", **solid, **MATERIAL}
    is_post = solid["kind"] == "cylinder"
    other = {"kind": "box", **TILTED} if is_post else POST
    positions = np.c_[np.linspace(-5.0, 5.0, 1000), np.full(1000, -6.0), np.full(1000, 2.0)]
    positions[700], positions[900] = inside, TILTED["point"] if is_post else [-2.0, 2.0, 0.6]
    fortran = "fortran" in suffix
    path = _pellet_file(tmp_path / f"pellets{suffix.replace('-fortran', '')}", positions, fortran)
    surfaces = [GROUND, {"name": "pole", **other, **MATERIAL}, solid]
    raw = {**_sampled([0, 0, 5], surfaces), "shot": {"file": path, "diameter": 0.0025, "density": 7000.0}}
    with pytest.raises(SceneError) as e:
        scene_from_dict(raw)
    message = str(e.value)
    start = f"shot.file:position = {[float(c) for c in inside]}: {path}: pellet 700 starts inside surfaces.2 ('shed', {name})"
    assert message.startswith(start), message
    assert "\n" not in message and message.endswith(
        "outside every post, box and closed mesh (inside a closed mesh wound inwards)"
    )
    (tmp_path / "scene.toml").write_text("\n".join(toml_lines(raw, "")))
    rc, _out, err = cli(["run", tmp_path / "scene.toml", "--device", "cpu", "-o", tmp_path / "out.h5"])
    assert rc == 2 and err.count("\n") == 1 and "pellet 700" in err and "shot.file:position" in err, err
    assert list(tmp_path.glob("out*")) == []
    with pytest.raises(SceneError, match=r": pellet 900 starts inside surfaces\.1 \('pole'"):
        scene_from_dict({**raw, "surfaces": [GROUND, {"name": "pole", **other, **MATERIAL}]})
    positions[700], positions[900] = above, [0.0, -6.0, 2.0]
    _pellet_file(path, positions, fortran)
    assert scene_from_dict(raw).shot.count == 1000


ROOM = {"point": [0.0, 0.0, 1.0], "normal": [0.0, 0.0, 1.0], "axis_u": [1.0, 0.0, 0.0], "size": [6.0, 4.0, 3.0]}
R = 0.00125  # m, the pellets' radius


def _first_contact(x, v, g=9.81):
    """Float64 reference: the time and centre of each pellet's first contact inside ROOM over the
    ground z = 0 (its floor lies below): the least positive time its parabola's centre reaches R
    from a wall, the ceiling or the ground (the room's inside is convex: before that it touches
    nothing), and the surface met (0 the ground, 1 the room)."""
    half = 0.5 * np.asarray(ROOM["size"]) - R
    times = []
    for axis in (0, 1):
        with np.errstate(divide="ignore"):
            times.append(np.where(v[:, axis] > 0, half[axis] - x[:, axis], -half[axis] - x[:, axis]) / v[:, axis])
    for height in (ROOM["point"][2] + half[2], R):  # z0 + vz t - g t^2 / 2 = height: the later root for the ground
        disc = v[:, 2] ** 2 + 2.0 * g * (x[:, 2] - height)
        root = (v[:, 2] + np.sqrt(np.maximum(disc, 0.0))) / g if height == R else (v[:, 2] - np.sqrt(np.maximum(disc, 0.0))) / g
        times.append(np.where(disc >= 0.0, root, np.inf) if height != R else root)
    times = np.stack(times, axis=1)
    times[~(times > 0)] = np.inf
    t = times.min(axis=1)
    centre = x + v * t[:, None] + 0.5 * t[:, None] ** 2 * np.array([0.0, 0.0, -g])
    return t, centre, np.where(times.argmin(axis=1) == 3, 0, 1)


def test_pellets_launched_in_a_room_wound_inwards_stay_in_it(tmp_path):
    """300 pellets (float32, vacuum) launched from random points inside a 6 x 4 x 3 m room (a box's
    STL wound inwards, met from inside) over the ground, 20 to 60 m/s in random directions, to
    their fourth impact: the scene is read (every centre is outside the room's solid), each first
    impact's centre and surface is the float64 parabola's first contact (within 1e-5 m), every
    impact and landing centre lies in the room (R or more from its walls, within 1e-4 m), and no
    pellet's energy (kinetic + potential, per kg) rises."""
    import h5py

    from warp_ricochet.api import run

    rng = np.random.default_rng(3)
    x = rng.uniform([-2.7, -1.7, 0.3], [2.7, 1.7, 2.2], (300, 3))
    d = rng.normal(size=(300, 3))
    v = d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(20.0, 60.0, (300, 1))
    room = {"kind": "mesh", "name": "room", "file": _box_stl(tmp_path / "room.stl", ROOM, flip=True), **MATERIAL}
    physics = {"gravity": [0.0, 0.0, -9.81], "until": "landing", "bounces": 3}
    scene = explicit_scene(tmp_path, x, v, surfaces=[GROUND, room], physics=physics, precision="float32")
    fields = ("impact.surface", "impact.position", "landing.position", "landing.velocity")
    run(scene.replace(output=dataclasses.replace(scene.output, fields=fields)), tmp_path / "room.h5", device="cpu")
    with h5py.File(tmp_path / "room.h5") as f:
        surface = f["pellets/impact/surface"][()].reshape(300, -1)
        impacts = f["pellets/impact/position"][()].reshape(300, -1, 3)
        landing, speed = f["pellets/landing/position"][()], np.linalg.norm(f["pellets/landing/velocity"][()], axis=1)
    _t, centre, first = _first_contact(x, v)
    np.testing.assert_array_equal(surface[:, 0], first)
    assert np.abs(impacts[:, 0] - centre).max() < 1e-5 and (first == 0).sum() > 20 and (first == 1).sum() > 150
    box = scene_from_dict(_sampled([0, 0, 5], [GROUND, {"kind": "box", **ROOM, **MATERIAL}])).surfaces[1]
    assert np.isfinite(landing).all() and (surface >= 0).all()
    for points in (*impacts.transpose(1, 0, 2), landing):
        assert (solid_gaps(box, points) <= -R + 1e-4).all() and (points[:, 2] >= R - 1e-4).all()
    energy = 0.5 * speed**2 + 9.81 * landing[:, 2]
    assert (energy <= 0.5 * np.linalg.norm(v, axis=1) ** 2 + 9.81 * x[:, 2] + 1e-3).all()


def test_pellets_from_a_file_outside_a_room_wound_inwards_are_refused_in_one_line(tmp_path):
    """1,000 pellets inside the room (ROOM wound inwards) but pellet 700 outside it and pellet 900
    on its far side: refused in one line naming shot.file:position, pellet 700's position, the
    file, the surface and that its solid is all outside it (exit status 2, nothing written); with
    both inside, the scene is read and a sampled shot from the room's middle runs (exit status 0)."""
    positions = np.random.default_rng(4).uniform([-2.9, -1.9, 0.1], [2.9, 1.9, 2.4], (1000, 3))
    positions[700], positions[900] = [0.0, 0.0, 2.5 + 1e-6], [0.0, 0.0, -3.0]
    path = _pellet_file(tmp_path / "pellets.npz", positions)
    room = {"kind": "mesh", "name": "room", "file": _box_stl(tmp_path / "room.stl", ROOM, flip=True), **MATERIAL}
    raw = {**_sampled([0, 0, 1], [GROUND, room]), "shot": {"file": path, "diameter": 0.0025, "density": 7000.0}}
    with pytest.raises(SceneError) as e:
        scene_from_dict(raw)
    message = str(e.value)
    start = f"shot.file:position = [0.0, 0.0, {2.5 + 1e-6}]: {path}: pellet 700 starts outside surfaces.1 ('room', a closed "
    assert message.startswith(start + "mesh wound inwards, whose solid is all outside it)") and "\n" not in message, message
    (tmp_path / "scene.toml").write_text("\n".join(toml_lines(raw, "")))
    rc, _out, err = cli(["run", tmp_path / "scene.toml", "--device", "cpu", "-o", tmp_path / "out.h5"])
    assert rc == 2 and err.count("\n") == 1 and "pellet 700" in err and "wound inwards" in err, err
    assert list(tmp_path.glob("out*")) == []
    positions[700], positions[900] = [0.0, 0.0, 2.5 - 1e-6], [0.0, 0.0, 1.0]
    _pellet_file(path, positions)
    assert scene_from_dict(raw).shot.count == 1000
    sampled = _sampled([0.0, 0.0, 1.0], [GROUND, room]) | {"numerics": {"precision": "float32"}}
    (tmp_path / "sampled.toml").write_text("\n".join(toml_lines(sampled, "")))
    rc, _out, err = cli(["run", tmp_path / "sampled.toml", "--device", "cpu", "-o", tmp_path / "sampled.h5"])
    assert rc == 0 and (tmp_path / "sampled.h5").exists(), err


def _stations(surfaces, mid, side=5.0, radius=0.05):
    """Three stations `side` m apart along y, `mid` the position of the middle one, `surfaces`
    beside the ground; the shot's envelope_center is left at its default, the origin (unused: each
    shot starts at its station)."""
    stations = [
        {"name": "left", "position": [0.0, -side, 1.5], "azimuth": [-30.0, 30.0], "elevation": [2.0, 15.0]},
        {"name": "mid", "position": [float(c) for c in mid], "azimuth": 10.0},
        {"name": "right", "position": [0.0, side, 1.5], "azimuth": [-90.0, 90.0], "elevation": 5.0},
    ]
    shot = {"count": 4, "shots": 6, "diameter": 0.0025, "density": 7000.0, "speed": 300.0, "direction": [1.0, 0.0, 0.0]}
    shot["envelope_radius"] = radius
    return {"shot": shot, "surfaces": [GROUND, *surfaces], "physics": {"gravity": [0, 0, -9.81]}, "stations": stations}


HUT = {"point": [0.0, 0.0, 1.0], "normal": [0.0, 0.0, 1.0], "axis_u": [1.0, 1.0, 0.0], "size": [1.0, 1.0, 2.0]}


@pytest.mark.parametrize(
    ("solid", "inside", "near", "name"),
    [
        ({"kind": "box", **HUT}, [0.1, 0.2, 1.5], [0.0, 0.0, 2.01], "is inside surfaces.1 ('hut', a box)"),
        (
            POST | {"point": [0.0, 0.0, 0.0]},
            [0.05, 0.1, 1.0],
            [0.0, 0.16, 1.0],
            "is inside surfaces.1 ('hut', a post (cylinder))",
        ),
        ("mesh", [0.1, 0.2, 1.5], [0.0, 0.0, 2.01], "is inside surfaces.1 ('hut', a closed mesh)"),
        ("room", [0.0, 0.0, 5.0], [2.99, 0.0, 1.0], "is outside surfaces.1 ('hut', a closed mesh wound inwards"),
    ],
    ids=["box", "post", "mesh", "room"],
)
def test_a_station_inside_a_solid_is_refused_in_one_line(tmp_path, solid, inside, near, name):
    """A station's envelope (shot.envelope_radius about its position) is checked as the single
    muzzle's: the middle station inside a box, a post or a closed mesh, or outside a room wound
    inwards, or 0.01 m from it with a 0.05 m radius, is refused in one line naming
    stations.1.position, its value, the station, the surface and the depth (exit status 2, nothing
    written); with every station clear of it the scene is read, though the default, unused
    envelope_center (the origin) lies on the base of the box, the post and the mesh."""
    room = solid == "room"
    if solid in ("mesh", "room"):
        solid = {"kind": "mesh", "file": _box_stl(tmp_path / "hut.stl", ROOM if room else HUT, flip=room)}
    surfaces = [{"name": "hut", **solid, **MATERIAL}]
    side = 1.5 if room else 5.0  # the other stations: inside the room, or clear of the hut
    for where, text in ((inside, name), (near, "is 0.01 m from surfaces.1 ('hut'")):
        with pytest.raises(SceneError) as e:
            scene_from_dict(_stations(surfaces, where, side))
        message = str(e.value)
        assert message.startswith(f"stations.1.position = {where}: station 'mid' {text}") and "\n" not in message, message
        assert message.endswith("outside every post, box and closed mesh (inside a closed mesh wound inwards)")
    assert "reaches 0.04 m into it" in message
    clear = [0.0, 0.0, 1.0] if room else [0.0, -2.0, 1.5]
    scene = scene_from_dict(_stations(surfaces, clear, side))
    assert room or abs(envelope_gap(scene.surfaces[1], np.zeros(3))) < 1e-6  # (the origin: refused without stations)
    assert scene_from_dict(_stations(surfaces, clear, side)).stations[1].position == tuple(clear)
    (tmp_path / "scene.toml").write_text("\n".join(toml_lines(_stations(surfaces, inside, side), "")))
    rc, _out, err = cli(["run", tmp_path / "scene.toml", "--device", "cpu", "-o", tmp_path / "out.h5"])
    assert rc == 2 and err.count("\n") == 1 and "stations.1.position" in err and "station 'mid'" in err, err
    assert list(tmp_path.glob("out*")) == []
