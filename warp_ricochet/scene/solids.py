"""Solids a launch must start outside (docs/geometry.md, "Launches inside a solid"), on the host in
float64: posts, boxes and closed meshes are met from outside only, so a pellet launched inside one
flies through it as if it were not there (the solid of a closed mesh wound inwards, a room, is all
outside it).

- `solid_gaps(s, x)`: the signed distance (m, negative inside) of points x from a post or a box,
  exact (the rounded-box distance: |max(q, 0)| + min(max_i q_i, 0), q the per-axis excess);
- `closed_triangles(s)`: a mesh's triangles when they close a volume (every edge, vertices merged by
  position, shared by exactly two triangles that run it in opposite directions), else None;
- `winding_numbers(vertices, triangles, x)`: the generalized winding number of each point (Jacobson,
  Kavan and Sorkine-Hornung, "Robust inside-outside segmentation using generalized winding
  numbers", ACM ToG 32(4), 2013, eq. 3), each triangle's signed solid angle by Van Oosterom and
  Strackee, IEEE Trans. Biomed. Eng. 30(2), 1983: tan(Omega/2) = a.(b x c) / (|a||b||c| +
  (a.b)|c| + (b.c)|a| + (c.a)|b|), a, b, c the vertices less x. 1 inside a closed mesh wound
  counter-clockwise seen from outside, 0 outside; -1 inside one wound inwards;
- `winding_level(tri)`: the winding number above which a point lies in a closed mesh's solid:
  1/2 for a mesh wound outwards (its solid its inside, w = 1 there), -1/2 for one wound inwards
  (a room: its solid all outside it, w = 0 there, -1 in the room), told by the sign of its
  enclosed volume (1/6) sum_t a.(b x c) (the divergence theorem);
- `inside_rows(s, x)`, `envelope_gap(s, centre)`: what `scene.parse` refuses with.
NumPy only: no optional package is needed (a mesh file itself needs trimesh to be read)."""

from __future__ import annotations

import functools

import numpy as np

from .triangles import TriangleSurface, triangles_of

SOLIDS = ("cylinder", "box", "mesh")  # the kinds checked (a mesh: when closed)
WINDING_INSIDE = 0.5  # a point is inside a closed mesh wound outwards where its winding number exceeds this
FLAT_VOLUME = 1e-9  # a closed mesh whose |volume| is below this share of sum_t |a.(b x c)| / 6 encloses none
PAIRS = 1 << 20  # point-triangle pairs a NumPy batch holds (about 8 MB per temporary array)


def solid_gaps(s, x: np.ndarray) -> np.ndarray:
    """Signed distances (m; negative inside) from points x (n, 3) to a post (base centre `point`,
    axis `normal`, `radius`, `length`) or a box (centre `point`, sides `size` along axis_u,
    normal x axis_u and normal)."""
    axis = np.asarray(s.normal, dtype=np.float64)
    d = np.atleast_2d(x) - np.asarray(s.point, dtype=np.float64)
    if s.kind == "cylinder":
        along = d @ axis
        radial = np.linalg.norm(d - along[:, None] * axis, axis=1)
        q = np.stack([radial - s.radius, np.maximum(-along, along - s.length)], axis=1)
    else:
        u = np.asarray(s.axis_u, dtype=np.float64)
        q = np.abs(np.stack([d @ u, d @ np.cross(axis, u), d @ axis], axis=1)) - 0.5 * np.asarray(s.size, dtype=np.float64)
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


@functools.lru_cache(maxsize=16)
def _closed(tri: TriangleSurface) -> bool:
    """Whether `tri` closes a volume: with vertices merged by position and triangles that collapse
    to a segment or a point left out, every directed edge occurs once and its reverse once."""
    _unique, ids = np.unique(tri.vertices, axis=0, return_inverse=True)
    f = ids.reshape(-1)[tri.triangles]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    if len(f) == 0:
        return False
    size = np.int64(len(_unique))
    start, end = f.reshape(-1).astype(np.int64), np.roll(f, -1, axis=1).reshape(-1).astype(np.int64)
    forward, backward = np.sort(start * size + end), np.sort(end * size + start)
    return bool((np.diff(forward) > 0).all() and np.array_equal(forward, backward))


def closed_triangles(s) -> TriangleSurface | None:
    """The triangles of mesh surface s if they close a volume (`_closed`), else None."""
    if s.kind != "mesh":
        return None
    tri = triangles_of(s)
    return tri if _closed(tri) else None


@functools.lru_cache(maxsize=16)
def winding_level(tri: TriangleSurface) -> float:
    """The winding number above which a point lies in the solid of the closed triangles `tri`:
    WINDING_INSIDE where they enclose a positive volume (wound outwards: the solid is their
    inside), -WINDING_INSIDE where a negative one (wound inwards, met from inside: the solid is
    all outside them). The volume is (1/6) sum_t a.(b x c), the vertices taken about their mean
    (it is the same about any point for a closed surface); a closed surface enclosing none (a
    triangle and its reverse) keeps WINDING_INSIDE: no point exceeds it."""
    v = tri.vertices - tri.vertices.mean(axis=0)
    a, b, c = (v[tri.triangles[:, j]] for j in range(3))
    terms = np.einsum("ij,ij->i", a, np.cross(b, c))
    inward = terms.sum() < -FLAT_VOLUME * np.abs(terms).sum()
    return -WINDING_INSIDE if inward else WINDING_INSIDE


def winding_numbers(vertices: np.ndarray, triangles: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The generalized winding number of each point x (n, 3) about the triangles (module docstring),
    in batches of at most PAIRS point-triangle pairs, component by component."""
    corners = [vertices[triangles[:, j]].T for j in range(3)]  # each (3, m): a, b, c
    out = np.empty(len(x))
    step = max(1, PAIRS // len(triangles))
    for start in range(0, len(x), step):
        p = x[start : start + step]
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = ([corner[i][None, :] - p[:, i, None] for i in range(3)] for corner in corners)
        det = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
        la, lb, lc = (
            np.sqrt(ax * ax + ay * ay + az * az),
            np.sqrt(bx * bx + by * by + bz * bz),
            np.sqrt(cx * cx + cy * cy + cz * cz),
        )
        below = la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (bx * cx + by * cy + bz * cz) * la
        below += (cx * ax + cy * ay + cz * az) * lb
        out[start : start + step] = np.arctan2(det, below).sum(axis=1) / (2.0 * np.pi)
    return out


def _mesh_distance(tri: TriangleSurface, x: np.ndarray) -> float:
    """The distance (m) from the point x to the nearest point of the triangles: to the plane where
    x projects inside a triangle, else to the nearest of its three edges."""
    a, b, c = (tri.vertices[tri.triangles[:, j]] for j in range(3))
    best = np.inf
    for p, q in ((a, b), (b, c), (c, a)):
        e = q - p
        length2 = np.einsum("ij,ij->i", e, e)
        t = np.clip(np.einsum("ij,ij->i", x - p, e) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
        best = min(best, float(np.linalg.norm(x - p - t[:, None] * e, axis=1).min()))
    n = np.cross(b - a, c - a)
    inner = np.ones(len(n), dtype=bool)
    for p, q in ((a, b), (b, c), (c, a)):
        inner &= np.einsum("ij,ij->i", np.cross(q - p, x - p), n) >= 0.0
    area = np.linalg.norm(n, axis=1)
    inner &= area > 0
    if inner.any():
        best = min(best, float(np.abs(np.einsum("ij,ij->i", x - a[inner], n[inner]) / area[inner]).min()))
    return best


def inside_rows(s, x: np.ndarray) -> np.ndarray:
    """Whether each point x (n, 3) lies inside solid s: a post's or a box's gap below 0, in a
    closed mesh's solid (winding number above `winding_level`; only the points within its box,
    boundary included for one wound inwards, are tested: outside the box the winding number is 0,
    in the solid of a mesh wound inwards, outside one wound outwards); never for other surfaces."""
    if s.kind in ("cylinder", "box"):
        return solid_gaps(s, x) < 0.0
    tri = closed_triangles(s)
    if tri is None:
        return np.zeros(len(x), dtype=bool)
    level = winding_level(tri)
    inside = np.full(len(x), level < 0.0)
    low, high = tri.vertices.min(axis=0), tri.vertices.max(axis=0)
    within = ((x >= low) & (x <= high)) if level < 0.0 else ((x > low) & (x < high))
    near = np.flatnonzero(within.all(axis=1))
    if near.size:
        inside[near] = winding_numbers(tri.vertices, tri.triangles, x[near]) > level
    return inside


def envelope_gap(s, centre: np.ndarray) -> float | None:
    """The signed distance (m, negative inside) from the point `centre` to solid s: a post, a box,
    a closed mesh (negative in its solid: outside it when it is wound inwards, `winding_level`);
    None for other surfaces (planes, plates, open meshes, terrain)."""
    if s.kind in ("cylinder", "box"):
        return float(solid_gaps(s, centre)[0])
    tri = closed_triangles(s)
    if tri is None:
        return None
    distance = _mesh_distance(tri, centre)
    inside = winding_numbers(tri.vertices, tri.triangles, centre[None, :])[0] > winding_level(tri)
    return -distance if inside else distance
