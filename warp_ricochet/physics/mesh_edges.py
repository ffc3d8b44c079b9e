"""A mesh's convex edges and their corners, found on the host in float64 (docs/geometry.md, "Meshes
and boxes"): the features a sphere can touch where no face's R-offset covers it
(`physics.edge_contact`).

Triangles share an edge where they share its two end points (positions compared exactly, so an STL's
unmerged copies of a vertex are one point). An edge is kept when it is
- a border (one triangle), or shared by three or more (not a manifold), or by two wound the same
  way round it (their normals disagree on the side pellets meet);
- or convex: the second triangle's third vertex c2 lies behind the first's plane,
  n1.(c2 - a) < -FLAT |c2 - a| (the outward normals turn away from each other).
Flat and concave edges are not: the faces' own contacts meet a sphere there first. A corner is an
end point of a kept edge. Each kept edge and corner is owned by one triangle that holds it (the
first), so that a search over candidate triangles tests it once.
"""

import numpy as np

FEW_FACES = 16  # a mesh of at most this many triangles is searched whole, without its BVH (`mesh_contact`)
FLAT = 1e-9  # sine of a dihedral below which an edge counts as flat (the sphere's gap: R FLAT^2 / 8)
COPLANAR = 64 * 2.0**-52  # a corner this far in front of a plane (of its and the plane's coordinates) counts as on it
FLAT_SINGLE = (
    2.0**-23
)  # `flat_mesh`: in float32 data, a vertex this far off the first triangle's plane (of the coordinates) is on it
INSET = 1e-9  # `inner_depths`: a point projecting this far inside a triangle (of its edges' l1) counts as on its edges


def convex_features(vertices, triangles) -> dict:
    """The kept edges and corners of a mesh (module docstring): `edges` float64 (E, 2, 3) end
    points (m), `corners` float64 (C, 3), and per triangle the kept edges and corners it owns,
    `face_edges` and `face_corners` int32 (m, 3) (indices into `edges` / `corners`, -1 none)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    points, ids = np.unique(vertices, axis=0, return_inverse=True)
    ids = ids.reshape(-1)[triangles]  # (m, 3): the triangles in merged points
    m = len(triangles)
    a, b, c = (points[ids[:, j]] for j in range(3))
    n = np.cross(b - a, c - a)
    size = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, size, out=np.zeros_like(n), where=size > 0)
    # every directed edge (i -> j) of every triangle, with its triangle and the third vertex
    start = ids.reshape(-1)
    stop = ids[:, [1, 2, 0]].reshape(-1)
    third = ids[:, [2, 0, 1]].reshape(-1)
    face = np.repeat(np.arange(m), 3)
    key = np.minimum(start, stop) * len(points) + np.maximum(start, stop)  # (< 2^63: at most 2^30 points)
    unique, which, count = np.unique(key, return_inverse=True, return_counts=True)
    unique = np.stack([unique // len(points), unique % len(points)], axis=1)
    which = which.reshape(-1)
    order = np.argsort(which, kind="stable")  # the directed edges grouped by undirected edge
    first = np.r_[0, np.cumsum(count)[:-1]]
    keep = count != 2
    pair = count == 2
    one, two = order[first[pair]], order[first[pair] + 1]
    same_way = start[one] == start[two]
    behind = np.einsum("ij,ij->i", n[face[one]], points[third[two]] - points[start[one]])
    reach = np.linalg.norm(points[third[two]] - points[start[one]], axis=1)
    keep[np.flatnonzero(pair)] = same_way | (behind < -FLAT * reach)
    kept = np.flatnonzero(keep)
    owner = face[order[first[kept]]]  # the first triangle holding each kept edge
    slot = order[first[kept]] % 3
    face_edges = np.full((m, 3), -1, dtype=np.int32)
    face_edges[owner, slot] = np.arange(len(kept), dtype=np.int32)
    ends = unique[kept]  # (E, 2) merged point ids
    corner_ids = np.unique(ends)
    face_corners = np.full((m, 3), -1, dtype=np.int32)
    where = np.full(len(points), -1, dtype=np.int64)
    where[corner_ids] = np.arange(len(corner_ids))
    flat = ids.reshape(-1)
    held = np.flatnonzero(where[flat] >= 0)  # triangle slots at a corner, in triangle order
    _, firsts = np.unique(flat[held], return_index=True)
    slots = held[firsts]
    face_corners[slots // 3, slots % 3] = where[flat[slots]].astype(np.int32)
    return {"edges": points[ends], "corners": points[corner_ids], "face_edges": face_edges, "face_corners": face_corners}


def covering_faces(vertices, triangles, corners) -> np.ndarray:
    """Per triangle whether every kept corner (`convex_features`' `corners`: the end points of the
    kept edges) lies on or behind its plane, n.(c - a) <= COPLANAR (|c - a| + |a|_1 + |c|_1): within
    float64's rounding of the mesh as given,
    then no kept edge or corner is nearer a centre in front of the plane than its height over it, so
    none is met before the face's R-offset plane is reached from in front (`physics.edge_contact`).
    True for every face of a convex or a flat mesh. bool (m,)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    corners = np.asarray(corners, dtype=np.float64).reshape(-1, 3)
    a, b, c = (vertices[triangles[:, j]] for j in range(3))
    n = np.cross(b - a, c - a)
    size = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, size, out=np.zeros_like(n), where=size > 0)
    away = corners[None, :, :] - a[:, None, :]  # (m, C, 3)
    scale = np.linalg.norm(away, axis=2) + np.abs(a).sum(axis=1)[:, None] + np.abs(corners).sum(axis=1)[None, :]
    ahead = np.einsum("mj,mcj->mc", n, away) - COPLANAR * scale
    return (size[:, 0] > 0) & (ahead <= 0).all(axis=1)


def flat_mesh(vertices, triangles) -> bool:
    """Whether a mesh is flat (searched as its plane: `physics.flat_contact`): every triangle has an
    area and turns its normal the way its first triangle's does, and every vertex lies on that
    triangle's plane within the rounding of the coordinates as given, |n.(p - a)| <= r (|p - a| +
    |a|_1 + |p|_1), r = COPLANAR (`covering_faces`' measure) or, where every coordinate is a float32
    value (an STL's, a binary PLY's), FLAT_SINGLE: such a file rounds a tilted plane's vertices off
    it by up to half a float32 ulp."""
    vertices = np.asarray(vertices, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if len(triangles) == 0:
        return False
    a, b, c = (vertices[triangles[:, j]] for j in range(3))
    n = np.cross(b - a, c - a)
    size = np.linalg.norm(n, axis=1)
    if not (size > 0).all():
        return False
    n = n / size[:, None]
    if not (n @ n[0] > 0).all():
        return False
    used = vertices[np.unique(triangles)]
    single = np.array_equal(used.astype(np.float32).astype(np.float64), used)
    away = used - a[0]
    scale = np.linalg.norm(away, axis=1) + np.abs(a[0]).sum() + np.abs(used).sum(axis=1)
    return bool((np.abs(away @ n[0]) <= (FLAT_SINGLE if single else COPLANAR) * scale).all())


def flat_plane(vertices, triangles) -> np.ndarray:
    """A flat mesh's plane (`flat_mesh`): its first triangle's first vertex a (m) and unit normal
    (b - a) x (c - a) / |.|, in float64. (2, 3)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    a, b, c = vertices[np.asarray(triangles, dtype=np.int64).reshape(-1, 3)[0]]
    n = np.cross(b - a, c - a)
    return np.stack([a, n / np.linalg.norm(n)])


def flat_edges(vertices, triangles, plane, origin) -> tuple:
    """A flat mesh's edge lines (`flat_mesh`, its `flat_plane` (a, n)), for `physics.flat_contact`'s
    inside tests in its plane: per triangle (a, b, c), per edge p -> q of (a -> b, b -> c, c -> a),
    the in-plane unit normal w = n x (q - p) / |q - p| (towards the triangle: it is wound
    counter-clockwise about n) and the offset w.(p - origin) (m), so that w.(y - origin) - offset is
    how far y lies inside that edge (`mesh_contact.edge_distance`); and the slack (m) that covers its
    vertices' distance from the plane, FLAT_SINGLE (|high - low|_1 + |a|_1 + |low|_1 + |high|_1) of
    its box (low, high). float64: ((m, 3, 3) normals, (m, 3) offsets, slack)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    corners = vertices[np.asarray(triangles, dtype=np.int64).reshape(-1, 3)]  # (m, 3, 3)
    a, n = np.asarray(plane, dtype=np.float64)
    p, q = corners, np.roll(corners, -1, axis=1)
    w = np.cross(n, q - p)
    w /= np.linalg.norm(w, axis=2, keepdims=True)
    offsets = np.einsum("mjk,mjk->mj", w, p - np.asarray(origin, dtype=np.float64))
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    slack = FLAT_SINGLE * (np.abs(high - low).sum() + np.abs(a).sum() + np.abs(low).sum() + np.abs(high).sum())
    return w, offsets, float(slack)


def inner_depths(vertices, triangles, edges, corners) -> np.ndarray:
    """Per triangle the least depth (m) behind its plane of the kept edges' and corners' points that
    project inside it (more than INSET of its edges' l1 lengths from them), np.inf where none does
    (a box's faces, a flat mesh's): a centre within R in front of the triangle is farther than R
    from every such point while its overlap of R is less than that depth, and from the points that
    project outside it or onto its edges by at least its distance from them
    (`mesh_contact.leaves_clear`). float64 (m,), the mesh as given."""
    vertices = np.asarray(vertices, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    ends = np.concatenate(
        [
            np.asarray(edges, dtype=np.float64).reshape(-1, 2, 3),
            np.repeat(np.asarray(corners, dtype=np.float64).reshape(-1, 1, 3), 2, axis=1),
        ]
    )
    depths = np.full(len(triangles), np.inf)
    for f, (a, b, c) in enumerate(vertices[triangles]):
        slack = INSET * (np.abs(b - a).sum() + np.abs(c - b).sum() + np.abs(a - c).sum())
        n = np.cross(b - a, c - a)
        if not np.linalg.norm(n) > 0:
            continue
        n = n / np.linalg.norm(n)
        sides = [np.cross(n, q - p) / np.linalg.norm(q - p) for p, q in ((a, b), (b, c), (c, a))]
        lo, hi = np.zeros(len(ends)), np.ones(len(ends))  # the part of each segment over the triangle
        for side, p in zip(sides, (a, b, c)):
            f0, f1 = (ends[:, 0] - p) @ side - slack, (ends[:, 1] - p) @ side - slack
            rising, falling = f1 > f0, f1 < f0
            cross = np.divide(-f0, f1 - f0, out=np.zeros_like(f0), where=f1 != f0)
            lo = np.where(rising, np.maximum(lo, cross), lo)
            hi = np.where(falling, np.minimum(hi, cross), hi)
            flat_out = (f1 == f0) & (f0 <= 0)
            hi = np.where(flat_out, -1.0, hi)
        over = lo <= hi
        if over.any():
            d0, d1 = -(ends[over, 0] - a) @ n, -(ends[over, 1] - a) @ n  # (linear along a segment)
            first, last = d0 + lo[over] * (d1 - d0), d0 + hi[over] * (d1 - d0)
            depths[f] = max(0.0, float(np.minimum(first, last).min()))
    return depths
