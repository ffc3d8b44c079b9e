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

FLAT = 1e-9  # sine of a dihedral below which an edge counts as flat (the sphere's gap: R FLAT^2 / 8)


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
