"""The kernels against the NumPy float64 reference of plates and meshes (reference/shapes.py) on
random scenes in vacuum, until landing: the same surface at every impact, and the impacts, the
landing positions and velocities within 1e-6 relative in float64."""

import dataclasses

import h5py
import numpy as np
import pytest
from helpers import explicit_scene

from warp_ricochet.api import run
from warp_ricochet.reference.shapes import closing_root, simulate_shapes

FIELDS = ("impact.surface", "impact.position", "impact.velocity", "landing.position", "landing.velocity", "landing.surface")
GROUND = {"name": "ground", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "restitution": 0.4, "mu_s": 0.3}


def _unit(rng):
    n = rng.normal(size=3)
    return n / np.linalg.norm(n)


def _plates(rng):
    """A rectangle and a disc, tilted at random, facing up-ish, one of them two-sided."""
    surfaces = []
    for kind in ("rectangle", "disc"):
        n = _unit(rng) + [0.0, 0.0, 1.5]
        n /= np.linalg.norm(n)
        s = {"kind": kind, "point": list(rng.uniform([2, -2, 0.5], [8, 2, 2.5])), "normal": list(n)}
        s |= {"restitution": float(rng.uniform(0.2, 0.8)), "mu_s": float(rng.uniform(0.1, 0.5))}
        if kind == "rectangle":
            u = np.cross(n, _unit(rng))
            s |= {"axis_u": list(u / np.linalg.norm(u)), "size": list(rng.uniform(1.0, 4.0, 2))}
        else:
            s["radius"] = float(rng.uniform(0.5, 2.0))
        s["two_sided"] = bool(rng.integers(2))
        surfaces.append(s)
    return surfaces


def _tent(tmp_path, rng):
    """A random open 'tent' of 4 triangles over a square (a ridge: convex and concave seams), as a PLY."""
    trimesh = pytest.importorskip("trimesh")
    c = rng.uniform([3, -3, 0.2], [6, 0, 0.6])
    w = rng.uniform(1.0, 3.0)
    top = c + [0.0, 0.0, rng.uniform(0.3, 1.5)]
    vertices = np.array([c + [-w, -w, 0], c + [w, -w, 0], c + [w, w, 0], c + [-w, w, 0], top])
    faces = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]
    path = tmp_path / "tent.ply"
    trimesh.Trimesh(vertices=vertices, faces=faces, process=False).export(path)
    return {"kind": "mesh", "file": str(path), "restitution": 0.5, "mu_s": 0.3}


def _box(rng):
    n = _unit(rng) + [0.0, 0.0, 2.0]
    n /= np.linalg.norm(n)
    u = np.cross(n, _unit(rng))
    return {
        "kind": "box",
        "point": list(rng.uniform([3, 1, 0.5], [7, 3, 1.0])),
        "normal": list(n),
        "axis_u": list(u / np.linalg.norm(u)),
        "size": list(rng.uniform(0.5, 2.0, 3)),
        "restitution": 0.6,
        "mu_s": 0.25,
    }


def _shots(rng, count):
    """Pellets whose parabolas pass through random points of the surfaces' region after 0.1-0.6 s."""
    x = np.c_[rng.uniform(-1, 1, count), rng.uniform(-2, 2, count), rng.uniform(1.5, 4.0, count)]
    target = rng.uniform([2, -5, 0.2], [9, 4, 2.5], (count, 3))
    t = rng.uniform(0.1, 0.6, count)[:, None]
    v = (target - x) / t + 0.5 * np.array([0.0, 0.0, 9.81]) * t
    return x, v, rng.normal(0, 300, (count, 3))


def _kernels(tmp_path, scene):
    scene = scene.replace(output=dataclasses.replace(scene.output, fields=FIELDS))
    run(scene, tmp_path / "run.h5", device="cpu", overwrite=True)
    with h5py.File(tmp_path / "run.h5") as f:
        return {name: f["pellets/" + name.replace(".", "/")][()] for name in FIELDS}


def _relative(a, b, scale):
    both = ~np.isnan(a).any(axis=-1)
    assert np.array_equal(both, ~np.isnan(b).any(axis=-1))
    return (np.linalg.norm(a - b, axis=-1) / scale)[both]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_kernels_land_where_the_reference_does(tmp_path, seed):
    """Per random scene (the ground, a rectangle, a disc, a box and a tent mesh; one of the plates
    two-sided): float64 kernels and the float64 reference agree on every impact's surface and on
    positions and velocities within 1e-6 relative; each finite surface is met."""
    rng = np.random.default_rng(seed)
    surfaces = [GROUND, *_plates(rng), _box(rng), _tent(tmp_path, rng)]
    x, v, w = _shots(rng, 600)
    physics = {"gravity": [0.0, 0.0, -9.81], "until": "landing", "bounces": 2, "impact_duration": 0.0}
    scene = explicit_scene(tmp_path, x, v, w, surfaces=surfaces, physics=physics)
    got = _kernels(tmp_path, scene)
    ref, _ = simulate_shapes(scene, x, v, w)
    np.testing.assert_array_equal(got["impact.surface"], ref["impact.surface"])
    np.testing.assert_array_equal(got["landing.surface"], ref["landing.surface"])
    met = [(ref["impact.surface"] == k).sum() for k in range(1, 5)]
    assert min(met) >= 5 and (ref["impact.surface"][:, 1] > 0).sum() >= 10, met  # each met; ricochets onto them
    span = np.linalg.norm(ref["landing.position"] - x, axis=1)
    for name in ("impact.position", "impact.velocity"):
        scale = span if name.endswith("position") else np.linalg.norm(v, axis=1)
        err = _relative(got[name], ref[name], scale[:, None])
        assert err.max() <= 1e-6, (name, err.max())
    assert _relative(got["landing.position"], ref["landing.position"], span).max() <= 1e-6
    assert _relative(got["landing.velocity"], ref["landing.velocity"], np.linalg.norm(v, axis=1)).max() <= 1e-6


def test_closing_root_is_the_root_where_the_gap_falls():
    """The reference's root: h(t) = c + b t + a t^2 falling through 0, none when it only rises."""
    np.testing.assert_allclose(closing_root(np.array([1.0, 1.0, -1e-17]), np.array([-1.0, 2.0, 3.0]), -4.9), [
        (1.0 - np.sqrt(1.0 + 19.6)) / -9.8, (-2.0 - np.sqrt(4.0 + 19.6)) / -9.8, 3.0 / 4.9
    ], rtol=1e-15)  # fmt: skip
    assert np.isnan(closing_root(np.array([1.0]), np.array([1.0]), 4.9)).all()
    np.testing.assert_allclose(closing_root(np.array([2.0, 2.0]), np.array([-4.0, 4.0]), 0.0), [0.5, np.nan])


def test_the_kernels_land_on_a_random_terrain_where_the_reference_does(tmp_path):
    """A random 9 x 7 raster (96 triangles; ESRI ASCII grid) placed with its origin and elevation:
    the same surfaces at every impact, landings within 1e-6 relative."""
    pytest.importorskip("rasterio")
    rng = np.random.default_rng(5)
    z = 100.0 + rng.uniform(-0.8, 0.8, (7, 9))
    header = "ncols 9\nnrows 7\nxllcorner 600000.0\nyllcorner 4100000.0\ncellsize 1.5\nNODATA_value -9999\n"
    (tmp_path / "dem.asc").write_text(header + "\n".join(" ".join(f"{h:.6f}" for h in row) for row in z) + "\n")
    terrain = {"kind": "terrain", "file": str(tmp_path / "dem.asc"), "origin": [599996.0, 4100000.0], "elevation": 99.0}
    terrain |= {"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "restitution": 0.5, "mu_s": 0.3}
    x = np.c_[rng.uniform(-1, 1, 400), rng.uniform(-1, 1, 400), rng.uniform(2.0, 3.0, 400)]
    target = rng.uniform([4.5, 1.0, 0.0], [16.0, 10.0, 0.0], (400, 3))
    t = rng.uniform(0.2, 0.5, 400)[:, None]
    v = (target - x) / t + 0.5 * np.array([0.0, 0.0, 9.81]) * t
    physics = {"gravity": [0.0, 0.0, -9.81], "until": "landing", "bounces": 1, "impact_duration": 0.0}
    scene = explicit_scene(tmp_path, x, v, surfaces=[terrain, GROUND | {"point": [0.0, 0.0, -5.0]}], physics=physics)
    got = _kernels(tmp_path, scene)
    ref, _ = simulate_shapes(scene, x, v, np.zeros_like(x))
    np.testing.assert_array_equal(got["impact.surface"], ref["impact.surface"])
    assert (ref["impact.surface"][:, 0] == 0).sum() > 200 and (ref["landing.surface"] == 0).sum() > 20
    span = np.linalg.norm(ref["landing.position"] - x, axis=1)
    assert _relative(got["landing.position"], ref["landing.position"], span).max() <= 1e-6
    assert _relative(got["landing.velocity"], ref["landing.velocity"], np.linalg.norm(v, axis=1)).max() <= 1e-6
