"""Triangle surfaces (docs/geometry.md, "Meshes and boxes"): meshes read from files and closed boxes.

Their scene keys are checked in one line each; a closed box's 12 triangles face outwards."""

import dataclasses
import os
from pathlib import Path

import numpy as np
import pytest
from helpers import explicit_scene

from bench.meshes import BOX, aimed, box_shots, inside_box
from warp_ricochet.errors import SceneError
from warp_ricochet.scene import scene_from_dict
from warp_ricochet.scene.triangles import TriangleSurface, box_triangles, load_mesh

trimesh = pytest.importorskip("trimesh")

MATERIAL = {"restitution": 0.5, "mu_s": 0.3}
SQUARE = np.array([[0.0, 0.0, 0.0], [100.0, 0.0, 0.0], [100.0, 100.0, 0.0], [0.0, 100.0, 0.0]])  # z = 0, up +z


def _write(path, vertices, faces):
    trimesh.Trimesh(vertices=vertices, faces=faces, process=False).export(path)
    return str(path)


def _raw(surfaces, **physics):
    shot = {"count": 4, "diameter": 0.0025, "density": 7000.0, "speed": 300.0, "direction": [1.0, 0.0, -0.05]}
    shot |= {"envelope_radius": 0.01, "envelope_center": [0.0, 0.0, 1.0]}
    return {"shot": shot, "surfaces": surfaces, "physics": {"until": "landing", "gravity": [0, 0, -9.81], **physics}}


@pytest.mark.parametrize("suffix", ["stl", "obj", "ply"])
def test_a_mesh_file_is_read_into_scene_coordinates(tmp_path, suffix):
    path = _write(tmp_path / f"square.{suffix}", SQUARE, [[0, 1, 2], [0, 2, 3]])
    mesh = load_mesh(path, "surfaces.0.file", offset=(1.0, 2.0, 3.0))
    assert mesh.vertices.dtype == np.float64 and mesh.triangles.dtype == np.int32
    corners = np.unique(np.round(mesh.vertices, 9), axis=0)
    assert np.array_equal(corners, np.unique(SQUARE + [1.0, 2.0, 3.0], axis=0))
    assert np.allclose(mesh.normals(), [0.0, 0.0, 1.0])  # counter-clockwise from above: up
    scene = scene_from_dict(_raw([{"kind": "mesh", "file": f"square.{suffix}", "point": [1, 2, 3], **MATERIAL}]), tmp_path)
    assert scene.surfaces[0].is_mesh and scene.surfaces[0].file == path


def test_a_box_is_closed_and_faces_outwards():
    box = box_triangles((1.0, 2.0, 3.0), (0.0, 0.0, 2.0), (1.0, 1.0, 0.0), (1.0, 2.0, 3.0))
    centroids = box.vertices[box.triangles].mean(axis=1)
    assert len(box.triangles) == 12 and (np.einsum("ij,ij->i", box.normals(), centroids - [1.0, 2.0, 3.0]) > 0).all()
    edges = np.sort(box.triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    assert (np.unique(edges, axis=0, return_counts=True)[1] == 2).all()  # every edge shared by two triangles
    assert np.isclose(abs(np.linalg.det(box.vertices[[4, 2, 1]] - box.vertices[0])), 1.0 * 2.0 * 3.0)


@pytest.mark.parametrize(
    ("vertices", "triangles", "message"),
    [
        (np.zeros((0, 3)), np.zeros((0, 3), np.int32), "at least one triangle"),
        ([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]], [[0, 1, 2]], "finite vertices"),
        (
            [[0, 0, 0], [1, 0, 0], [0, 1, 1e30]],
            [[0, 1, 2]],
            r"vertex 2 at \[0.0, 1.0, 1e\+30\] m; vertices must be within \+-1e\+06 m",
        ),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 3]], "vertex index outside 0 to 2"),
        ([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]], "no triangle of nonzero area"),
    ],
)
def test_a_bad_mesh_is_one_line(vertices, triangles, message):
    surface = TriangleSurface(np.asarray(vertices, float), np.asarray(triangles, np.int32), "m.stl")
    with pytest.raises(SceneError, match=message) as caught:
        surface.check("surfaces.0.file")
    assert "\n" not in str(caught.value) and str(caught.value).startswith("surfaces.0.file")


@pytest.mark.parametrize(
    ("surface", "key", "message"),
    [
        ({"kind": "mesh", "file": "nowhere.stl"}, "surfaces.0.file", "existing mesh file"),
        ({"kind": "mesh", "file": "junk.stl"}, "surfaces.0.file", "at least one triangle"),
        ({"kind": "mesh", "file": "junk.toml"}, "surfaces.0.file", r"must be a triangle mesh \(STL, OBJ or PLY\) .*: file_type"),
        ({"kind": "mesh"}, "surfaces.0.file", "required for kind = 'mesh'"),
        ({"kind": "mesh", "file": "square.stl", "radius": 1.0}, "surfaces.0.radius", "of kind = 'disc' or 'cylinder' only"),
        (
            {"kind": "box", "point": [0, 0, 0], "normal": [0, 0, 1], "axis_u": [1, 0, 0], "size": [1, 1]},
            "surfaces.0.size",
            "3 numbers",
        ),
        (
            {"kind": "box", "point": [0, 0, 0], "normal": [0, 0, 1], "axis_u": [0, 0, 1], "size": [1, 1, 1]},
            "surfaces.0.axis_u",
            "perpendicular",
        ),
        (
            {"kind": "rectangle", "point": [0, 0, 0], "normal": [0, 0, 1], "axis_u": [1, 0, 0], "size": [1, 1, 1]},
            "surfaces.0.size",
            "2 numbers",
        ),
    ],
)
def test_bad_mesh_keys_are_one_line_errors(tmp_path, surface, key, message):
    _write(tmp_path / "square.stl", SQUARE, [[0, 1, 2], [0, 2, 3]])
    (tmp_path / "junk.stl").write_text("not a mesh")
    (tmp_path / "junk.toml").write_text("[shot]")  # (trimesh reads no .toml: what is allowed, then its reason)
    with pytest.raises(SceneError, match=message) as caught:
        scene_from_dict(_raw([surface | MATERIAL]), tmp_path)
    assert "\n" not in str(caught.value) and str(caught.value).startswith(key)


def test_meshes_are_met_until_rest_and_with_collisions(tmp_path):
    box = {"kind": "box", "point": [5, 0, 0], "normal": [0, 0, 1], "axis_u": [1, 0, 0], "size": [1, 1, 1], **MATERIAL}
    assert scene_from_dict(_raw([box], until="rest"), tmp_path).physics.until == "rest"  # (tests/test_mesh_rest.py)
    assert scene_from_dict(_raw([box]) | {"collisions": {"enabled": True}}, tmp_path).pair_collisions  # (test_dense_solids.py)


def _landings(tmp_path, x, v, surfaces, precision="float64", name="run", air=None):
    """Per pellet: (surface of its first impact, its centre there, landing position), in vacuum
    or in `air`, landing at the second impact."""
    import h5py

    from warp_ricochet.api import run

    physics = {"gravity": [0.0, 0.0, -9.81], "until": "landing", "bounces": 1}
    scene = explicit_scene(tmp_path, x, v, surfaces=surfaces, physics=physics, precision=precision, name=f"{name}.npz")
    scene = scene.replace(
        output=dataclasses.replace(scene.output, fields=("impact.surface", "impact.position", "landing.position"))
    )
    if air is not None:
        scene = scene_from_dict({**scene.to_dict(), "air": air})
    assert scene.in_air == (air is not None)
    run(scene, tmp_path / f"{name}.h5", device="cpu", overwrite=True)
    with h5py.File(tmp_path / f"{name}.h5") as f:
        first = f["pellets/impact/surface"][()].reshape(len(x), -1)[:, 0]
        return first, f["pellets/impact/position"][()].reshape(len(x), -1, 3)[:, 0], f["pellets/landing/position"][()]


def _tilted_square(tmp_path, normal, point, half=1.0e4):
    """A two-triangle square of side 2 half on the plane (point, normal), written as an STL."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    u = np.cross(n, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(n, u)
    corners = np.asarray(point) + half * np.array([-u - w, u - w, u + w, -u + w])
    return _write(tmp_path / "square.stl", corners, [[0, 1, 2], [0, 2, 3]]), n


@pytest.mark.parametrize("air", [None, {"density": 1.225}], ids=["vacuum", "air"])
@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_a_two_triangle_mesh_lands_where_its_plane_does(tmp_path, precision, air):
    """Issue 27, part 4: within 1e-6 relative of the analytic plane in float64 (float32: 1e-3),
    in vacuum and in air (the same steps, searched per triangle)."""
    path, n = _tilted_square(tmp_path, [0.05, -0.1, 1.0], [3.0, -2.0, 0.5])
    rng = np.random.default_rng(7)
    count = 2000 if air is None else 300
    x = np.c_[rng.uniform(-1, 1, count), rng.uniform(-1, 1, count), rng.uniform(1.0, 3.0, count)]
    v = np.c_[rng.normal(0, 60, count), rng.normal(0, 60, count), rng.uniform(-40, 40, count)]
    plane = {"point": [3.0, -2.0, 0.5], "normal": list(n), **MATERIAL}
    hit_plane, _, at_plane = _landings(tmp_path, x, v, [plane], precision, "plane", air)
    hit_mesh, _, at_mesh = _landings(tmp_path, x, v, [{"kind": "mesh", "file": path, **MATERIAL}], precision, "mesh", air)
    assert (hit_plane == 0).all() and (hit_mesh == 0).all() and not np.isnan(at_plane).any()
    error = np.linalg.norm(at_mesh - at_plane, axis=1) / np.linalg.norm(at_plane - x, axis=1)
    assert error.max() <= (1e-6 if precision == "float64" else 1e-3), error.max()  # float32: vertices at 1e4 m


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_pellets_aimed_at_shared_edges_and_vertices_do_not_pass(tmp_path, precision):
    """Centres aimed exactly at the diagonal shared by the two triangles and at their shared vertices
    (at the surface offset by R and at the surface itself): every one meets the mesh."""
    half = 8.0
    corners = np.array([[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]])
    path = _write(tmp_path / "square.stl", corners, [[0, 1, 2], [0, 2, 3]])
    rng = np.random.default_rng(3)
    s = np.r_[rng.uniform(-half, half, 400), -half, half, 0.0]
    for level in (0.00125, 0.0):
        targets = np.c_[s, s, np.full(len(s), level)]
        v = np.c_[rng.normal(0, 20, len(s)), rng.normal(0, 20, len(s)), rng.uniform(-80, -1, len(s))]
        hit, at, _ = _landings(
            tmp_path, aimed(targets, v), v, [{"kind": "mesh", "file": path, **MATERIAL}], precision, f"edge{level}"
        )
        assert (hit == 0).all(), np.flatnonzero(hit != 0)
        assert (at[:, 2] >= -1e-6).all() and (np.abs(at[:, 2] - 0.00125) <= 1e-5).sum() > 300


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_no_pellet_fired_at_a_closed_box_ends_inside(tmp_path, precision):
    """Issue 27, part 4: pellets fired at a closed box from all sides (and exactly at its edges and
    vertices) all meet it, and no centre is inside it at an impact or the landing after it (on the
    box or on the ground below it)."""
    x, v = box_shots(np.random.default_rng(11), 20000, BOX)
    ground = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], **MATERIAL}
    hit, first, landing = _landings(tmp_path, x, v, [{"kind": "box", **BOX, **MATERIAL}, ground], precision, "box")
    slack = 1e-9 if precision == "float64" else 1e-5
    assert (hit == 0).all(), np.flatnonzero(hit != 0)[:10]
    assert not inside_box(first, BOX, slack).any()
    landed = ~np.isnan(landing).any(axis=1)
    assert landed.sum() > 100 and not inside_box(landing[landed], BOX, slack).any()


@pytest.mark.parametrize("air", [None, {"density": 1.225}], ids=["vacuum", "air"])
def test_a_small_mesh_tested_whole_meets_what_its_bvh_finds(tmp_path, air):
    """A mesh of at most FEW_FACES triangles has every triangle tested; the same box with tiny
    triangles added deep inside it (never reached), too many to test whole, is searched through its
    BVH: the same first surface, impact centre and landing for every pellet, bit for bit."""
    from warp_ricochet.physics.mesh_contact import FEW_FACES

    box = box_triangles(BOX["point"], BOX["normal"], BOX["axis_u"], BOX["size"])
    rng = np.random.default_rng(5)
    inner = np.asarray(BOX["point"]) + 1e-3 * rng.uniform(-1, 1, (3 * FEW_FACES, 3))
    faces = np.r_[box.triangles, len(box.vertices) + np.arange(3 * FEW_FACES).reshape(-1, 3)]
    assert len(box.triangles) <= FEW_FACES < len(faces)
    whole = _write(tmp_path / "box.obj", box.vertices, box.triangles)
    searched = _write(tmp_path / "box_inside.obj", np.r_[box.vertices, inner], faces)
    x, v = box_shots(np.random.default_rng(9), 3000 if air is None else 300, BOX)
    runs = [
        _landings(tmp_path, x, v, [{"kind": "mesh", "file": f, **MATERIAL}], "float64", Path(f).stem, air)
        for f in (whole, searched)
    ]
    assert (runs[0][0] == 0).all()
    for a, b in zip(*runs):
        np.testing.assert_array_equal(a, b)


def test_a_pellet_grazing_a_box_edge_bounces_off_the_face_it_meets(tmp_path):
    """Two float32 pellets of `bench.meshes box` (seed 27) that skim the top face and meet the
    side face's plane within rounding of its top edge: the impact takes the normal of the face
    they approach (not the nearest triangle's, which they leave: taken for a rest, no impact)."""
    rng = np.random.default_rng(27)
    box_shots(rng, 1000)
    x, v = box_shots(rng, 500000)
    pick = [426431, 492834]
    hit, first, _ = _landings(tmp_path, x[pick], v[pick], [{"kind": "box", **BOX, **MATERIAL}], "float32", "graze")
    assert (hit == 0).all() and not np.isnan(first).any() and not inside_box(first, BOX, 1e-5).any()


def test_the_command_line_refuses_a_bad_mesh_in_one_line_and_runs_a_good_one(tmp_path):
    from helpers import cli

    from warp_ricochet.scene.toml_out import toml_lines

    _write(tmp_path / "square.stl", SQUARE - [50.0, 50.0, 0.0], [[0, 1, 2], [0, 2, 3]])
    (tmp_path / "junk.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")  # one triangle of zero area
    for name, expected in (("junk.obj", 2), ("square.stl", 0)):
        raw = _raw([{"kind": "mesh", "file": name, **MATERIAL}])
        (tmp_path / "scene.toml").write_text("\n".join(toml_lines(raw, "")))
        rc, _out, err = cli(["run", tmp_path / "scene.toml", "--device", "cpu", "-o", tmp_path / "out.h5"])
        assert rc == expected, err
        if expected:
            assert err.count("\n") == 1 and "surfaces.0.file" in err and "nonzero area" in err, err
            assert not (tmp_path / "out.h5").exists()
    assert (tmp_path / "out.h5").exists()


def test_the_benchmarks_terrain_is_the_raster_it_claims(tmp_path):
    """`bench.meshes terrain_raster`: (cells + 1)^2 samples read back as 2 cells^2 triangles of
    CELL m, heights within 0.5 m of 0 and slopes below 0.022 (a few times the paper's ricochet angle)."""
    pytest.importorskip("rasterio")
    from bench.meshes import CELL, terrain_raster
    from warp_ricochet.scene.terrain import load_terrain

    vertices, triangles = load_terrain(terrain_raster(tmp_path, cells=40))
    assert len(triangles) == 2 * 40 * 40 and len(vertices) == 41 * 41
    assert np.abs(vertices[:, 2]).max() <= 0.5 and np.ptp(vertices[:, 0]) == 40 * CELL
    n = TriangleSurface(vertices, triangles, "bench").normals()
    assert (n[:, 2] > 0).all() and np.hypot(n[:, 0], n[:, 1]).max() / n[:, 2].min() < 0.022


@pytest.mark.parametrize(
    ("argv", "want"),
    [
        (["bench.meshes", "box", "--jitter", "nan"], "argument --jitter: 'nan': must be a fraction in [0, 1)"),
        (["bench.meshes", "box", "--jitter", "-0.1"], "argument --jitter: '-0.1': must be a fraction in [0, 1)"),
        (["bench.meshes", "box", "--jitter", "1"], "argument --jitter: '1': must be a fraction in [0, 1)"),
        (["bench.rest", "kernels", "--shots", "0"], "argument --shots: '0': must be a whole number in [1, "),
        (["bench.rest", "kernels", "--count", "1.5"], "argument --count: '1.5': must be a whole number in [1, "),
    ],
)
def test_the_benchmarks_refuse_odd_options_in_one_line(argv, want, capsys):
    """`python -m bench.meshes box --jitter` and `bench.rest kernels`' counts: argparse's usage and
    one line, exit 2, before any work (a NaN jitter or 0 shots once ran the warm-up and ended in a traceback)."""
    import importlib

    module = importlib.import_module(argv[0])
    with pytest.raises(SystemExit) as exc:
        module.main(argv[1:])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.splitlines()[-1].startswith(f"python -m {argv[0]}: error: {want}"), err


def test_a_mesh_file_edited_between_runs_is_read_again(tmp_path):
    """A model is reused only while its mesh files are unchanged: the same scene after its file is
    rewritten in the same process (a notebook's second run) takes the new triangles, as a new
    process would (before, the cached model kept the old ones while `RunSpec` read the new file)."""
    from warp_ricochet.device import resolve_device
    from warp_ricochet.model import Model

    path = _write(tmp_path / "square.obj", SQUARE, [[0, 1, 2], [0, 2, 3]])
    raw = _raw([{"kind": "mesh", "file": "square.obj", **MATERIAL}])
    device = resolve_device("cpu")
    before = Model.from_scene(scene_from_dict(raw, tmp_path), device).meshes[0].vertices
    _write(path, SQUARE + [0.0, 0.0, -2.0], [[0, 1, 2], [0, 2, 3]])
    stamp = Path(path).stat()
    os.utime(path, ns=(stamp.st_atime_ns, stamp.st_mtime_ns + 10**9))  # (a coarse clock: a new time)
    after = Model.from_scene(scene_from_dict(raw, tmp_path), device).meshes[0].vertices
    assert np.array_equal(before[:, 2], np.zeros(4)) and np.array_equal(after[:, 2], np.full(4, -2.0))
