"""The surfaces behind one interface (physics/geometry.py): it is the only code that reads the
`Surfaces` struct's fields (read from the source with `ast`), and its queries agree with NumPy
float64 on random planes and points: height, rounding scale, normal, material, a step's gaps, the
parabola's next contact (`reference.ballistic.next_contact`), and the normal a flight's contact
carries (in vacuum and in air)."""

import ast
import math
from pathlib import Path

import numpy as np
import pytest
import warp as wp

from warp_ricochet.physics.geometry import make_geometry, project
from warp_ricochet.physics.types import GROUND_FIELDS, surfaces_of, types_for
from warp_ricochet.reference.ballistic import next_contact as reference_next_contact

PACKAGE = Path(__file__).resolve().parents[1] / "warp_ricochet"
GEOMETRY = PACKAGE / "physics" / "geometry.py"
MESH_GEOMETRY = PACKAGE / "physics" / "mesh_contact.py"  # the meshes' part of the interface, used by geometry.py
POST_GEOMETRY = PACKAGE / "physics" / "cylinder_contact.py"  # the posts' part of the interface
EDGE_GEOMETRY = PACKAGE / "physics" / "edge_contact.py"  # the meshes' convex edges and corners
GRID_GEOMETRY = PACKAGE / "physics" / "grid_walk.py"  # a terrain's raster, walked
FLAT_GEOMETRY = PACKAGE / "physics" / "flat_contact.py"  # a flat mesh's plane
KERNEL_PACKAGES = ("core", "dense", "physics", "tallies")
RADIUS, GRAVITY = 0.00125, (0.0, -9.81, 0.0)


def _surfaces_fields():
    """The field names of the `Surfaces` struct, from physics/types.py's source."""
    tree = ast.parse((PACKAGE / "physics" / "types.py").read_text())
    cls = next(n for n in ast.walk(tree) if isinstance(n, ast.ClassDef) and n.name == "Surfaces")
    return {n.target.id for n in cls.body if isinstance(n, ast.AnnAssign)}


def _reads(path, fields):
    """(line, source) of every read of an attribute in `fields` of an expression that names a
    surface or plane (`surfaces.normal[k]`, `scene.surfaces[i].point`, `plane.normal`)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Attribute) and node.attr in fields and isinstance(node.ctx, ast.Load):
            base = ast.unparse(node.value).lower()
            if "surface" in base or "plane" in base:
                found.append((node.lineno, ast.unparse(node)))
    return found


def test_only_the_geometry_module_reads_the_surfaces():
    """No solver reads a surface's arrays or a scene plane's point and normal: only
    physics/geometry.py does (model.py fills the struct; reference/ is the independent NumPy
    reference and io/, report/ write and draw the scene's planes)."""
    fields = _surfaces_fields()
    ground = {*GROUND_FIELDS, "liquid"}  # the ground materials' (physics.types.Material)
    plates = {"kind", "axis_u", "axis_v", "half_u", "half_v", "two_sided"}  # (physics.types: read with plates only)
    meshes = {
        "mesh",
        "mesh_first",
        "mesh_low",
        "mesh_high",
        "mesh_points",
        "mesh_triangles",
        "mesh_edge",
        "mesh_faces",
    }  # (read with meshes only)
    meshes |= {
        "face_first",
        "face_edges",
        "face_corners",
        "face_cover",
        "face_depth",
        "edge_ends",
        "corner_points",
    }  # (physics.edge_contact)
    meshes |= {"flat_point", "flat_normal", "flat_slack", "flat_edge", "flat_offset"}  # (physics.flat_contact)
    meshes |= {
        "grid_dims",
        "grid_first",
        "grid_origin",
        "grid_col",
        "grid_row",
        "grid_up",
        "grid_level",
        "grid_top",
        "grid_cell",
        "grid_slack",
    }
    assert fields == {"point", "normal", "point_noise", "restitution", "mu_s", "mu_d", *ground, *plates, *meshes}, (
        fields
    )  # (the parse found the struct)
    assert len(_reads(GEOMETRY, fields)) >= 5  # (the test sees the reads where they are)
    offenders = []
    for package in KERNEL_PACKAGES:
        for path in sorted((PACKAGE / package).rglob("*.py")):
            if path not in (GEOMETRY, MESH_GEOMETRY, POST_GEOMETRY, EDGE_GEOMETRY, GRID_GEOMETRY, FLAT_GEOMETRY):
                offenders += [f"{path.relative_to(PACKAGE)}:{line}: {text}" for line, text in _reads(path, fields)]
    for path in sorted(PACKAGE.rglob("*.py")):  # the kernels' struct is named `surfaces` everywhere
        if (
            path not in (GEOMETRY, MESH_GEOMETRY, POST_GEOMETRY, EDGE_GEOMETRY, GRID_GEOMETRY, FLAT_GEOMETRY)
            and path.parent.name not in KERNEL_PACKAGES
        ):
            for node in ast.walk(ast.parse(path.read_text())):
                if (
                    isinstance(node, ast.Attribute)
                    and node.attr in fields
                    and isinstance(node.ctx, ast.Load)
                    and isinstance(node.value, ast.Name)
                    and node.value.id == "surfaces"
                ):
                    offenders.append(f"{path.relative_to(PACKAGE)}:{node.lineno}: {ast.unparse(node)}")
    assert not offenders, "read the surfaces through physics.geometry:\n" + "\n".join(offenders)


def _random_planes(rng, count):
    normals = rng.normal(size=(count, 3))
    normals[:, 1] = np.abs(normals[:, 1]) + 0.3  # mostly facing up, against gravity
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    points = rng.uniform(-0.5, 0.5, (count, 3))
    materials = rng.uniform(0.0, 1.0, (count, 3))
    materials[:, 2] *= materials[:, 1]  # mu_d <= mu_s
    return points, normals, materials


def _surfaces(precision, points, normals, materials, device="cpu"):
    return surfaces_of(precision, points, normals, materials, device)


def _physics(precision, air=None, device="cpu"):
    from warp_ricochet.model import air_struct

    physics = types_for(precision).Physics()
    physics.radius = RADIUS
    physics.inertia_factor = 0.4
    physics.gravity = GRAVITY
    physics.impact_duration = 1e-5
    mass = 7000.0 * 4.0 / 3.0 * math.pi * RADIUS**3
    physics.air = air_struct(air, precision, device, RADIUS, mass, GRAVITY, 1e-6)
    return physics


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_the_point_queries_match_numpy(precision):
    """locate (height n.(x - p), its rounding scale sum (|x_i| + |p_i|) |n_i|, the normal), normal,
    material and step_gaps, for 4 random planes at 500 random points, within the precision's
    rounding of NumPy float64 on the same (rounded) inputs; the material exactly."""
    t = types_for(precision)
    scalar, vec3, Surfaces = t.scalar, t.vec3, t.Surfaces
    geo = make_geometry(precision)

    @wp.kernel(enable_backward=False, module="unique")
    def queries(
        surfaces: Surfaces,
        x: wp.array(dtype=vec3),
        v: wp.array(dtype=vec3),
        a: wp.array(dtype=vec3),
        h: scalar,
        heights: wp.array2d(dtype=scalar),
        normals: wp.array2d(dtype=vec3),
        materials: wp.array2d(dtype=vec3),
        gaps: wp.array3d(dtype=scalar),
    ):
        i = wp.tid()
        for k in range(geo.count(surfaces)):
            height, noise, n = geo.locate(surfaces, k, x[i])
            heights[i, 2 * k] = height
            heights[i, 2 * k + 1] = noise
            normals[i, 2 * k] = n
            normals[i, 2 * k + 1] = geo.normal(surfaces, k, x[i])
            m = geo.material(surfaces, k, x[i])
            materials[i, k] = vec3(m.restitution, m.mu_s, m.mu_d)
            g0, s0, q0, g1, s1, q1 = geo.step_gaps(surfaces, k, scalar(RADIUS), h, x[i], v[i], a[i], x[i + 1], v[i + 1], a[i + 1])
            gaps[i, k, 0] = g0
            gaps[i, k, 1] = s0
            gaps[i, k, 2] = q0
            gaps[i, k, 3] = g1
            gaps[i, k, 4] = s1
            gaps[i, k, 5] = q1

    rng = np.random.default_rng(25)
    dtype, planes, n = np.dtype(precision), 4, 500
    points, normals, materials = (a.astype(dtype) for a in _random_planes(rng, planes))
    x = rng.uniform(-3.0, 3.0, (n + 1, 3)).astype(dtype)
    v = rng.normal(0.0, 100.0, (n + 1, 3)).astype(dtype)
    a = rng.normal(0.0, 50.0, (n + 1, 3)).astype(dtype)
    step = 1e-3
    out = (
        wp.zeros((n, 2 * planes), dtype=scalar),
        wp.zeros((n, 2 * planes), dtype=vec3),
        wp.zeros((n, planes), dtype=vec3),
        wp.zeros((n, planes, 6), dtype=scalar),
    )
    inputs = [_surfaces(precision, points, normals, materials), *(wp.array(z, dtype=vec3) for z in (x, v, a)), step]
    wp.launch(queries, dim=n, inputs=inputs + list(out), device="cpu")
    heights, got_normals, got_materials, gaps = (o.numpy().astype(np.float64) for o in out)
    eps = float(np.finfo(dtype).eps)
    p, nrm, x, v, a = (z.astype(np.float64) for z in (points, normals, x, v, a))
    offset = x[:n, None, :] - p[None]  # (n, planes, 3)
    scale = ((np.abs(x[:n, None, :]) + np.abs(p[None])) * np.abs(nrm[None])).sum(-1)
    np.testing.assert_allclose(heights[:, 0::2], (offset * nrm[None]).sum(-1), rtol=0, atol=4 * eps * (scale.max() + 1))
    np.testing.assert_allclose(heights[:, 1::2], scale, rtol=4 * eps)
    assert (got_normals[:, 0::2] == nrm[None]).all() and (got_normals[:, 1::2] == nrm[None]).all()
    assert (got_materials == materials.astype(np.float64)[None]).all()
    level = p @ nrm.T
    level = np.diag(level) + RADIUS  # n_k . p_k + R
    want = np.stack(
        [
            x[:n] @ nrm.T - level,
            step * (v[:n] @ nrm.T),
            step * step * (a[:n] @ nrm.T),
            x[1:] @ nrm.T - level,
            step * (v[1:] @ nrm.T),
            step * step * (a[1:] @ nrm.T),
        ],
        axis=-1,
    )
    magnitude = np.abs(np.stack([np.abs(x).sum(-1)[:n], step * np.abs(v).sum(-1)[:n], step**2 * np.abs(a).sum(-1)[:n]] * 2, -1))
    assert (np.abs(gaps - want) <= 8 * eps * (magnitude[:, None, :] + 1)).all()


def _contact_kernel(precision, planes, model, laws=None):
    from warp_ricochet.physics.flight import make_flight

    t = types_for(precision)
    scalar, vec3, Surfaces, Physics = t.scalar, t.vec3, t.Surfaces, t.Physics
    geo = make_geometry(precision, planes)
    flight = make_flight(precision, planes, model, laws)
    BALLISTIC = model == "ballistic"

    @wp.kernel(enable_backward=False, module="unique")
    def contacts(
        surfaces: Surfaces,
        physics: Physics,
        x: wp.array(dtype=vec3),
        v: wp.array(dtype=vec3),
        touching: wp.array(dtype=wp.int32),
        times: wp.array(dtype=scalar),
        indices: wp.array(dtype=wp.int32),
        normals: wp.array(dtype=vec3),
        positions: wp.array(dtype=vec3),
        flown: wp.array(dtype=wp.int32),
    ):
        i = wp.tid()
        if wp.static(BALLISTIC):
            t, k = geo.next_contact(surfaces, x[i], v[i], physics.gravity, physics.radius, touching[i])
            times[i] = t
            indices[i] = k
        dt, k2, n, x2, _v, _w, _steps = flight.to_contact(x[i], v[i], vec3(), touching[i], surfaces, physics)
        flown[i] = k2
        normals[i] = n
        positions[i] = x2
        if wp.static(not BALLISTIC):
            times[i] = dt

    return contacts


def _fly(precision, model, points, normals, x, v, touching, air=None):
    laws = None if air is None else (air.drag, air.lift if air.magnus else None, air.spin_decay_law if air.spin_decay else None)
    kernel = _contact_kernel(precision, len(points), model, laws)
    t = types_for(precision)
    n = len(x)
    out = [
        wp.zeros(n, dtype=t.scalar),
        wp.zeros(n, dtype=wp.int32),
        wp.zeros(n, dtype=t.vec3),
        wp.zeros(n, dtype=t.vec3),
        wp.zeros(n, dtype=wp.int32),
    ]
    materials = np.full((len(points), 3), 0.5)
    inputs = [
        _surfaces(precision, points, normals, materials),
        _physics(precision, air),
        wp.array(x, dtype=t.vec3),
        wp.array(v, dtype=t.vec3),
        wp.array(touching, dtype=wp.int32),
    ]
    wp.launch(kernel, dim=n, inputs=inputs + out, device="cpu")
    return [o.numpy() for o in out]


def test_the_next_contact_matches_numpy_and_carries_its_normal():
    """The parabola's next contact (time, surface) among 3 random planes, from 2,000 random states
    (some leaving a plane), is NumPy float64's (`reference.ballistic`) to 1e-9; the flight's contact
    carries the normal of the surface it met (zero when none), and the pellet touches it there."""
    rng = np.random.default_rng(2025)
    points, normals, _ = _random_planes(rng, 3)
    n = 2000
    x = rng.uniform(-2.0, 2.0, (n, 3))
    x[:, 1] = rng.uniform(0.5, 3.0, n)
    v = rng.normal(0.0, 30.0, (n, 3))
    touching = rng.integers(-1, 3, n)
    times, indices, got_normals, positions, flown = _fly("float64", "ballistic", points, normals, x, v, touching)
    want_t, want_k = reference_next_contact(x, v, GRAVITY, RADIUS, points, normals, touching)
    assert (indices == want_k).all() and (flown == want_k).all(), np.flatnonzero(indices != want_k)[:5]
    met = want_k >= 0
    assert 0.3 * n < met.sum() < n  # (both cases are seen)
    np.testing.assert_allclose(times[met], want_t[met], rtol=1e-9, atol=1e-12)
    assert (times[~met] == -1.0).all()
    assert (got_normals[met] == normals[want_k[met]]).all() and (got_normals[~met] == 0.0).all()
    k = want_k[met]
    gap = ((positions[met] - points[k]) * normals[k]).sum(-1) - RADIUS
    leaving = touching[met] == k
    assert (np.abs(gap[~leaving]) <= 1e-9 * (1.0 + np.abs(positions[met][~leaving]).sum(-1))).all()


def test_a_contact_in_air_carries_its_normal():
    """The integrated flight in air meets the surface where its gap is zero and returns that
    surface's normal: after a flight, and at once (touching a plane, moving into it); zero when
    it meets none (its centre behind every plane)."""
    from warp_ricochet.scene.schema import Air

    rng = np.random.default_rng(11)
    points = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    normals = np.array([[0.0, 1.0, 0.0], [-0.8, 0.6, 0.0]])
    n = 64
    x = np.stack([rng.uniform(-1.0, 1.0, n), rng.uniform(0.2, 1.5, n), rng.uniform(-1.0, 1.0, n)], 1)
    v = rng.normal(0.0, 40.0, (n, 3))
    x[:8] = [5.0, -1.0, 0.0]  # behind both planes: never meets one
    x[8:16, 1] = RADIUS  # on the ground, moving into it: met at once
    v[8:16, 1] = -np.abs(v[8:16, 1])
    times, _indices, got_normals, positions, flown = _fly("float64", "air", points, normals, x, v, np.full(n, -1), air=Air())
    assert (flown[:8] == -1).all() and (got_normals[:8] == 0.0).all()
    assert (flown[8:16] == 0).all() and (times[8:16] == 0.0).all()
    met = flown >= 0
    assert met[16:].all() and (flown[16:] == 1).any()  # (both planes are met)
    k = flown[met]
    assert (got_normals[met] == normals[k]).all()
    gap = ((positions[met] - points[k]) * normals[k]).sum(-1) - RADIUS
    assert (np.abs(gap) <= 1e-12).all(), np.abs(gap).max()
    assert (times[16:] > 0).all()


FAR_PLANES = {  # (point, normal, position touching it, velocity): each met at once, as at the origin
    "ground at y = 50 m": ((0.0, 50.0, 0.0), (0.0, 1.0, 0.0), (3.0, 50.0 + RADIUS, -2.0), (20.0, 0.0, 5.0)),
    "wall at x = 15 m": ((15.0, 0.0, 0.0), (-1.0, 0.0, 0.0), (15.0 - RADIUS, 1.0, 0.0), (0.01, 0.0, 20.0)),
}


@pytest.mark.parametrize("model", ["ballistic", "air"])
@pytest.mark.parametrize("far", list(FAR_PLANES))
def test_a_pellet_touching_a_plane_far_from_the_origin_meets_it_at_once(far, model):
    """In float32 a pellet released touching a plane whose point is far from the origin (resting on
    it, or moving into it) meets it at time 0, as it does the same plane through the origin: the
    touching band counts the rounding of the coordinates, eps (|x_i| + |p_i|) (`physics.geometry`),
    which here is 1e-6 m (ulp(50) / 3), far wider than 64 eps of the offset."""
    from warp_ricochet.scene.schema import Air

    point, normal, x, v = (np.array(z) for z in FAR_PLANES[far])
    shifted = point - point * np.abs(normal)  # the same plane through the origin along its normal
    for p, pos in ((point, x), (shifted, x - (point - shifted))):
        out = _fly("float32", model, p[None], normal[None], pos[None], v[None], [-1], air=Air() if model == "air" else None)
        times, _indices, _normals, _positions, flown = out
        assert flown[0] == 0 and times[0] == 0.0, (p, times[0], flown[0])


def test_the_reference_meets_a_plane_far_from_the_origin_at_once():
    """reference.ballistic (float64) counts the coordinates' rounding in its touching band too: a
    pellet resting on ground at y = 15 m (its gap 6e-16 m after rounding) lands at once."""
    point, normal = np.array([[0.0, 15.0, 0.0]]), np.array([[0.0, 1.0, 0.0]])
    x, v = np.array([[1.0, 15.0 + RADIUS, 0.0]]), np.array([[10.0, 0.0, 0.0]])
    assert ((x - point) @ normal[0])[0] - RADIUS > 0.0  # (it is above the plane after rounding)
    t, k = reference_next_contact(x, v, GRAVITY, RADIUS, point, normal, np.array([-1]))
    assert k[0] == 0 and t[0] == 0.0, t


def test_project_gives_the_foot_and_normal_of_a_plane():
    """On the host (the hazard map's grid): the foot lies on the plane, below x along its normal."""
    from warp_ricochet.scene.schema import Surface

    rng = np.random.default_rng(3)
    for _ in range(20):
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        plane = Surface(point=tuple(rng.uniform(-5, 5, 3)), normal=tuple(normal), restitution=0.5, mu_s=0.5)
        x = rng.uniform(-10, 10, 3)
        foot, n = project(plane, x)
        assert abs(np.dot(foot - np.asarray(plane.point), n)) <= 1e-12 * 20
        np.testing.assert_allclose(np.cross(x - foot, n), 0.0, atol=1e-12 * 20)
        np.testing.assert_allclose(n, normal, rtol=0, atol=0)
