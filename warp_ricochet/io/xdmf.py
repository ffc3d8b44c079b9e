"""XDMF sidecars: `OUT.xmf` beside a run or sweep file, so that ParaView (and VTK's `vtkXdmfReader`)
open the HDF5 results without copying them.

The sidecar is XDMF 2 (http://xdmf.org/index.php/XDMF_Model_and_Format): the format of VTK's
`vtkXdmfReader`, the reader in VTK wheels and in ParaView ("Xdmf Reader"); the XDMF 3 reader is
not built into VTK's wheels. It holds no data of its own except the surfaces' corners and the
frames' times: every array is a reference into the HDF5 file (`NAME.h5:/pellets/...`, a path
relative to the sidecar's folder), a hyperslab of one (one ricochet of an (N, B, 3) dataset, or the
rows `/progress/rows` counts as final in an unfinished file), or a function of such slabs (speeds
and energies). Only datasets that exist in the file are referenced.

What it holds, per run (a run file's root, or each `/runs/NNNN` of a sweep, in its own spatial
collection `point_NNNN`):
- point clouds (Polyvertex, one vertex per pellet, row i = pellet i; NaN positions where there is
  no such point): `launch` (/pellets/initial), `impact_1` ... `impact_B` (the k-th ricochet),
  `landing`, `rest` (where each pellet ends, physics.until = "rest": its `state` code, names in
  /pellets/rest/state's attribute `states`), `release` (runs with pellet-pellet collisions), each with its group's datasets as
  point data, the magnitudes of its vectors (`speed`, `spin`, m/s and rad/s), the energies
  `energy_translational` = m |v|^2 / 2 and `energy_rotational` = I |w|^2 / 2 (J; eq. 40's W_T and
  W_R per pellet), and `landing.range`, `collisions.count`, `collisions.last_time` and the hazard
  at landing (`hazard.energy`, `hazard.energy_density`, `hazard.exceeds`) where present;
- `surfaces`: each plane as a finite quad (cell data: `surface` index, `restitution`, `mu_s`, `mu_d`),
  centred where the plane meets the pellets: it spans the plane's point and the projections onto
  the plane of the box around the launch, impact and landing positions, 10 % wider on each side;
- `geometry_I`: surface I's triangles when it is a box, a mesh or a terrain (/geometry/surface_I,
  the triangles the run used, stored once in the HDF5 file);
- `frames` (runs with H5MD trajectory frames): a temporal collection, one grid per frame at its
  time (s), with the pellets' `id` and the per-pellet values above, so ParaView animates the shot.
"""

from __future__ import annotations

import os
import tempfile
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..errors import OutputError, not_regular
from ..fields import FIELDS
from .h5open import rows_final
from .inputcheck import open_valid

__all__ = ["sidecar_path", "write_xdmf", "xdmf_text"]

EXTRAS = (
    "landing.range",
    "collisions.count",
    "collisions.last_time",  # per-pellet values shown on every cloud
    "hazard.energy",
    "hazard.energy_density",
    "hazard.exceeds",
)
SAMPLE_BLOCK = 1 << 16  # rows read at a time to size the surfaces (at most 16 blocks: bounded time)
SAMPLE_BLOCKS = 16  # blocks read at most (spread over the file)
_NUMBER_TYPES = {"f": "Float", "i": "Int", "u": "UInt"}
_MAGNITUDES = {"velocity": "speed", "angular_velocity": "spin"}
_ENERGIES = {"velocity": ("energy_translational", "mass"), "angular_velocity": ("energy_rotational", "inertia")}


def sidecar_path(path) -> Path:
    """The sidecar of an HDF5 file: NAME.xmf for NAME.h5 or NAME.hdf5, else the name + ".xmf"."""
    p = Path(os.fsdecode(path))
    return p.with_suffix(".xmf") if p.suffix.lower() in (".h5", ".hdf5") else p.with_name(p.name + ".xmf")


def check_sidecar(path, overwrite: bool, shown: str) -> None:
    """Refuse (OutputError) when the sidecar of `path` exists and `overwrite` is not given."""
    xmf = sidecar_path(path)
    if xmf.exists() and not overwrite:
        raise OutputError(f"{shown}: {xmf.name} (its XDMF sidecar) exists; give --overwrite (overwrite=True) to replace it")


def write_xdmf(path, *, overwrite: bool = False) -> Path:
    """Write the XDMF sidecar of the run or sweep file `path` (see the module notes) and return its
    path; refuses (OutputError) a file that is not ours, or an existing sidecar unless `overwrite`.
    The sidecar appears whole (written beside it, then renamed; never over a file that appeared
    meanwhile without `overwrite`)."""
    src = Path(os.fsdecode(path))
    shown = f"file = {str(src)!r}"
    if why := not_regular(src):
        raise OutputError(f"{shown}: {why}")
    if not src.is_file():
        raise OutputError(f"{shown}: does not exist")
    check_sidecar(src, overwrite, shown)
    text = xdmf_text(src)
    _openable(src, shown)
    xmf = sidecar_path(src)
    fd, tmp = tempfile.mkstemp(prefix=xmf.name + ".", suffix=".new", dir=xmf.parent if str(xmf.parent) else ".")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as out:
            out.write(text)
        os.chmod(tmp, 0o666 & ~_umask())
        if overwrite:
            os.replace(tmp, xmf)
        else:
            try:
                os.link(tmp, xmf)
            except FileExistsError:
                raise OutputError(f"{shown}: {xmf.name} appeared meanwhile; give --overwrite to replace it") from None
            os.unlink(tmp)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return xmf


def _openable(src: Path, shown: str) -> None:
    """Make a killed run's partial openable by any HDF5 reader: VTK's (ParaView's) opens files
    plainly, and HDF5 refuses a plain open of a file whose writer died ("already open for write"):
    its superblock's status flags are cleared, as `h5clear -s` does (`--resume` does it too), while
    an exclusive lock shows that no run writes it and the writer the file records (`writer_pid`,
    `writer_host`) is not alive here nor on another host (whose lock is not seen here on NFS/Lustre);
    a file a run may be writing is refused."""
    import h5py

    from .h5open import open_for_reading
    from .locks import try_lock, writer_state
    from .superblock import clear_status_flags

    try:
        h5py.File(src, "r", locking=False).close()
        return
    except OSError as exc:
        if "already open for write" not in str(exc):
            raise OutputError(f"{shown}: HDF5 cannot open it ({' '.join(str(exc).split())})") from None
    busy = (
        f"{shown}: another process has it open (a run writing it?); ParaView cannot open a "
        "file being written: write its sidecar when the run has ended"
    )
    with open_for_reading(src) as f:  # (a flock is local only on NFS/Lustre: the writer the file records)
        attrs = {k: f.attrs.get(k) for k in ("status", "writer_pid", "writer_host")}
    attrs = {k: v.decode("utf-8", "replace") if isinstance(v, bytes) else v for k, v in attrs.items()}
    where = writer_state(attrs) if attrs["status"] == "running" else "unknown"
    if where == "elsewhere":
        raise OutputError(
            f"{shown}: its writer ran on host {attrs['writer_host']!r}, which may still write it; "
            "write its sidecar when that run has ended (or there: h5clear -s, then xdmf)"
        )
    if where == "alive":
        raise OutputError(busy)
    try:
        fd = os.open(src, os.O_RDWR)
    except PermissionError:
        raise OutputError(
            f"{shown}: its writer was killed, and clearing the flags it left (so that ParaView can open "
            "it) needs write access to it: make it writable, or run h5clear -s on it"
        ) from None
    try:
        if not try_lock(fd):
            raise OutputError(busy)
        clear_status_flags(src)
    except ValueError as exc:
        raise OutputError(f"{shown}: HDF5 cannot open it, and its superblock is not one we know ({exc})") from None
    finally:
        os.close(fd)
    warnings.warn(
        f"{src.name}: its writer was killed; cleared the flags it left in the file (as h5clear -s "
        "does) so that ParaView can open it",
        stacklevel=3,
    )


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def xdmf_text(path) -> str:
    """The XDMF document of the run or sweep file `path`, referring to it by its file name."""
    src = Path(os.fsdecode(path))
    shown = f"file = {str(src)!r}"
    with open_valid(src, shown) as f:
        root = ET.Element("Xdmf", Version="2.0")
        domain = ET.SubElement(root, "Domain")
        if f.attrs["kind"] == "run":
            _run(domain, f, src.name, "run", "")
        else:
            for name in sorted(f.get("runs", {})):
                _run(domain, f["runs"][name], src.name, f"point_{name}", f" point_{name}")
    ET.indent(root, space=" ")
    return '<?xml version="1.0" ?>\n' + ET.tostring(root, encoding="unicode") + "\n"


# ------------------------------------------------------------------------------------------ one run


def _run(parent, group, h5name: str, name: str, suffix: str) -> None:
    """A spatial collection `name` of the run's point clouds, surfaces and frames; each grid's name
    ends in `suffix` (ParaView's block names are unique). A run file's one collection is the
    reader's root: its blocks are /Root/landing ... in ParaView."""
    rows = rows_final(group)
    run = ET.SubElement(parent, "Grid", Name=name, GridType="Collection", CollectionType="Spatial")
    ref = _Refs(group, h5name)
    extras = [n for n in EXTRAS if FIELDS[n].path in group]
    constants = {k: float(group[f"constants/{k}"][()]) for k in ("mass", "inertia") if f"constants/{k}" in group}
    bounces = int(group["constants/bounces"][()]) if "constants/bounces" in group else 0
    clouds = [("launch", "initial", None)] + [(f"impact_{b + 1}", "impact", b) for b in range(bounces)]
    clouds += [("landing", "landing", None), ("rest", "rest", None), ("release", "release", None)]
    if rows > 0:
        for cloud, stage, bounce in clouds:
            if FIELDS[f"{stage}.position"].path in group:
                _cloud(
                    run, ref, rows, cloud + suffix, stage, bounce, [e for e in extras if not e.startswith(stage + ".")], constants
                )
    _surfaces(run, group, ref, rows, "surfaces" + suffix)
    _geometry(run, group, ref, suffix)
    _frames(run, group, ref, extras, "frames" + suffix)


class _Refs:
    """XDMF data items referring to the datasets of one HDF5 group."""

    def __init__(self, group, h5name: str):
        self.group, self.h5name = group, h5name

    def __contains__(self, path):
        return path in self.group

    def item(self, parent, path, rows=None, fixed=None):
        """A DataItem of dataset `path`: its first `rows` rows (all: None), with the axes in
        `fixed` ({axis: index}) held at one index (a HyperSlab when anything is left out)."""
        ds = self.group[path]
        shape = list(ds.shape)
        start, count = [0] * len(shape), list(shape)
        if rows is not None:
            count[0] = rows
        for axis, index in (fixed or {}).items():
            start[axis], count[axis] = index, 1
        whole = _data(ds, f"{self.h5name}:{ds.name}", shape)
        if start == [0] * len(shape) and count == shape:
            parent.append(whole)
            return
        slab = ET.SubElement(parent, "DataItem", ItemType="HyperSlab", Type="HyperSlab", Dimensions=_dims(count))
        ET.SubElement(slab, "DataItem", Dimensions=f"3 {len(shape)}", Format="XML").text = " ".join(
            str(v) for v in start + [1] * len(shape) + count
        )
        slab.append(whole)

    def norm(self, parent, path, rows, fixed=None, scale=None):
        """A Function item: |v| of the (..., 3) dataset `path` per row, times `scale` * |v| when
        given (scale |v|^2: an energy)."""
        axis = len(self.group[path].shape) - 1
        squares = "$0*$0 + $1*$1 + $2*$2"
        text = f"sqrt({squares})" if scale is None else f"{scale!r} * ({squares})"
        fn = ET.SubElement(parent, "DataItem", ItemType="Function", Function=text, Dimensions=str(rows))
        for c in range(3):
            self.item(fn, path, rows, {**(fixed or {}), axis: c})


def _data(ds, ref: str, shape) -> ET.Element:
    kind = ds.dtype.kind
    number = "Char" if (kind == "i" and ds.dtype.itemsize == 1) else _NUMBER_TYPES[kind]
    item = ET.Element("DataItem", Dimensions=_dims(shape), NumberType=number, Precision=str(ds.dtype.itemsize), Format="HDF")
    item.text = ref
    return item


def _dims(shape) -> str:
    return " ".join(str(int(n)) for n in shape)


def _attribute(grid, name, kind, unit, center="Node"):
    a = ET.SubElement(grid, "Attribute", Name=name, AttributeType=kind, Center=center)
    ET.SubElement(a, "Information", Name="units", Value=unit)
    return a


def _points_grid(parent, name, rows):
    grid = ET.SubElement(parent, "Grid", Name=name, GridType="Uniform")
    ET.SubElement(grid, "Topology", TopologyType="Polyvertex", NumberOfElements=str(rows), NodesPerElement="1")
    return grid


def _cloud(parent, ref, rows, name, stage, bounce, extras, constants):
    """One point cloud: the positions of `stage` (at ricochet `bounce` for impacts), its datasets as
    point data with the magnitudes and energies of its vectors, and the per-pellet `extras`."""
    fixed = None if bounce is None else {1: bounce}
    grid = _points_grid(parent, name, rows)
    geometry = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
    ref.item(geometry, FIELDS[f"{stage}.position"].path, rows, fixed)
    for field in (f for f in FIELDS.values() if f.name.startswith(stage + ".") and not f.name.endswith(".position")):
        if field.path not in ref:
            continue
        short = field.name.split(".", 1)[1]
        if field.kind != "vec3":
            ref.item(_attribute(grid, short, "Scalar", field.unit), field.path, rows, fixed)
            continue
        ref.item(_attribute(grid, short, "Vector", field.unit), field.path, rows, fixed)
        base, tail = short.removesuffix("_before"), "_before" if short.endswith("_before") else ""
        if base in _MAGNITUDES:
            ref.norm(_attribute(grid, _MAGNITUDES[base] + tail, "Scalar", field.unit), field.path, rows, fixed)
            energy, constant = _ENERGIES[base]
            if constant in constants:
                ref.norm(_attribute(grid, energy + tail, "Scalar", "J"), field.path, rows, fixed, scale=0.5 * constants[constant])
    for extra in extras:
        ref.item(_attribute(grid, extra, "Scalar", FIELDS[extra].unit), FIELDS[extra].path, rows)


# ------------------------------------------------------------------------------------------ surfaces


def _sample_box(group, rows) -> np.ndarray:
    """The 8 corners (8, 3) of the axis-aligned box around the finite positions (launch, impacts,
    landings, releases) of at most SAMPLE_BLOCKS blocks of SAMPLE_BLOCK rows spread over the first
    `rows` rows; (0, 3) when there are none. Their projections onto a plane span at least those
    of the positions themselves."""
    starts = np.arange(0, rows, SAMPLE_BLOCK)
    if len(starts) > SAMPLE_BLOCKS:
        starts = starts[np.linspace(0, len(starts) - 1, SAMPLE_BLOCKS).round().astype(int)]
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for stage in ("initial", "impact", "landing", "rest", "release"):
        path = FIELDS[f"{stage}.position"].path
        if path not in group:
            continue
        ds = group[path]
        for start in starts:
            block = np.asarray(ds[start : min(start + SAMPLE_BLOCK, rows)]).reshape(-1, 3)
            block = block[np.isfinite(block).all(axis=1)]
            if len(block):
                lo, hi = np.minimum(lo, block.min(axis=0)), np.maximum(hi, block.max(axis=0))
    if not np.all(lo <= hi):
        return np.zeros((0, 3))
    return np.array([[(lo, hi)[(k >> axis) & 1][axis] for axis in range(3)] for k in range(8)], dtype=np.float64)


def plane_basis(normal) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane of `normal` (orthonormal, right-handed with it)."""
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    axis = np.zeros(3)
    axis[np.argmin(np.abs(n))] = 1.0  # the axis least aligned with n
    t1 = np.cross(n, axis)
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(n, t1)


def quad_corners(point, normal, positions) -> np.ndarray:
    """The 4 corners (4, 3) of a finite quad of the plane (point, normal), counter-clockwise about
    the normal: it spans `point` and the projections of `positions`, 10 % of the larger span wider
    on each side (1 m wide with nothing to span)."""
    p = np.asarray(point, dtype=np.float64)
    t1, t2 = plane_basis(normal)
    rel = np.vstack([np.zeros(3), np.asarray(positions, dtype=np.float64).reshape(-1, 3) - p])
    u, v = rel @ t1, rel @ t2
    span = max(u.max() - u.min(), v.max() - v.min())
    pad = 0.1 * span if span > 0 else 0.5
    (u0, u1), (v0, v1) = (u.min() - pad, u.max() + pad), (v.min() - pad, v.max() + pad)
    return np.array([p + a * t1 + b * t2 for a, b in ((u0, v0), (u1, v0), (u1, v1), (u0, v1))])


def _surfaces(parent, group, ref, rows, name):
    """The planes as finite quads, with their index and coefficients as cell data (none for a
    scene without planes); the finite plates as triangles in a grid of their own (`_plates`)."""
    if "constants/surfaces/point" not in group:
        return
    points, normals = group["constants/surfaces/point"][()], group["constants/surfaces/normal"][()]
    planes = np.arange(len(points))
    if "constants/surfaces/kind" in group:
        _plates(parent, group, name.replace("surfaces", "plates"))
        planes = np.flatnonzero(group["constants/surfaces/kind"][()] == 0)  # (SURFACE_KINDS' indices)
    if len(planes) == 0:
        return
    sample = _sample_box(group, rows)
    corners = np.concatenate([quad_corners(points[i], normals[i], sample) for i in planes])
    grid = ET.SubElement(parent, "Grid", Name=name, GridType="Uniform")
    ET.SubElement(grid, "Topology", TopologyType="Quadrilateral", NumberOfElements=str(len(planes)))
    geometry = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
    item = ET.SubElement(geometry, "DataItem", Dimensions=f"{len(corners)} 3", NumberType="Float", Precision="8", Format="XML")
    item.text = "\n" + "\n".join(" ".join(repr(float(x)) for x in c) for c in corners) + "\n"
    _cell_values(grid, "surface", planes)
    for key in ("restitution", "mu_s", "mu_d"):
        path = f"constants/surfaces/{key}"
        if path in ref and len(planes) == len(points):
            ref.item(_attribute(grid, key, "Scalar", "1", "Cell"), path)
        elif path in ref:
            _cell_values(grid, key, group[path][()][planes])


def _cell_values(grid, key, values):
    """Cell data `key` written into the sidecar itself (integers, or float64 values)."""
    integer = np.asarray(values).dtype.kind in "iu"
    data = ET.SubElement(
        _attribute(grid, key, "Scalar", "1", "Cell"),
        "DataItem",
        Dimensions=str(len(values)),
        NumberType="Int" if integer else "Float",
        Precision="4" if integer else "8",
        Format="XML",
    )
    data.text = " ".join(str(int(x)) if integer else repr(float(x)) for x in values)


DISC_SIDES = 48  # triangles of a disc's fan in the sidecar


def plate_triangles(point, normal, axis_u, size, kind) -> np.ndarray:
    """The triangles (T, 3, 3) of a plate (docs/geometry.md), counter-clockwise about its normal:
    a rectangle (kind 1) of sides `size` along axis_u and normal x axis_u as 2, a disc (kind 2) of
    diameter size[0] as a fan of DISC_SIDES inscribed in it; a post (kind 6: `post_triangles`)."""
    p, n, u = (np.asarray(x, dtype=np.float64) for x in (point, normal, axis_u))
    n = n / np.linalg.norm(n)
    if kind == 6:
        return post_triangles(p, n, 0.5 * size[0], size[2])
    if kind == 2:
        u, v = plane_basis(n)
        angles = 2.0 * np.pi * np.arange(DISC_SIDES + 1) / DISC_SIDES
        rim = p + 0.5 * size[0] * (np.cos(angles)[:, None] * u + np.sin(angles)[:, None] * v)
        return np.stack([np.broadcast_to(p, (DISC_SIDES, 3)), rim[:-1], rim[1:]], axis=1)
    v = np.cross(n, u)
    a, b = 0.5 * size[0] * u, 0.5 * size[1] * v
    c = [p - a - b, p + a - b, p + a + b, p - a + b]
    return np.array([[c[0], c[1], c[2]], [c[0], c[2], c[3]]])


def post_triangles(base, axis, radius, length) -> np.ndarray:
    """A post's triangles (docs/geometry.md "Posts"): its side as DISC_SIDES quads (two triangles
    each) and its caps as fans, all counter-clockwise seen from outside; `axis` unit, from the base's
    centre to the top's."""
    u, v = plane_basis(axis)
    angles = 2.0 * np.pi * np.arange(DISC_SIDES + 1) / DISC_SIDES
    ring = radius * (np.cos(angles)[:, None] * u + np.sin(angles)[:, None] * v)
    low, high = base + ring, base + length * axis + ring
    side = np.concatenate([np.stack([low[:-1], low[1:], high[1:]], axis=1), np.stack([low[:-1], high[1:], high[:-1]], axis=1)])
    top = np.stack([np.broadcast_to(base + length * axis, (DISC_SIDES, 3)), high[:-1], high[1:]], axis=1)
    bottom = np.stack([np.broadcast_to(base, (DISC_SIDES, 3)), low[1:], low[:-1]], axis=1)
    return np.concatenate([side, top, bottom])


def _plates(parent, group, name):
    """The finite plates and posts as triangles, with their surface's index and coefficients as cell data."""
    s = group["constants/surfaces"]
    kinds = s["kind"][()]
    which = np.flatnonzero((kinds == 1) | (kinds == 2) | (kinds == 6))  # plates, posts (boxes, meshes, terrain: `_geometry`)
    if not len(which):
        return
    parts = [plate_triangles(s["point"][i], s["normal"][i], s["axis_u"][i], s["size"][i], kinds[i]) for i in which]
    owner = np.concatenate([np.full(len(t), i) for i, t in zip(which, parts)])
    corners = np.concatenate(parts).reshape(-1, 3)
    grid = ET.SubElement(parent, "Grid", Name=name, GridType="Uniform")
    ET.SubElement(grid, "Topology", TopologyType="Triangle", NumberOfElements=str(len(owner)))
    geometry = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
    item = ET.SubElement(geometry, "DataItem", Dimensions=f"{len(corners)} 3", NumberType="Float", Precision="8", Format="XML")
    item.text = "\n" + "\n".join(" ".join(repr(float(x)) for x in c) for c in corners) + "\n"
    for key in ("surface", "restitution", "mu_s", "mu_d"):
        _cell_values(grid, key, owner if key == "surface" else s[key][()][owner])


def _geometry(parent, group, ref, suffix):
    """The boxes, meshes and terrain as the triangles the run used: one grid `geometry_I` per
    surface I, its topology and points references to /geometry/surface_I (stored once in the HDF5
    file, so a terrain of 1e6 triangles adds no data to the sidecar); the surface's index, name and
    coefficients as Information."""
    if "geometry" not in group:
        return
    s = group["constants/surfaces"]
    meshes = {int(g.attrs["surface"]): key for key, g in group["geometry"].items() if "surface" in g.attrs}
    for i, key in sorted(meshes.items()):  # (the group also holds their dimension scales)
        g = group["geometry"][key]
        grid = ET.SubElement(parent, "Grid", Name=f"geometry_{i}{suffix}", GridType="Uniform")
        info = {"surface": str(i), "name": str(g.attrs["name"]), "kind": str(g.attrs["kind"])}
        info.update({k: repr(float(s[k][i])) for k in ("restitution", "mu_s", "mu_d") if k in s})
        for name, value in info.items():
            ET.SubElement(grid, "Information", Name=name, Value=value)
        count = str(g["triangles"].shape[0])
        ref.item(ET.SubElement(grid, "Topology", TopologyType="Triangle", NumberOfElements=count), f"geometry/{key}/triangles")
        ref.item(ET.SubElement(grid, "Geometry", GeometryType="XYZ"), f"geometry/{key}/vertices")


# ------------------------------------------------------------------------------------------ frames


def _frames(parent, group, ref, extras, name):
    """The H5MD trajectory frames as a temporal collection (one grid per frame, at its time)."""
    value = "particles/pellets/position/value"
    if value not in group or group[value].shape[0] == 0:
        return
    frames, pellets = group[value].shape[:2]
    times = group["particles/pellets/position/time"][()]
    collection = ET.SubElement(parent, "Grid", Name=name, GridType="Collection", CollectionType="Temporal")
    for k in range(frames):
        grid = _points_grid(collection, f"frame_{k}", pellets)
        ET.SubElement(grid, "Time", Value=repr(float(times[k])))
        geometry = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
        ref.item(geometry, value, None, {0: k})
        if "particles/pellets/id" in ref:
            ref.item(_attribute(grid, "id", "Scalar", "1"), "particles/pellets/id")
        for extra in extras:
            ref.item(_attribute(grid, extra, "Scalar", FIELDS[extra].unit), FIELDS[extra].path, pellets)
