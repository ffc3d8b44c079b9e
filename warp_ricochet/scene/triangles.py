"""Triangle surfaces (docs/geometry.md, "Meshes and boxes"): a mesh read from a file (STL, OBJ or
PLY, through trimesh: the optional extra `mesh`) or a closed box, as float64 vertices in scene
coordinates (m) and int32 triangles wound counter-clockwise seen from the side pellets meet."""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass

import numpy as np

from .keys import err
from .schema import MAX_COORDINATE

MAX_TRIANGLES = 2**28  # 3 indices each must fit an int32 index buffer (wp.Mesh)


@dataclass(frozen=True, eq=False)
class TriangleSurface:
    """A triangle mesh: `vertices` float64 (n, 3), m, in scene coordinates; `triangles` int32 (m, 3),
    counter-clockwise seen from the side pellets meet (outward normals); `source`: where it came
    from, for messages; `edges`: its convex edges and corners are contacts of their own
    (`physics.edge_contact`; a terrain's are not: docs/geometry.md, "Meshes and boxes"); `grid`: a
    terrain's `scene.terrain.TerrainGrid` (its raster walked instead of its BVH), or None."""

    vertices: np.ndarray
    triangles: np.ndarray
    source: str
    edges: bool = True
    grid: object = None

    def check(self, key: str) -> TriangleSurface:
        """Itself, or the one-line SceneError naming `key`: an empty mesh, non-finite vertices or
        vertices beyond MAX_COORDINATE, indices out of range, or no triangle of nonzero area."""
        v, f = self.vertices, self.triangles
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(v) == 0 or len(f) == 0:
            raise err(key, self.source, f"must hold at least one triangle (it has {len(v)} vertices, {len(f)} triangles)")
        if len(f) > MAX_TRIANGLES:
            raise err(key, self.source, f"has {len(f):,} triangles; at most {MAX_TRIANGLES:,}")
        if not np.isfinite(v).all():
            raise err(key, self.source, f"must have finite vertices (vertex {int(np.argmin(np.isfinite(v).all(axis=1)))} is not)")
        if np.abs(v).max() > MAX_COORDINATE:  # (as every scene coordinate: one far vertex spoils float32)
            far = int(np.argmax(np.abs(v).max(axis=1)))
            raise err(
                key, self.source, f"has vertex {far} at {v[far].tolist()} m; vertices must be within +-{MAX_COORDINATE:g} m"
            )
        if f.min() < 0 or f.max() >= len(v):
            bad = int(np.argmax((f < 0).any(axis=1) | (f >= len(v)).any(axis=1)))
            raise err(key, self.source, f"has triangle {bad} with a vertex index outside 0 to {len(v) - 1}")
        if not (self.normals(unit=False) ** 2).sum(axis=1).any():
            raise err(key, self.source, "has no triangle of nonzero area")
        return self

    def normals(self, unit: bool = True) -> np.ndarray:
        """Per triangle (b - a) x (c - a) in float64: twice its area along its normal; `unit`: made
        unit (a degenerate triangle's stays zero)."""
        a, b, c = (self.vertices[self.triangles[:, j]] for j in range(3))
        n = np.cross(b - a, c - a)
        if unit:
            length = np.linalg.norm(n, axis=1, keepdims=True)
            n = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
        return n


@functools.lru_cache(maxsize=16)
def _read(path: str, stamp: tuple) -> tuple:
    """(vertices, triangles) of a mesh file as trimesh reads it, unprocessed (no vertex merging);
    ValueError: why it cannot (what is allowed, then trimesh's reason)."""
    try:
        import trimesh
    except ImportError as exc:
        raise ValueError("needs trimesh to read meshes: pip install 'warp-ricochet[mesh]'") from exc
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
        vertices = np.asarray(mesh.vertices, dtype=np.float64)
        triangles = np.asarray(mesh.faces, dtype=np.int64)
    except Exception as exc:  # noqa: BLE001 - trimesh's loaders raise many kinds for a bad file
        reason = " ".join(str(exc).split())[:120] or type(exc).__name__
        raise ValueError(f"must be a triangle mesh (STL, OBJ or PLY) trimesh can read: {reason}") from None
    vertices.setflags(write=False)
    return vertices, triangles


def file_stamp(path: str) -> tuple | None:
    """(modification time in ns, size in bytes) of the file `path`, None if it cannot be read: what
    tells an edited mesh file from the one a cache read."""
    try:
        status = os.stat(path)
    except OSError:
        return None
    return status.st_mtime_ns, status.st_size


def load_mesh(path: str, key: str, offset=(0.0, 0.0, 0.0)) -> TriangleSurface:
    """The checked TriangleSurface of the mesh file `path` moved by `offset` (m); `key` names the
    scene key in its one-line errors (a missing file, one that is not a mesh, `check`'s)."""
    if not os.path.isfile(path):
        raise err(key, path, "must be an existing mesh file (STL, OBJ or PLY)")
    try:
        vertices, triangles = _read(path, file_stamp(path))
    except ValueError as exc:  # the reader's one line, under this key
        raise err(key, path, str(exc)) from None
    if len(triangles) and (triangles.min() < 0 or triangles.max() > np.iinfo(np.int32).max):
        raise err(key, path, "has a vertex index outside the int32 range")
    surface = TriangleSurface(vertices + np.asarray(offset, dtype=np.float64), triangles.astype(np.int32), path)
    return surface.check(key)


# a unit cube's corners (signs along u, v, w) and its 12 triangles, counter-clockwise from outside
_CORNERS = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=np.float64)
_CUBE = np.array(
    [
        [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5],  # -u, +u
        [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],  # -v, +v
        [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],  # -w, +w
    ],
    dtype=np.int32,
)  # fmt: skip


def box_triangles(point, normal, axis_u, size, source: str = "box") -> TriangleSurface:
    """A closed box centred on `point` (m): sides size[0], size[1], size[2] along the unit axes u =
    `axis_u` (made perpendicular to n), v = n x u and n = `normal`; 12 triangles, normals outward."""
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    u = np.asarray(axis_u, dtype=np.float64)
    u = u - np.dot(u, n) * n
    u = u / np.linalg.norm(u)
    axes = np.stack([u, np.cross(n, u), n])  # rows: u, v, w = n (right-handed)
    half = 0.5 * np.asarray(size, dtype=np.float64)
    vertices = np.asarray(point, dtype=np.float64) + (_CORNERS * half) @ axes
    return TriangleSurface(vertices, _CUBE.copy(), source)


def triangles_of(surface) -> TriangleSurface | None:
    """The triangles of a scene surface (`scene.schema.Surface`): a box's 12, a mesh's file's
    (moved by its point), None for a plane or a plate."""
    if surface.kind == "box":
        return box_triangles(surface.point, surface.normal, surface.axis_u, surface.size, source=f"box {surface.name!r}")
    if surface.kind == "mesh":
        return load_mesh(surface.file, "file", surface.point)
    return None
