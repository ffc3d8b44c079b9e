"""Named dimensions of a run file: HDF5 dimension scales (the HDF5 Dimension Scale specification, as
netCDF-4 writes them), so that netCDF readers (h5netcdf, xarray, netCDF-C) see `pellet`, `bounce`,
`xyz`, ... instead of anonymous dimensions.

A dimension is a dataset in the top group of the datasets it names (`/constants/surface`,
`/progress/segment`, `/hazard/threshold`; below /stats, whose datasets are the statistics, in its
subgroup: `/stats/quantiles/level`), except `pellet`, `bounce`, `xyz` and `frame`, in the run's
group: /pellets holds per-pellet fields only (code walks it), and H5MD's groups only what H5MD
names. format_version 1 kept them all in the run's group (the file's root). netCDF
readers look a dimension up in the group of a variable and its ancestors only, so one `/dims` group
would hide them; and a dimension in the run's root clashed with a variable of its name in any group
below (`/hazard/map/surface`: h5netcdf sliced that scalar as a coordinate). `xyz` is a coordinate
(the strings "x", "y", "z"); the others are dimension-only scales (netCDF's "This is a netCDF
dimension but not a netCDF variable." name): they hold no data and cost no disk, and an unlimited
one (`pellet`, `frame`, `segment`, `shot`) takes its length from the datasets attached to it, as
netCDF defines it. `name_run_dimensions` runs after the writer made a run's objects and before the
file switches to SWMR (HDF5 attaches scales by writing attributes, which SWMR forbids later).
"""

from __future__ import annotations

import h5py
import numpy as np

from ..fields import FIELDS
from ..scene.materials import GROUND_KEYS

NOT_A_VARIABLE = "This is a netCDF dimension but not a netCDF variable."
XYZ = ("x", "y", "z")

# datasets of a run group (relative paths) -> the names of their axes (per-pellet fields: from fields.FIELDS)
RUN_DIMENSIONS = {
    "constants/gravity": ("xyz",),
    "constants/surfaces/point": ("surface", "xyz"),
    "constants/surfaces/normal": ("surface", "xyz"),
    "constants/surfaces/restitution": ("surface",),
    "constants/surfaces/mu_s": ("surface",),
    "constants/surfaces/mu_d": ("surface",),
    "constants/surfaces/kind": ("surface",),  # with finite plates (docs/geometry.md)
    "constants/surfaces/axis_u": ("surface", "xyz"),
    "constants/surfaces/size": ("surface", "side"),
    "constants/surfaces/two_sided": ("surface",),
    **{f"constants/surfaces/{key}": ("surface",) for key in GROUND_KEYS},  # ground materials (scene.materials)
    "progress/segment_results": ("segment", "segment_column"),
    "progress/shot_totals": ("shot", "shot_column"),
    "progress/shot_partials": ("shot_piece", "segment_column"),  # runs of several shots (tallies.ensemble)
    "particles/pellets/position/step": ("frame",),
    "particles/pellets/position/time": ("frame",),
    "particles/pellets/position/value": ("frame", "pellet", "xyz"),
    "particles/pellets/species": ("pellet",),
    "particles/pellets/id": ("pellet",),
    # landing tallies (io.tally_out, docs/hazard.md)
    "progress/tally": ("tally_slot", "tally_column"),
    "progress/tally_rows": ("tally_slot",),
    "stats/histograms/counts": ("histogram_row", "bin"),
    "stats/histograms/edges": ("bin_edge",),
    "stats/histograms/rest_counts": ("bin",),  # physics.until = "rest"
    **{
        f"stats/quantiles/{lower}{q}": ("level",)
        for q in ("range", "distance", "speed", "energy", "rest_distance")
        for lower in ("", "lower/")
    },
    **{f"stats/tail/{name}": ("tail_distance",) for name in ("distance", "count", "fraction")},
    **{f"hazard/thresholds/{name}": ("threshold",) for name in ("name", "kind", "value", "speed", "landings", "reaching")},
    **{
        f"hazard/{group}/{name}": ("threshold", "fraction")
        for name in ("distance", "ci_low", "ci_high", "needed_landings")
        for group in ("danger_distance", "landing_danger_distance")
    },
    "hazard/danger_distance/fraction": ("fraction",),
    "hazard/landing_danger_distance/fraction": ("fraction",),
    "hazard/map/passes": ("map_v", "map_u"),
    "hazard/map/exposure": ("threshold", "map_v", "map_u"),
    "hazard/map/exposure_outside": ("all_then_threshold",),
    "hazard/map/count": ("map_v", "map_u"),
    "hazard/map/energy": ("map_v", "map_u"),
    "hazard/map/above": ("threshold", "map_v", "map_u"),
    "hazard/map/u_edges": ("map_u_edge",),
    "hazard/map/v_edges": ("map_v_edge",),
    # named places (docs/hazard.md, section 9): the dimension `place` (a sweep's `point` is another)
    **{f"hazard/points/{name}": ("place",) for name in ("name", "area", "radius")},
    "hazard/points/position": ("place", "xyz"),
    **{
        f"hazard/points/{name}": ("place", "threshold")
        for name in ("pellets", "expected_per_shot", "expected_ci_low", "expected_ci_high", "probability", "ci_low", "ci_high")
    },
    "hazard/site/shooter": ("site_xy",),  # [hazard.site] (gis.site): the CRS's x, y
    "hazard/site/local": ("site_dl", "site_uv1"),  # rows d, l; columns u, v, 1
}


def field_dimensions(name: str) -> tuple[str, ...]:
    """The axes of per-pellet field `name` ("landing.position" -> ("pellet", "xyz"))."""
    f = FIELDS[name]
    columns = ("bounce",) if f.per_bounce else ("threshold",) if f.per_threshold else ()
    return ("pellet",) + columns + (("xyz",) if f.kind == "vec3" else ())


def in_station(path: str) -> tuple[str, str] | None:
    """(`stations/<name>`, the rest) of a path below a station's group, which holds the run's
    layout of its own pellets (`io.station_out`); None for any other path."""
    parts = path.split("/", 2)
    return ("/".join(parts[:2]), parts[2]) if parts[0] == "stations" and len(parts) == 3 else None


def dimensions_of(path: str, ds: h5py.Dataset) -> tuple[str, ...]:
    """The axes of the dataset at `path` (relative to its run group; a station's as the run's):
    from the layout, else, for a dataset the layout does not know, `xyz` for a last axis of 3 and
    `<path>_<axis>` (slashes as underscores: one dimension per dataset and axis) for the rest."""
    if (station := in_station(path)) is not None:
        return dimensions_of(station[1], ds)
    if path.startswith("pellets/") and path.count("/") == 2:
        name = path[len("pellets/") :].replace("/", ".")
        if name in FIELDS:
            return field_dimensions(name)
    if path in RUN_DIMENSIONS:
        return RUN_DIMENSIONS[path]
    if path.startswith("stats/shots/"):  # each statistic's per-shot values
        return ("shot",)
    if path.startswith("geometry/") and path.count("/") == 2:  # a mesh's vertices (m, xyz), triangles (corners)
        surface, name = path.split("/")[1:]
        return (f"{surface}_vertex", "xyz") if name == "vertices" else (f"{surface}_triangle", "corner")
    base = path.replace("/", "_")
    return tuple("xyz" if n == 3 and axis == ds.ndim - 1 else f"{base}_{axis}" for axis, n in enumerate(ds.shape))


def scale(group: h5py.Group, name: str, size: int, unlimited: bool) -> h5py.Dataset:
    """The dimension `name` of `group`: made (a dimension scale) if it does not exist."""
    if name in group:
        return group[name]
    if name == "xyz":
        ds = group.create_dataset(name, data=np.array(XYZ, dtype=object), dtype=h5py.string_dtype())
        ds.make_scale(name)
        ds.attrs["units"] = "1"
        ds.attrs["description"] = "Cartesian components (SI axes of the scene)"
        return ds
    if unlimited:
        ds = group.create_dataset(name, shape=(0,), maxshape=(None,), chunks=(1024,), dtype="f4")
    else:
        ds = group.create_dataset(name, shape=(size,), dtype="f4")  # never written: no storage
    ds.make_scale(name)
    ds.attrs["NAME"] = np.bytes_(f"{NOT_A_VARIABLE}{0 if unlimited else size:10d}")
    ds.attrs["units"] = "1"
    ds.attrs["description"] = f"the dimension {name} (an HDF5 dimension scale without data; docs/output.md)"
    return ds


def attach(root: h5py.Group, ds: h5py.Dataset, names: tuple[str, ...]) -> None:
    """Attach the dimensions `names` (made in `root` as needed) to the axes of `ds`."""
    for axis, name in enumerate(names):
        dim = ds.dims[axis]
        if name is None or len(dim):
            continue
        dim.attach_scale(scale(root, name, ds.shape[axis], ds.maxshape[axis] is None))


def is_dimension(obj) -> bool:
    """Whether `obj` is a dimension scale holding no values of its own (`xyz`, or a dimension-only
    scale): readers that walk a group leave it out."""
    if not isinstance(obj, h5py.Dataset) or obj.attrs.get("CLASS") != b"DIMENSION_SCALE":
        return False
    return obj.name.rsplit("/", 1)[-1] == "xyz" or bytes(obj.attrs.get("NAME", b"")).startswith(NOT_A_VARIABLE.encode())


def name_run_dimensions(group: h5py.Group) -> None:
    """Attach named dimensions to every dataset of the run in `group` (its per-pellet datasets,
    constants, progress and frames; not its scalars), each made in the group `home_of` names."""
    found = []

    def visit(path, obj):
        if isinstance(obj, h5py.Dataset) and obj.ndim and path.split("/", 1)[0] != "runs" and not is_dimension(obj):
            found.append((path, obj))

    group.visititems(visit)
    for path, ds in found:
        for axis, name in enumerate(dimensions_of(path, ds)):
            home = home_of(path, name)
            attach(group[home] if home else group, ds, (None,) * axis + (name,))


RUN_GROUP_DIMENSIONS = ("pellet", "bounce", "xyz", "frame")  # in the run's group: /pellets holds fields only


def home_of(path: str, name: str) -> str:
    """The group (relative to the run's) holding the dimension `name` of the dataset at `path`: the
    run's ("") for RUN_GROUP_DIMENSIONS, the H5MD frames' and a dataset's of the run's group; else
    the dataset's top group, its second below /stats; below a station's group, that group's
    (`stations/<name>/hazard/threshold`: a station's shots and map are its own)."""
    if (station := in_station(path)) is not None:
        home = home_of(station[1], name)
        return f"{station[0]}/{home}" if home else ""
    parts = path.split("/")[:-1]
    if name in RUN_GROUP_DIMENSIONS or not parts or parts[0] == "particles":
        return ""
    return "/".join(parts[:2] if parts[0] == "stats" else parts[:1])


def name_sweep_dimensions(root: h5py.Group) -> None:
    """Attach the dimension `point` (the sweep's points) to the arrays of /sweep and /stats, and
    `xyz` to a swept vector's components ((points, 3) in /sweep): the sweep file's dimensions, in
    its root (the groups share them)."""
    for name in ("sweep", "stats"):
        if name in root:
            for ds in root[name].values():
                if isinstance(ds, h5py.Dataset) and ds.ndim == 1:
                    attach(root, ds, ("point",))
                elif isinstance(ds, h5py.Dataset) and name == "sweep" and ds.ndim == 2 and ds.shape[1] == 3:
                    attach(root, ds, ("point", "xyz"))
