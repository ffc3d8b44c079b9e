"""Writers: one run's results into a group of an HDF5 file (the root of a run file, or /runs/NNNN of
a sweep file), as HOOMD-blue's writers do: they receive what compute produced and decide nothing
about what is computed.

`RunWriter` creates every object first (SWMR files may not create objects later): the per-pellet
datasets of the fields it is given (fields.FIELDS: chunked, resizable, appended per chunk), the
constants, the statistics the run computes (NaN until the end) and /progress; then after each
chunk it appends the rows, flushes, and commits the chunk by advancing /progress/rows. Every
dataset has a `units` attribute. The layout is documented in docs/output.md.
"""

from __future__ import annotations

import errno
import os
import re

import h5py
import numpy as np

from ..ends import STATES
from ..fields import FIELDS, numpy_dtype, shape
from ..scene.materials import GROUND_KEYS, RANGES
from ..scene.schema import COMPRESSIONS
from ..scene.units import unit_of
from ..tallies.collisions import SHOT_TOTALS, SHOT_TOTALS_UNITS
from ..tallies.ensemble import has_ensemble
from ..tallies.reduce import SEGMENT, SEGMENT_WIDTH
from ..tallies.sums import STAT_UNITS
from . import bound_out, h5md, station_out, tally_out
from .dimensions import name_run_dimensions, name_sweep_dimensions
from .ensemble import create_ensemble_datasets, write_ensemble
from .runfile import _OPEN
from .shards import BOUNDS, create_virtual, cut, record
from .space import check_space

MAX_H5_CHUNK_ROWS = 1 << 16


def _write_failure(exc: Exception, group) -> Exception:
    """An HDF5 write error as a one-line OSError (errno and reason from the library's text, EIO
    and the library's own words when it names no errno) and the file marked broken (detached when
    closed: a library that failed a write is not asked to write again)."""
    text = " ".join(str(exc).split())
    found = re.search(r"errno = (\d+)", text)
    out = _OPEN.get(group.file.filename)
    if out is not None:
        out.broken = True
    if found is None:
        return OSError(errno.EIO, f"{os.strerror(errno.EIO)} ({text[:200]})", _shown_name(group))
    code = int(found.group(1))
    return OSError(code, os.strerror(code), _shown_name(group))


def _shown_name(group) -> str:
    """The name of the file `group` is in, as the user knows it (NAME.partial, not a set-up name)."""
    out = _OPEN.get(group.file.filename)
    return str(out.staging) if out is not None else group.file.filename


def _write_plates(group, surfaces):
    """The shapes of a scene's surfaces of other kinds beside the planes' (docs/geometry.md): `kind`
    (its index in `scene.schema.SURFACE_KINDS`, named in its attribute `kinds`), `axis_u`, `size`
    (m, 3 a surface: a rectangle's 2 sides, a disc's diameter twice, a box's 3 sides, a cylinder's
    diameter twice and its length; zeros elsewhere) and `two_sided`, a plane's entries zero."""
    from ..scene.schema import SURFACE_KINDS

    kinds = [SURFACE_KINDS.index(p.kind or "plane") for p in surfaces]
    axes = [p.axis_u if p.axis_u is not None else (0.0, 0.0, 0.0) for p in surfaces]
    sizes = np.zeros((len(surfaces), 3))
    for i, p in enumerate(surfaces):
        shape = p.size if p.size is not None else (2.0 * (p.radius or 0.0),) * 2 + ((p.length,) if p.length else ())
        sizes[i, : len(shape)] = shape
    for name, unit, data in (
        ("kind", "1", np.asarray(kinds, dtype=np.int32)),
        ("axis_u", "1", np.asarray(axes, dtype=np.float64).reshape(len(surfaces), 3)),
        ("size", "m", sizes),
        ("two_sided", "1", np.asarray([bool(p.two_sided) for p in surfaces], dtype=np.int8)),
    ):
        group.create_dataset(name, data=data).attrs["units"] = unit
    group["kind"].attrs["kinds"] = list(SURFACE_KINDS)


def _write_geometry(group, surfaces, meshes) -> None:
    """The triangles the run used for its boxes, meshes and terrain (docs/output.md), once each:
    `surface_I/vertices` (m, float64 (n, 3), scene coordinates) and `surface_I/triangles` (int32
    (m, 3) vertex indices, counter-clockwise seen from the side pellets meet), I the surface's index;
    attributes `surface` (I), `name` and `kind`."""
    for i, (surface, mesh) in enumerate(zip(surfaces, meshes)):
        if mesh is None:
            continue
        g = group.create_group(f"surface_{i}")
        g.attrs.update(surface=i, name=surface.name or "", kind=surface.kind)
        for name, unit, data in (("vertices", "m", mesh.vertices), ("triangles", "1", mesh.triangles)):
            ds = g.create_dataset(name, data=np.ascontiguousarray(data, dtype=np.float64 if name == "vertices" else np.int32))
            ds.attrs["units"] = unit


def _write_load(group, shot) -> None:
    """[shot] load (scene.loads): its keys as given (the charge in kg), the diameter, density and count
    the shot has (the load's, or the scene's own where it gives them), each number's unit beside it
    (`NAME_units`), and the published tables its size and material come from."""
    from ..scene.loads import sources_of

    load = dict(shot.load)
    for key in ("size", "material"):
        if key in load:
            group.attrs[key] = load[key]
    values = {"charge": load.get("charge"), "diameter": shot.diameter, "density": shot.density, "count": shot.count}
    for key, unit in (("charge", "kg"), ("diameter", "m"), ("density", "kg/m^3"), ("count", "1")):
        if values[key] is not None:
            group.attrs[key], group.attrs[f"{key}_units"] = values[key], unit
    group.attrs["sources"] = sources_of(shot.load)


class RunWriter:
    """Writes one run into `group`: constants, per-pellet chunks, statistics, and the progress a
    reader or `--resume` relies on (/progress: the rows complete, the chunk size, the per-segment
    statistics partials of every complete chunk and, in a run with pair collisions, the per-shot
    totals its collision statistics are made of)."""

    def __init__(self, group: h5py.Group, model, *, scene, fields, pellets: int, stats, scene_toml=None, shards=None):
        """`fields`: the per-pellet fields written; `stats`: the names of the statistics the run
        computes (`tallies.sums.stat_names`); `scene_toml`: the scene recorded, when not `scene`'s
        (a bounded run is laid out as its budget's: `bound.planned`); `shards`: (folder, [(start,
        stop)]) of a run on a cluster, its fields virtual datasets over the tasks' shards
        (`io.shards`), not appended here (a bounded run's over its budget's, `cut` at the end)."""
        self.group = group
        self.fields = tuple(fields)
        self.rows = 0
        group.attrs["scene_toml"] = scene.to_toml() if scene_toml is None else scene_toml
        group.attrs["precision"] = model.precision
        if scene.shot.file is None:
            group.attrs["seed"] = scene.shot.seed
        self._write_constants(group.create_group("constants"), model, scene, pellets)
        h5_rows = max(1, min(MAX_H5_CHUNK_ROWS, pellets))  # compute chunks are whole multiples of it
        for name in self.fields:
            empty = shape(name, 0, model.bounces, model.thresholds)
            if shards is not None:
                ds = create_virtual(group, name, model, pellets, *shards, growing=_bounded(scene))
            else:
                ds = group.create_dataset(
                    FIELDS[name].path,
                    shape=empty,
                    maxshape=(None,) + empty[1:],
                    chunks=(h5_rows,) + empty[1:],
                    dtype=numpy_dtype(name, model.precision),
                    **COMPRESSIONS[scene.output.compression],
                )
            ds.attrs["units"] = FIELDS[name].unit
            ds.attrs["description"] = FIELDS[name].description
            if name == "rest.state":  # its codes' names (`ends`)
                ds.attrs["states"] = np.asarray(STATES, dtype="S")
        self._create_progress(group.create_group("progress"), model, scene)
        record(group["progress"], shards)
        for name in stats:  # written at the end: NaN until then
            ds = group.create_dataset(f"stats/{name}", data=np.nan)
            ds.attrs["units"], ds.attrs["description"] = STAT_UNITS[name]
        if has_ensemble(scene):  # intervals over shots: made now, filled at the end (SWMR: no new objects then)
            create_ensemble_datasets(group, stats, scene.shot.shots)
        if scene.pair_collisions and scene.collisions.frame_every:
            h5md.create_frames(group, pellets, scene.collisions.frame_every)
        if scene.output.quantiles:
            tally_out.create(group, scene, model)
        if _bounded(scene):
            bound_out.create(group, scene.hazard.bound)
        if scene.stations:
            station_out.create(group, scene, model, stats)
        name_run_dimensions(group)  # before SWMR: attaching a scale writes attributes
        self._open_datasets()
        self._start_watching()

    def append_frame(self, step: int, time: float, positions):
        """One H5MD frame: the dense phase's step, its time (s) and every pellet's centre (m)."""
        h5md.append_frame(self.group, step, time, positions)

    @classmethod
    def reopen(cls, group: h5py.Group, *, fields, rows: int, segments: int, shots: int = 0, pieces: int = 0):
        """The writer of a run in an existing file, continuing after `rows` complete rows (and their
        `segments` segment results, with pair collisions the totals of their `shots` shots, and
        the `pieces` rows of per-shot partials of their complete shots):
        anything written after them is cut off."""
        self = cls.__new__(cls)
        self.group = group
        self.fields = tuple(fields)
        self._open_datasets()
        for ds in self.datasets.values():
            ds.resize(rows, axis=0)
        self.segment_results.resize(segments, axis=0)
        if self.shot_totals is not None:
            self.shot_totals.resize(shots, axis=0)
        if self.shot_partials is not None:
            self.shot_partials.resize(pieces, axis=0)
        self.rows = rows
        self.progress_rows[()] = rows
        group.file.flush()
        self._start_watching()
        return self

    def _open_datasets(self):
        g = self.group
        self.datasets = {name: g[FIELDS[name].path] for name in self.fields if not g[FIELDS[name].path].is_virtual}
        self.progress_rows = g["progress/rows"]
        self.chunk_rows = g["progress/chunk_rows"]
        self.segment_results = g["progress/segment_results"]
        self.shot_totals = g.get("progress/shot_totals")  # runs with pair collisions
        self.shot_partials = g.get("progress/shot_partials")  # runs of several shots (tallies.ensemble)
        self.station_ends = g["stations"].attrs["piece_ends"].tolist() if "stations" in g else []  # (io.station_out)

    def _start_watching(self):
        out = _OPEN.get(self.group.file.filename)
        if out is not None and out.watchable and self.group.name == "/":
            out.start_watching()

    @staticmethod
    def _create_progress(g, model, scene):
        g.attrs["description"] = (
            "rows complete (every /pellets dataset and statistics partial below them is "
            "final), the chunk size, and the per-segment statistics partials, in pellet "
            "order: what readers of a running run and --resume rely on"
        )
        g.attrs["segment_rows"] = SEGMENT
        g.attrs["device_name"] = model.device.name
        if scene.shot.file is not None:
            st = os.stat(scene.shot.file)
            g.attrs["pellet_file_size"] = st.st_size
            g.attrs["pellet_file_mtime_ns"] = st.st_mtime_ns
        g.create_dataset("rows", data=np.int64(0)).attrs["units"] = "1"
        g.create_dataset("chunk_rows", data=np.int64(0)).attrs["units"] = "1"
        width = SEGMENT_WIDTH
        ds = g.create_dataset("segment_results", shape=(0, width), maxshape=(None, width), chunks=(256, width), dtype="f8")
        ds.attrs["units"] = "SI (sums of the quantities of warp_ricochet.tallies.sums.SUM_NAMES, then range minima and maxima, m)"
        if scene.pair_collisions:
            ds = g.create_dataset(
                "shot_totals",
                shape=(0, len(SHOT_TOTALS)),
                maxshape=(None, len(SHOT_TOTALS)),
                chunks=(1024, len(SHOT_TOTALS)),
                dtype="f8",
            )
            ds.attrs["columns"] = list(SHOT_TOTALS)
            ds.attrs["units"] = SHOT_TOTALS_UNITS
            ds.attrs["description"] = (
                "per shot: pellets that collided, pellet-pellet collisions counted by both "
                "pellets, energy lost in them, steps and end time of its dense phase"
            )
        if has_ensemble(scene):
            ds = g.create_dataset("shot_partials", shape=(0, width), maxshape=(None, width), chunks=(256, width), dtype="f8")
            ds.attrs["units"] = "as segment_results"
            ds.attrs["description"] = (
                "per piece of 256 pellets of a shot (core.shots.PIECE), shots complete in "
                "order: the statistics partials each shot's values in /stats/shots are made of"
            )

    @staticmethod
    def _write_constants(g, model, scene, pellets):
        def scalar(name, value, unit, doc):
            ds = g.create_dataset(name, data=value)
            ds.attrs["units"] = unit
            ds.attrs["description"] = doc

        scalar("pellets", pellets, "1", "pellets launched")
        scalar("radius", model.radius, "m", "pellet radius R")
        scalar("mass", model.mass, "kg", "pellet mass m = rho 4/3 pi R^3")
        scalar("inertia", model.inertia, "kg m^2", "moment of inertia 2/5 m R^2 (eq. 17)")
        scalar("gravity", np.asarray(scene.physics.gravity), "m/s^2", "gravity vector")
        scalar("impact_duration", scene.physics.impact_duration, "s", "delta t of eq. (1)")
        scalar("bounces", scene.physics.bounces, "1", "ricochets followed per pellet")
        if scene.shot.pattern is not None:  # a choke's pattern (scene.patterns); its name in the scene's TOML
            scalar("pattern", scene.shot.pattern, "percent", "of the charge inside a 30-inch circle at 40 yards")
            spread = "spread of the directions about the aim: standard deviation of tan(polar angle) per axis (~ rad)"
            scalar("pattern_spread", scene.shot.pattern_spread, "1", spread)
        if scene.shot.load is not None:
            _write_load(g.create_group("load"), scene.shot)
        s = g.create_group("surfaces")
        planes = scene.surfaces
        for name, unit, values in (
            ("point", "m", [p.point for p in planes]),
            ("normal", "1", [p.normal for p in planes]),
            ("restitution", "1", [p.restitution for p in planes]),
            ("mu_s", "1", [p.mu_s for p in planes]),
            ("mu_d", "1", [p.mu_d for p in planes]),
            *((key, RANGES[key][2], [p.ground(key) for p in planes]) for key in GROUND_KEYS),
        ):
            arr = np.asarray(values, dtype=np.float64)
            if name in ("point", "normal"):
                arr = arr.reshape(len(planes), 3)
            s.create_dataset(name, data=arr).attrs["units"] = unit
        s.attrs["material"] = [p.material or "" for p in planes]  # catalogue names ("": a rigid plane)
        if any(p.kind for p in planes):
            _write_plates(s, planes)
        if any(m is not None for m in model.meshes):
            _write_geometry(g.parent.create_group("geometry"), planes, model.meshes)

    def append(
        self,
        arrays: dict[str, np.ndarray],
        rows: int,
        segment_results: np.ndarray,
        shot_totals=None,
        tally=None,
        shot_partials=None,
    ):
        """Append the first `rows` rows of each field's array, the chunk's segment results and (pair
        collisions) the totals of its shots, keep the landing counts so far (`tally`), and (several
        shots) the per-shot partials of the shots it completes; flush; then count the rows complete
        and flush again (the commit point of the chunk)."""
        start, stop = self.rows, self.rows + rows
        need = sum(arrays[name][:rows].nbytes for name in self.datasets) + segment_results.nbytes
        need += sum(block.nbytes for block in (shot_totals, shot_partials) if block is not None)
        out = _OPEN.get(self.group.file.filename)
        if out is not None:
            out.reserve(need, "the next chunk")
        else:
            check_space(self.group.file.filename, need, "the next chunk")
        try:
            for name, ds in self.datasets.items():
                ds.resize(stop, axis=0)
                ds[start:stop] = arrays[name][:rows]
            for ds, block in (
                (self.segment_results, segment_results),
                (self.shot_totals, shot_totals),
                (self.shot_partials, shot_partials),
            ):
                if block is not None:
                    done = len(ds)
                    ds.resize(done + len(block), axis=0)
                    ds[done:] = block
            if start == 0:
                self.chunk_rows[()] = rows
            if tally is not None:
                tally_out.store_progress(self.group, tally, stop)
                station_out.store_progress(self.group, tally, stop, self.station_ends)
            self.group.file.flush()
            self.progress_rows[()] = stop
            self.group.file.flush()
        except (OSError, RuntimeError) as exc:
            raise _write_failure(exc, self.group) from None
        self.rows = stop

    def write_stats(self, stats: dict[str, float]):
        """The statistics, and the landing tallies' results (`pipeline.RunStats.tally`)."""
        try:
            write_stats(self.group, stats)
            tally = getattr(stats, "tally", None)
            if tally is not None:
                tally_out.write_results(self.group, tally, int(stats["landed"]), int(stats["pellets"]))
            if getattr(stats, "ensemble", None) is not None:
                write_ensemble(self.group, stats.ensemble)
            if getattr(stats, "bound", None) is not None:
                bound_out.write(self.group, stats.bound)
                _cut_when_closed(self.group)
            if getattr(stats, "stations", None) is not None:
                station_out.write(self.group, stats)
            self.group.file.flush()
        except (OSError, RuntimeError) as exc:
            raise _write_failure(exc, self.group) from None


def _bounded(scene) -> bool:
    return scene.hazard is not None and scene.hazard.bound is not None


def _cut_when_closed(group) -> None:
    """A bounded run's sharded fields made over its budget's tasks: `shards.cut` to the checks run
    once its file is closed (SWMR: no new object before), before it moves into place."""
    out = _OPEN.get(group.file.filename)
    if out is not None and BOUNDS in group["progress"].attrs:
        out.finishing.append(lambda path, name=group.name: cut(path, name))


def unit_of_key(key: str) -> str:
    """The SI unit of a scalar scene key such as "surfaces.0.mu_s" (swept values; scene.units.KEY_UNITS)."""
    return unit_of(key) or "see the scene key"


def write_stats(group: h5py.Group, stats: dict):
    """Write a run's statistics under `group/stats`, as scalars."""
    g = group.require_group("stats")
    for name, value in stats.items():
        ds = g.require_dataset(name, shape=(), dtype="f8")  # a run's writer made it (SWMR: no new objects)
        ds[()] = float(value)
        _describe(ds, name)


def write_stats_table(group: h5py.Group, stats: list[dict]):
    """Write the statistics of a sweep's points under `group/stats`: one array each, a value a
    point (NaN where a point has none), written once, on the dimension `point`."""
    g = group.require_group("stats")
    for name in dict.fromkeys(name for point in stats for name in point):  # (in order of first appearance)
        values = np.array([float(point.get(name, np.nan)) for point in stats], dtype=np.float64)
        _describe(g.create_dataset(name, data=values, fillvalue=np.nan), name)
    name_sweep_dimensions(group)


def _describe(ds: h5py.Dataset, name: str):
    """A statistic's units and description (`STAT_UNITS`), once."""
    if "units" not in ds.attrs:
        unit, doc = STAT_UNITS[name]
        ds.attrs["units"] = unit
        ds.attrs["description"] = doc
