"""NumPy float64 reference of the flight in vacuum against finite plates and triangle meshes
(docs/geometry.md, "Contact rules" and "Meshes and boxes"), up to the landing.

Brute force, written apart from the kernels (no BVH, no chords): every face is a plane whose gap
h(t) = n.(x(t) - a) - R along the parabola of eq. (36), x(t) = x + v t + g t^2 / 2, is a quadratic;
its closing root (h = 0 with h' < 0; at most one per face) is kept where the centre there is inside
the face; a centre in front of the plane, within R of it and closing, meets it at once. A
rectangle's and a disc's face is the plate itself; a two-sided plate is two faces, n and -n (its
back face met once the centre has passed to that side); a plate's face is not met in a flight that
starts with the centre behind its plane (the plane's rule), a triangle's is (from behind, over its
plane and falling back onto it). A triangle is inside when its three edge functions
((b - a) x (y - a)).n are >= 0; it is also met where the centre itself reaches its plane inside it
(h = -R: the kernels' second rule, for convex edges). A box's or a mesh's kept edges and corners
(`physics.mesh_edges`, the host's classification) are met where the centre's distance from the
segment (a corner: from the point) falls through R: per pellet the real roots of the quartic
|P(t)|^2 - R^2 (P the part of x(t) - p across the edge) by `numpy.roots`, the first falling one
with the projection on the segment, or at once where it starts within R, closing; its normal is
radial; at equal times a face wins. Planes keep `reference.ballistic`'s rules. Impacts, landings
and statistics are `reference.ballistic.simulate`'s.
"""

from __future__ import annotations

import numpy as np

from ..physics.ballistic import MAX_FLIGHT_TIME
from ..physics.mesh_edges import convex_features
from ..scene.terrain import place_terrain
from ..scene.triangles import triangles_of
from .ballistic import next_contact, simulate

__all__ = ["faces_of", "shape_contact", "simulate_shapes"]

PLANE, RECTANGLE, DISC, TRIANGLE = range(4)


def faces_of(scene) -> dict:
    """The scene's non-plane surfaces as faces, in float64: `surface` (F,) its index, `kind` (F,),
        `point` (F, 3) a point of its plane (a plate's centre, a triangle's first vertex), `normal`
        (F, 3) unit, `u`, `v` (F, 3) a plate's in-plane axes, `half` (F, 2) a rectangle's half sides or
        a disc's radius twice, `corners` (F, 3, 3) a triangle's vertices, `one_sided` (F,): a one-sided
    plate's face (not met from behind its plane at a flight's start)."""
    rows = []
    for i, s in enumerate(scene.surfaces):
        if s.kind in ("rectangle", "disc"):
            n = np.asarray(s.normal, np.float64)
            if s.kind == "disc":
                other = [1.0, 0.0, 0.0] if abs(n[0]) < 0.5 else [0.0, 1.0, 0.0]
                u = np.cross(n, other)
                half = (s.radius, s.radius)
            else:
                u, half = np.asarray(s.axis_u, np.float64), (0.5 * s.size[0], 0.5 * s.size[1])
            u = u / np.linalg.norm(u)
            kind = RECTANGLE if s.kind == "rectangle" else DISC
            for sign in (1.0, -1.0) if s.two_sided else (1.0,):
                rows.append((i, kind, s.point, sign * n, u, np.cross(n, u), half, np.zeros((3, 3)), not s.two_sided))
        elif s.kind in ("box", "mesh", "terrain"):
            if s.kind == "terrain":
                vertices, tris = place_terrain(scene, i)
            else:
                mesh = triangles_of(s)
                vertices, tris = mesh.vertices, mesh.triangles
            corners = vertices[tris]
            n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
            n /= np.linalg.norm(n, axis=1, keepdims=True)
            for c, nrm in zip(corners, n):
                rows.append((i, TRIANGLE, c[0], nrm, np.zeros(3), np.zeros(3), (0.0, 0.0), c, False))
    names = ("surface", "kind", "point", "normal", "u", "v", "half", "corners", "one_sided")
    return {name: np.asarray([row[j] for row in rows]) for j, name in enumerate(names)}


def closing_root(c, b, a):
    """The time t >= 0 where c + b t + a t^2 falls through 0 (NaN: none), per pellet; `a` a scalar."""
    with np.errstate(divide="ignore", invalid="ignore"):
        if a == 0.0:
            t = np.where(b < 0, -c / b, np.nan)
        else:
            disc = b * b - 4.0 * a * c
            root = np.sqrt(np.where(disc >= 0, disc, np.nan))
            t = np.where(b >= 0, -(b + root) / (2.0 * a), 2.0 * c / (root - b))  # (the root with h' = -root)
    return np.where((t >= 0) & (t <= MAX_FLIGHT_TIME), t, np.nan)


def _inside(faces, f, y):
    """Whether the centres y (N, 3) project onto face f."""
    kind, d = faces["kind"][f], y - faces["point"][f]
    if kind == TRIANGLE:
        c, n = faces["corners"][f], faces["normal"][f]
        return np.all([np.cross(c[(j + 1) % 3] - c[j], y - c[j]) @ n >= 0 for j in range(3)], axis=0)
    a, b = d @ faces["u"][f], d @ faces["v"][f]
    if kind == DISC:
        return a * a + b * b <= faces["half"][f][0] ** 2
    return (np.abs(a) <= faces["half"][f][0]) & (np.abs(b) <= faces["half"][f][1])


def features_of(scene) -> list:
    """(surface index, p (3,), unit a (3,) or 0 for a corner, length L (m)) of every kept edge and
    corner of the scene's boxes and meshes."""
    rows = []
    for i, s in enumerate(scene.surfaces):
        if s.kind in ("box", "mesh"):
            mesh = triangles_of(s)
            found = convex_features(mesh.vertices, mesh.triangles)
            for p, q in found["edges"]:
                rows.append((i, p, (q - p) / np.linalg.norm(q - p), float(np.linalg.norm(q - p))))
            rows += [(i, c, np.zeros(3), 0.0) for c in found["corners"]]
    return rows


def _on(d, v, g, a, length, t):
    """Whether the centre's projection on the axis a at time t lies on [0, L] (within rounding)."""
    z = (d + v * t + 0.5 * g * t * t) @ a
    return -1e-12 * (1.0 + length) <= z <= length + 1e-12 * (1.0 + length)


def feature_root(r, v, g, radius, p, a, length):
    """Per pellet the first time t >= 0 where the centre's distance from the segment p + s a, s in
    [0, L] (a = 0: the point p) falls through R (NaN: none)."""
    out = np.full(len(r), np.nan)
    C = 0.5 * (g - (g @ a) * a)
    for i in range(len(r)):
        d = r[i] - p
        A, B = d - (d @ a) * a, v[i] - (v[i] @ a) * a
        if A @ A <= radius * radius and A @ B < 0 and _on(d, v[i], g, a, length, 0.0):
            out[i] = 0.0
            continue
        c = np.array([C @ C, 2 * B @ C, B @ B + 2 * A @ C, 2 * A @ B, A @ A - radius * radius])
        roots = np.roots(np.trim_zeros(c, "f"))
        real = np.sort(roots.real[(np.abs(roots.imag) <= 1e-9 * (1.0 + np.abs(roots.real))) & (roots.real >= 0)])
        for t in real:
            falling = 4 * c[0] * t**3 + 3 * c[1] * t**2 + 2 * c[2] * t + c[3] < 0
            if falling and t <= MAX_FLIGHT_TIME and _on(d, v[i], g, a, length, t):
                out[i] = t
                break
    return out


def shape_contact(scene):
    """`reference.ballistic.plane_contact` for a scene with plates and meshes: the first contact,
    over the planes (`next_contact`) and every face (the module's rules)."""
    radius = 0.5 * scene.shot.diameter
    g = np.asarray(scene.physics.gravity, np.float64)
    planes = [i for i, s in enumerate(scene.surfaces) if s.is_plane]
    points = np.array([scene.surfaces[i].point for i in planes], np.float64).reshape(-1, 3)
    normals = np.array([scene.surfaces[i].normal for i in planes], np.float64).reshape(-1, 3)
    faces, features = faces_of(scene), features_of(scene)

    def contact(r, v, touching):
        n_pellets = len(r)
        best_t, best_k, best_n = np.full(n_pellets, np.inf), np.full(n_pellets, -1), np.zeros((n_pellets, 3))
        if planes:
            plane_touching = np.array([planes.index(k) if k in planes else -1 for k in touching])
            t, k = next_contact(r, v, g, radius, points, normals, plane_touching)
            ok = np.isfinite(t)
            best_t, best_k = np.where(ok, t, best_t), np.where(ok, np.asarray(planes)[np.maximum(k, 0)], -1)
            best_n = np.where(ok[:, None], normals[np.maximum(k, 0)], best_n)
        for f in range(len(faces["kind"])):
            n = faces["normal"][f]
            height, b, a = (r - faces["point"][f]) @ n, v @ n, 0.5 * (g @ n)
            offsets = (radius, 0.0) if faces["kind"][f] == TRIANGLE else (radius,)
            for offset in offsets:
                t = closing_root(height - offset, b, a)
                t = np.where((height >= 0) & (height <= offset) & (b < 0), 0.0, t)  # overlapping, closing: now
                if faces["one_sided"][f]:
                    t = np.where(height >= 0, t, np.nan)
                y = r + v * np.nan_to_num(t)[:, None] + 0.5 * g * (np.nan_to_num(t) ** 2)[:, None]
                better = np.isfinite(t) & (t < best_t) & _inside(faces, f, y)
                best_t, best_k = np.where(better, t, best_t), np.where(better, faces["surface"][f], best_k)
                best_n = np.where(better[:, None], n, best_n)
        for k, p, a, length in features:
            t = feature_root(r, v, g, radius, p, a, length)
            better = np.isfinite(t) & (t < best_t)
            y = r + v * np.nan_to_num(t)[:, None] + 0.5 * g * (np.nan_to_num(t) ** 2)[:, None]
            out = y - (p + np.clip((y - p) @ a, 0.0, length)[:, None] * a)
            best_t, best_k = np.where(better, t, best_t), np.where(better, k, best_k)
            best_n = np.where(better[:, None], out / np.linalg.norm(out, axis=1, keepdims=True).clip(1e-300), best_n)
        return np.where(best_k >= 0, best_t, np.nan), best_k, best_n

    return contact


def simulate_shapes(scene, position, velocity, angular_velocity):
    """`reference.ballistic.simulate` of a scene with plates, boxes, meshes or terrain (in vacuum,
    until landing): (per-pellet dict, statistics)."""
    return simulate(scene, position, velocity, angular_velocity, contact=shape_contact(scene))
