"""Launches inside a solid are refused (docs/geometry.md, "Launches inside a solid"): a sampled
shot's envelope reaching into a closed mesh, as into a post or a box, and pellets of a file
(`shot.file`) starting inside a post, a box or a closed mesh: one line naming the key, the value,
the solid and what is allowed, exit status 2, nothing written. The closed-mesh test is the
generalized winding number (`scene.solids`), checked here against the analytic inside of a box."""

import numpy as np
import pytest
from helpers import cli

from warp_ricochet.errors import SceneError
from warp_ricochet.scene import scene_from_dict
from warp_ricochet.scene.solids import closed_triangles, envelope_gap, inside_rows, solid_gaps, winding_numbers
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


def test_the_winding_number_tells_a_closed_boxs_inside_as_its_geometry_does(tmp_path):
    """20,000 random points about a tilted box, a third of them within 1e-5 m of a face: inside
    the closed mesh of its STL (winding number > 1/2) exactly where the box's exact signed
    distance is negative (but for points within 1e-6 m of a face: the STL holds float32
    vertices, 2.4e-7 m apart at 3 m), and its envelope gap equals that distance within 1e-6 m."""
    rng = np.random.default_rng(5)
    axes, centre = _frame()
    half = 0.5 * np.asarray(TILTED["size"])
    local = rng.uniform(-1.5, 1.5, (20000, 3)) * half
    face = rng.integers(0, 3, 20000)
    near = np.arange(20000) % 3 == 0
    local[near, face[near]] = rng.choice([-1.0, 1.0], near.sum()) * half[face[near]] + rng.uniform(-1e-5, 1e-5, near.sum())
    x = centre + local @ axes
    mesh = scene_from_dict(_sampled([0.0, 0.0, 5.0], [GROUND, _mesh(tmp_path / "box.stl")])).surfaces[1]
    box = scene_from_dict(_sampled([0.0, 0.0, 5.0], [GROUND, {"kind": "box", **TILTED, **MATERIAL}])).surfaces[1]
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


def test_open_or_inward_meshes_are_not_solids(tmp_path):
    """A box's STL less one triangle (open) and one wound inwards (met from inside) refuse nothing:
    no volume is met from outside only."""
    open_ = scene_from_dict(_sampled([0, 0, 5], [GROUND, _mesh(tmp_path / "open.stl", drop=3)])).surfaces[1]
    inward = scene_from_dict(_sampled([0, 0, 5], [GROUND, _mesh(tmp_path / "in.stl", flip=True)])).surfaces[1]
    assert closed_triangles(open_) is None and closed_triangles(inward) is not None
    centre = np.asarray(TILTED["point"], float)
    assert envelope_gap(open_, centre) is None and envelope_gap(inward, centre) > 0.0
    for mesh in ("open.stl", "in.stl"):
        raw = _sampled(TILTED["point"], [GROUND, {"kind": "mesh", "file": str(tmp_path / mesh), **MATERIAL}])
        assert scene_from_dict(raw).shot.envelope_center == tuple(TILTED["point"])


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
    assert "\n" not in message and message.endswith("outside every post, box and closed mesh")
    (tmp_path / "scene.toml").write_text("\n".join(toml_lines(raw, "")))
    rc, _out, err = cli(["run", tmp_path / "scene.toml", "--device", "cpu", "-o", tmp_path / "out.h5"])
    assert rc == 2 and err.count("\n") == 1 and "pellet 700" in err and "shot.file:position" in err, err
    assert list(tmp_path.glob("out*")) == []
    with pytest.raises(SceneError, match=r": pellet 900 starts inside surfaces\.1 \('pole'"):
        scene_from_dict({**raw, "surfaces": [GROUND, {"name": "pole", **other, **MATERIAL}]})
    positions[700], positions[900] = above, [0.0, -6.0, 2.0]
    _pellet_file(path, positions, fortran)
    assert scene_from_dict(raw).shot.count == 1000
