"""The kernels' precision and the scene constants the laws read, as Warp structs (SI units).

`types_for(precision)` gives the scalar and 3-vector types of "float32" or "float64" and the
`Surfaces` (planes, read only through `physics.geometry`), `Material` (what a surface is made
of at a point), `Air` (the air's constants, premultiplied for the laws of `physics.air`) and
`Physics` (pellet, gravity, air) structs that `model.Model` fills once per scene and device.
"""

import functools
import weakref
from types import SimpleNamespace

import numpy as np
import warp as wp

from ..struct_refs import read_only
from .mesh_edges import FEW_FACES, convex_features, covering_faces, flat_edges, flat_mesh, flat_plane, inner_depths
from .mipmap import grid_deviation, max_pyramid

SCALARS = {"float32": wp.float32, "float64": wp.float64}


@functools.cache
def types_for(precision: str) -> SimpleNamespace:
    """scalar, vec3, Surfaces, Material, Air and Physics of one precision ("float32" or "float64")."""
    scalar = SCALARS[precision]
    vec3 = wp.types.vector(3, scalar)

    @wp.struct
    class Surfaces:
        """Planes: a point p (m), the unit normal n towards the pellets, E, mu_s, mu_d; and
        sum_i |p_i| |n_i| (m), the point's part of a gap's rounding scale (`surfaces_of` sets it)."""

        point: wp.array(dtype=vec3)
        normal: wp.array(dtype=vec3)
        point_noise: wp.array(dtype=scalar)
        restitution: wp.array(dtype=scalar)
        mu_s: wp.array(dtype=scalar)
        mu_d: wp.array(dtype=scalar)
        rolling_resistance: wp.array(dtype=scalar)  # the Material's fields below, per surface
        ploughing: wp.array(dtype=scalar)
        critical_angle: wp.array(dtype=scalar)
        critical_angle_rise: wp.array(dtype=scalar)
        critical_speed: wp.array(dtype=scalar)
        roughness: wp.array(dtype=scalar)
        restitution_scatter: wp.array(dtype=scalar)
        friction_scatter: wp.array(dtype=scalar)
        skip_loss: wp.array(dtype=scalar)
        liquid: wp.array(dtype=wp.int32)
        # plates (read only by kernels compiled with plates, `geometry.make_geometry`): KINDS code,
        # unit in-plane axes u and v = n x u, half sides along them (m; a disc: its radius twice)
        kind: wp.array(dtype=wp.int32)
        axis_u: wp.array(dtype=vec3)
        axis_v: wp.array(dtype=vec3)
        half_u: wp.array(dtype=scalar)
        half_v: wp.array(dtype=scalar)
        two_sided: wp.array(dtype=wp.int32)  # 1: met from either face
        # meshes (read only by kernels compiled with meshes, `physics.mesh_contact`): per surface its
        # wp.Mesh id (0: none), the row of its first triangle in mesh_triangles, its bounding box (m),
        # its triangles' median edge (m);
        # mesh_points: every mesh's vertices (m) in the kernel's precision; mesh_triangles: each
        # triangle's three vertices as rows of mesh_points
        mesh: wp.array(dtype=wp.uint64)
        mesh_first: wp.array(dtype=wp.int32)
        mesh_triangles: wp.array(dtype=wp.vec3i)
        mesh_low: wp.array(dtype=vec3)
        mesh_high: wp.array(dtype=vec3)
        mesh_edge: wp.array(dtype=scalar)  # m: the median edge of its triangles (the chords' scale)
        mesh_faces: wp.array(dtype=wp.int32)  # its triangles (0: not a mesh)
        mesh_points: wp.array(dtype=vec3)
        # a mesh's convex and border edges and their corners (`physics.mesh_edges`, read by
        # `physics.edge_contact`): per surface the row of its first triangle in face_edges and
        # face_corners (-1: none at all), which hold per triangle the edges and corners it owns (-1: none);
        # edge_ends: two end points (m) per edge; corner_points (m); per triangle of a mesh of at most
        # FEW_FACES, face_cover: 1 where every kept corner lies on or behind its plane
        # (`physics.mesh_edges.covering_faces`), face_depth: the least depth (m) of the kept points
        # projecting inside it (`physics.mesh_edges.inner_depths`; 0 for a larger mesh)
        face_first: wp.array(dtype=wp.int32)
        face_edges: wp.array(dtype=wp.vec3i)
        face_corners: wp.array(dtype=wp.vec3i)
        face_cover: wp.array(dtype=wp.int32)
        face_depth: wp.array(dtype=scalar)
        # per surface, a flat mesh's plane (`physics.mesh_edges.flat_mesh`, read by
        # `physics.flat_contact`): its first triangle's first vertex (m) and unit normal, from
        # float64 (zero for any other surface)
        flat_point: wp.array(dtype=vec3)
        flat_normal: wp.array(dtype=vec3)
        # a flat mesh's slack (m: its vertices' distance from that plane, bounded) per surface, and per
        # edge of its triangles (3 a triangle, from row 3 face_first[k]) the in-plane unit normal
        # towards the triangle and its offset (m) from the mesh's frame (`mesh_edges.flat_edges`)
        flat_slack: wp.array(dtype=scalar)
        flat_edge: wp.array(dtype=vec3)
        flat_offset: wp.array(dtype=scalar)
        edge_ends: wp.array(dtype=vec3)
        corner_points: wp.array(dtype=vec3)
        # a terrain walked in its raster (`physics.grid_walk`, scene.terrain.TerrainGrid): per surface
        # (cols, rows, levels) of its cells (levels 0: not walked), the rows of its level 0 in
        # grid_level and of its first cell in grid_cell; its origin (m), per_col and per_row (1/m), up;
        # grid_level: each level's first block in grid_top (m above the origin along up:
        # `physics.mipmap.max_pyramid`); grid_cell: each cell's first triangle (-1: a hole);
        # grid_slack: how far (m) its vertices lie from their cell corners (`physics.mipmap.grid_deviation`)
        grid_dims: wp.array(dtype=wp.vec3i)
        grid_first: wp.array(dtype=wp.vec2i)
        grid_origin: wp.array(dtype=vec3)
        grid_col: wp.array(dtype=vec3)
        grid_row: wp.array(dtype=vec3)
        grid_up: wp.array(dtype=vec3)
        grid_level: wp.array(dtype=wp.int32)
        grid_top: wp.array(dtype=scalar)
        grid_cell: wp.array(dtype=wp.int32)
        grid_slack: wp.array(dtype=scalar)

    @wp.struct
    class Material:
        """A surface's material at a point (`physics.geometry.material`; scene.materials, docs/ground.md),
        in the kernels' units, for this pellet (`model.Model` converts the scene's)."""

        restitution: scalar  # E
        mu_s: scalar
        mu_d: scalar
        rolling_resistance: scalar  # c: resisting force c N while rolling
        ploughing: scalar  # 1/m: b of the resisting acceleration b |v|^2 (3 c2 f / (4 rho_p R))
        critical_angle: scalar  # rad from the surface at zero speed (pi/2: never embeds; water: 18 deg / sqrt(SG))
        critical_angle_rise: scalar  # rad s/m: theta_c(v) = critical_angle + rise min(v, critical_speed)
        critical_speed: scalar  # m/s
        roughness: scalar  # rad: the mode of the normal's Rayleigh tilt (physics.ground.draw)
        restitution_scatter: scalar  # relative width of E's two-sided exponential
        friction_scatter: scalar  # sigma of mu's log-normal factor
        skip_loss: scalar  # water: tan(beta); a skip keeps exp(-2 theta skip_loss) of the speed
        liquid: wp.int32  # 1: a pellet cannot stay on it (water): it skips or sinks

    @wp.struct
    class Air:
        """The air and what the laws of `physics.air` need of it for this pellet, computed on the
        host in float64 (`model.air_struct`); all zero in vacuum."""

        wind: vec3  # m/s
        inverse_sound_speed: scalar  # s/m: M = |u| / c
        re_per_speed: scalar  # s/m: Re = rho d |u| / mu
        knudsen: scalar  # sqrt(pi gamma / 2) mu / (rho c d): Loth's Kn = that M / Re, from the fluid
        stokes: scalar  # 1/s: 3 pi mu d drag_factor / m (loth2021: a_D = -stokes f u, f = C_D Re/24)
        quadratic: scalar  # 1/m: rho A drag_factor / (2 m) (constant, table: a_D = -quadratic C_D |u| u)
        drag_coefficient: scalar  # the constant law's C_D
        table_mach: wp.array(dtype=scalar)  # the table law's C_D against Mach (empty otherwise)
        table_cd: wp.array(dtype=scalar)
        lift: scalar  # rho A R / (2 m): a_L = lift (C_L/S) (omega x u)
        radius: scalar  # m: S = R |omega x u| / |u|^2
        lift_slope: scalar  # the linear law's C_L/S
        lift_max: scalar  # the cap on C_L of every lift law
        spin: scalar  # 1/s: 8 pi mu R^3 / I (d omega/dt = -spin h(Re_R) omega)
        re_r_per_spin: scalar  # s: Re_R = rho d^2 |omega| / mu
        tolerance: scalar  # the integrator's relative tolerance (numerics.flight_tolerance)
        speed_floor: scalar  # m/s: speeds below it count as it in the error control, sqrt(|g| R)

    @wp.struct
    class Physics:
        radius: scalar  # m
        inertia_factor: scalar  # I / (m R^2)
        gravity: vec3  # m/s^2
        impact_duration: scalar  # s, the paper's delta t
        air: Air
        rest_speed: scalar  # m/s: on a surface, slower than it and held, a pellet is at rest
        max_impacts: wp.int32  # a pellet's budget of impacts (until = "rest")
        max_steps: wp.int32  # and of integration steps along surfaces
        surface_tolerance: scalar  # relative tolerance of phases along surfaces (numerics.surface_tolerance)

    read_only(Surfaces)
    read_only(Physics)
    return SimpleNamespace(
        precision=precision, scalar=scalar, vec3=vec3, Surfaces=Surfaces, Material=Material, Air=Air, Physics=Physics
    )


# the Material's scalar fields after restitution, mu_s, mu_d, and their values on a rigid plane
GROUND_FIELDS = (
    "rolling_resistance",
    "ploughing",
    "critical_angle",
    "critical_angle_rise",
    "critical_speed",
    "roughness",
    "restitution_scatter",
    "friction_scatter",
    "skip_loss",
)
RIGID_PLANE = {name: 0.0 for name in GROUND_FIELDS} | {"critical_angle": 0.5 * np.pi}
KINDS = {
    "plane": 0,
    "rectangle": 1,
    "disc": 2,
    "mesh": 3,
    "cylinder": 4,
}  # Surfaces.kind's codes ([[surfaces]] kind; a box is a mesh)


def plate_arrays(normals, plates) -> dict:
    """Surfaces' plate arrays in float64 from unit normals (P, 3) and `plates`: per surface None (a
    plane) or (kind, axis_u, half_u, half_v, two_sided); u is made exactly perpendicular to n here."""
    normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    plates = [None] * len(normals) if plates is None else list(plates)
    out = {"kind": [], "axis_u": [], "axis_v": [], "half_u": [], "half_v": [], "two_sided": []}
    for n, plate in zip(normals, plates):
        kind, u, half_u, half_v, two_sided = plate or ("plane", (0.0, 0.0, 0.0), 0.0, 0.0, False)
        u = np.asarray(u, dtype=np.float64)
        if kind in ("disc", "cylinder"):  # any in-plane axis (a cylinder's normal: its axis)
            u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        if kind not in ("plane", "mesh"):
            u = u - np.dot(u, n) * n
            u = u / np.linalg.norm(u)
        for key, value in zip(out, (KINDS[kind], u, np.cross(n, u), half_u, half_v, int(bool(two_sided)))):
            out[key].append(value)
    return {key: np.asarray(values) for key, values in out.items()}


_HELD = {}  # id of a Surfaces struct: the wp.Mesh objects its ids name (released with the struct)


def mesh_fields(surfaces, precision: str, meshes, device) -> None:
    """Set the Surfaces' mesh arrays from `meshes`: per surface None or triangles (an object with
    `vertices` float64 (n, 3) and `triangles` int32 (m, 3): `scene.triangles.TriangleSurface`);
    each gets a wp.Mesh (float32 BVH), kept alive as long as `surfaces`."""
    t, dtype = types_for(precision), np.dtype(precision)
    ids, first, low, high, edge, faces, points, held = [], [], [], [], [], [], [np.zeros((0, 3))], []
    rows = [np.zeros((0, 3), np.int64)]
    count = rows_so_far = 0
    for triangles in meshes:
        ids.append(0 if triangles is None else None)
        first.append(rows_so_far)
        faces.append(0 if triangles is None else len(triangles.triangles))
        if triangles is None:
            low.append(np.zeros(3))
            high.append(np.zeros(3))
            edge.append(0.0)
            continue
        vertices = np.asarray(triangles.vertices, dtype=np.float64).astype(dtype)
        corners = np.asarray(triangles.vertices, dtype=np.float64)[np.asarray(triangles.triangles, dtype=np.int64)]
        edge.append(float(np.median(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2))))
        mesh = wp.Mesh(
            points=wp.array(vertices.astype(np.float32), dtype=wp.vec3, device=device),
            indices=wp.array(
                np.ascontiguousarray(triangles.triangles, dtype=np.int32).reshape(-1), dtype=wp.int32, device=device
            ),
        )
        held.append(mesh)
        ids[-1] = mesh.id
        low.append(vertices.min(axis=0))
        high.append(vertices.max(axis=0))
        points.append(vertices)
        rows.append(np.asarray(triangles.triangles, dtype=np.int64).reshape(-1, 3) + count)
        count, rows_so_far = count + len(vertices), rows_so_far + len(rows[-1])
    surfaces.mesh = wp.array(np.asarray(ids, dtype=np.uint64), dtype=wp.uint64, device=device)
    surfaces.mesh_first = wp.array(np.asarray(first, dtype=np.int32), dtype=wp.int32, device=device)
    for name, values in (("mesh_low", low), ("mesh_high", high)):
        setattr(surfaces, name, wp.array(np.asarray(values).reshape(-1, 3).astype(dtype), dtype=t.vec3, device=device))
    surfaces.mesh_edge = wp.array(np.asarray(edge, dtype=dtype), dtype=t.scalar, device=device)
    surfaces.mesh_faces = wp.array(np.asarray(faces, dtype=np.int32), dtype=wp.int32, device=device)
    surfaces.mesh_points = wp.array(np.concatenate(points).astype(dtype), dtype=t.vec3, device=device)
    surfaces.mesh_triangles = wp.array(np.concatenate(rows).astype(np.int32), dtype=wp.vec3i, device=device)
    _feature_fields(surfaces, precision, meshes, device)
    _grid_fields(surfaces, precision, meshes, device)
    if held:
        _HELD[id(surfaces)] = held
        weakref.finalize(surfaces, _HELD.pop, id(surfaces), None)


def _feature_fields(surfaces, precision: str, meshes, device) -> None:
    """Set the Surfaces' edge and corner arrays (`physics.mesh_edges.convex_features`) of `meshes`,
    their indices made global; face_first -1 for a surface without (a plane, a plate, a terrain)."""
    t, dtype = types_for(precision), np.dtype(precision)
    face_first, face_edges, face_corners, ends, corners = [], [np.zeros((0, 3), np.int32)], [np.zeros((0, 3), np.int32)], [], []
    cover, depth = [np.zeros(0, np.int32)], [np.zeros(0)]
    planes, slack = np.zeros((len(meshes), 2, 3)), np.zeros(len(meshes))
    lines, offsets = [np.zeros((0, 3, 3))], [np.zeros((0, 3))]
    rows = edge_count = corner_count = 0
    for index, triangles in enumerate(meshes):
        if triangles is None or not getattr(triangles, "edges", True):
            face_first.append(-1)  # none
            continue
        face_first.append(rows)
        w, offset = np.zeros((len(triangles.triangles), 3, 3)), np.zeros((len(triangles.triangles), 3))
        if len(triangles.triangles) <= FEW_FACES and flat_mesh(triangles.vertices, triangles.triangles):
            planes[index] = flat_plane(triangles.vertices, triangles.triangles)
            stored = np.asarray(triangles.vertices, dtype=np.float64).astype(dtype).astype(np.float64)
            origin = 0.5 * (stored.min(axis=0) + stored.max(axis=0))  # (`mesh_contact.frame`)
            w, offset, slack[index] = flat_edges(triangles.vertices, triangles.triangles, planes[index], origin)
        lines.append(w)
        offsets.append(offset)
        found = convex_features(triangles.vertices, triangles.triangles)
        face_edges.append(np.where(found["face_edges"] >= 0, found["face_edges"] + edge_count, -1))
        face_corners.append(np.where(found["face_corners"] >= 0, found["face_corners"] + corner_count, -1))
        ends.append(found["edges"].reshape(-1, 3))
        corners.append(found["corners"])
        small = len(triangles.triangles) <= FEW_FACES  # (only a small mesh's search reads it)
        covers = small and covering_faces(triangles.vertices, triangles.triangles, found["corners"])
        cover.append(np.broadcast_to(np.asarray(covers, dtype=np.int32), len(triangles.triangles)))
        deep = small and inner_depths(triangles.vertices, triangles.triangles, found["edges"], found["corners"])
        depth.append(np.broadcast_to(np.asarray(deep, dtype=np.float64), len(triangles.triangles)))
        rows, edge_count, corner_count = (
            rows + len(triangles.triangles),
            edge_count + len(found["edges"]),
            corner_count + len(found["corners"]),
        )
    surfaces.face_first = wp.array(np.asarray(face_first, dtype=np.int32), dtype=wp.int32, device=device)
    surfaces.face_edges = wp.array(np.concatenate(face_edges).astype(np.int32), dtype=wp.vec3i, device=device)
    surfaces.face_corners = wp.array(np.concatenate(face_corners).astype(np.int32), dtype=wp.vec3i, device=device)
    surfaces.face_cover = wp.array(np.concatenate(cover).astype(np.int32), dtype=wp.int32, device=device)
    depth = np.concatenate(depth)  # rounded down into the kernel's precision
    depth = np.where(depth.astype(dtype) > depth, np.nextafter(depth.astype(dtype), dtype.type(-np.inf)), depth.astype(dtype))
    surfaces.face_depth = wp.array(np.maximum(depth, 0).astype(dtype), dtype=t.scalar, device=device)
    for name, values in (("flat_point", planes[:, 0]), ("flat_normal", planes[:, 1])):
        setattr(surfaces, name, wp.array(np.ascontiguousarray(values).astype(dtype), dtype=t.vec3, device=device))
    surfaces.flat_edge = wp.array(np.concatenate(lines).reshape(-1, 3).astype(dtype), dtype=t.vec3, device=device)
    surfaces.flat_offset = wp.array(np.concatenate(offsets).reshape(-1).astype(dtype), dtype=t.scalar, device=device)
    rounded_up = np.nextafter(slack.astype(dtype), dtype.type(np.inf))
    surfaces.flat_slack = wp.array(np.where(slack > 0, rounded_up, 0).astype(dtype), dtype=t.scalar, device=device)
    for name, values in (("edge_ends", ends), ("corner_points", corners)):
        setattr(surfaces, name, wp.array(np.concatenate([np.zeros((0, 3)), *values]).astype(dtype), dtype=t.vec3, device=device))


def _grid_fields(surfaces, precision: str, meshes, device) -> None:
    """Set the Surfaces' grid arrays of the terrains among `meshes` that have a `TerrainGrid`
    (`physics.mipmap.max_pyramid`: its tops from the kernel's vertices); levels 0 for the rest."""
    t, dtype = types_for(precision), np.dtype(precision)
    dims, first, frames, slack = [], [], [], []
    levels, tops, cells = [np.zeros(0, np.int32)], [np.zeros(0, dtype)], [np.zeros(0, np.int32)]
    level_rows = cell_rows = 0
    for triangles in meshes:
        grid = getattr(triangles, "grid", None)
        if grid is None:
            dims.append((0, 0, 0))
            first.append((0, 0))
            frames.append(np.zeros((4, 3)))
            slack.append(0.0)
            continue
        rows, cols = grid.cells.shape
        vertices = np.asarray(triangles.vertices, dtype=np.float64).astype(dtype)
        indices = np.asarray(triangles.triangles, dtype=np.int64)
        starts, heights = max_pyramid(grid, vertices, indices, dtype)
        slack.append(grid_deviation(grid, vertices, indices, dtype))
        dims.append((cols, rows, len(starts)))
        first.append((level_rows, cell_rows))
        frames.append(np.stack([grid.origin, grid.per_col, grid.per_row, grid.up]))
        levels.append(starts + sum(len(h) for h in tops))
        tops.append(heights)
        cells.append(grid.cells.ravel())
        level_rows, cell_rows = level_rows + len(starts), cell_rows + grid.cells.size
    surfaces.grid_dims = wp.array(np.asarray(dims, dtype=np.int32).reshape(-1, 3), dtype=wp.vec3i, device=device)
    surfaces.grid_first = wp.array(np.asarray(first, dtype=np.int32).reshape(-1, 2), dtype=wp.vec2i, device=device)
    frames = np.asarray(frames, dtype=np.float64).reshape(-1, 4, 3).astype(dtype)
    for j, name in enumerate(("grid_origin", "grid_col", "grid_row", "grid_up")):
        setattr(surfaces, name, wp.array(np.ascontiguousarray(frames[:, j]), dtype=t.vec3, device=device))
    surfaces.grid_level = wp.array(np.concatenate(levels).astype(np.int32), dtype=wp.int32, device=device)
    surfaces.grid_top = wp.array(np.concatenate(tops).astype(dtype), dtype=t.scalar, device=device)
    surfaces.grid_cell = wp.array(np.concatenate(cells).astype(np.int32), dtype=wp.int32, device=device)
    slack = np.asarray(slack, dtype=np.float64)
    surfaces.grid_slack = wp.array(np.nextafter(slack.astype(dtype), dtype.type(np.inf)), dtype=t.scalar, device=device)


def surfaces_of(precision: str, points, normals, materials, device, ground=None, liquid=None, plates=None, meshes=None) -> object:
    """The `Surfaces` struct of planes: points (m) and unit normals (P, 3), materials (P, 3) as
    restitution, mu_s, mu_d; their point_noise sum_i |p_i| |n_i| computed here in float64, once, so
    the kernels' rounding scale of a gap (`physics.geometry.locate`) adds it instead of p's terms.
    `ground`: {GROUND_FIELDS name: (P,) values in the kernels' units}, missing ones those of a rigid
    plane (RIGID_PLANE); `liquid`: (P,) flags (default 0); `plates`: as `plate_arrays` (default: planes)."""
    t = types_for(precision)
    dtype = np.dtype(precision)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    materials = np.asarray(materials, dtype=np.float64).reshape(-1, 3)
    surfaces = t.Surfaces()
    surfaces.point = wp.array(points.astype(dtype), dtype=t.vec3, device=device)
    surfaces.normal = wp.array(normals.astype(dtype), dtype=t.vec3, device=device)
    noise = (np.abs(points.astype(dtype)).astype(np.float64) * np.abs(normals.astype(dtype))).sum(axis=1)
    surfaces.point_noise = wp.array(noise.astype(dtype), dtype=t.scalar, device=device)
    for j, name in enumerate(("restitution", "mu_s", "mu_d")):
        setattr(surfaces, name, wp.array(materials[:, j].astype(dtype), dtype=t.scalar, device=device))
    ground = ground or {}
    for name in GROUND_FIELDS:
        values = np.broadcast_to(np.asarray(ground.get(name, RIGID_PLANE[name]), dtype=np.float64), len(points))
        setattr(surfaces, name, wp.array(values.astype(dtype), dtype=t.scalar, device=device))
    flags = np.zeros(len(points), dtype=np.int32) if liquid is None else np.asarray(liquid, dtype=np.int32).reshape(-1)
    surfaces.liquid = wp.array(flags, dtype=wp.int32, device=device)
    shapes = plate_arrays(normals, plates)
    for name in ("kind", "two_sided"):
        setattr(surfaces, name, wp.array(shapes[name].astype(np.int32), dtype=wp.int32, device=device))
    for name in ("axis_u", "axis_v"):
        setattr(surfaces, name, wp.array(shapes[name].reshape(-1, 3).astype(dtype), dtype=t.vec3, device=device))
    for name in ("half_u", "half_v"):
        setattr(surfaces, name, wp.array(shapes[name].astype(dtype), dtype=t.scalar, device=device))
    mesh_fields(surfaces, precision, [None] * len(points) if meshes is None else meshes, device)
    return surfaces
