"""HDF5 output, kept apart from compute (as HOOMD-blue does).

`OutputFile` owns the file: it refuses to replace an existing file unless asked, writes the
root attributes once, and marks the run `status` = "running" / "complete" / "interrupted" /
"failed". It writes to `NAME.partial` beside the target and moves it into place only when the
run is complete (atomically; without overwrite, never over a file that appeared meanwhile), so
the target is never half-written and a failed `--overwrite` run leaves the old result intact;
an interrupted or failed run leaves its completed chunks in `NAME.partial`. `RunWriter` writes one run into a group (the root of a run file, or
`/runs/NNNN` of a sweep file): per-pellet datasets that are chunked, resizable and appended per
chunk, constants written once, statistics at the end. Every dataset has a `units` attribute.
The layout is documented in docs/output.md.
"""

from __future__ import annotations

import datetime
import os
from pathlib import Path

import h5py
import numpy as np
import warp as wp

from . import __version__
from .errors import OutputError
from .model import FIELD_SPECS, field_numpy_dtype, field_shape
from .stats import STAT_UNITS

FORMAT_NAME = "warp-ricochet"
FORMAT_VERSION = 1
MAX_H5_CHUNK_ROWS = 1 << 16


def check_output_path(path, overwrite: bool) -> Path:
    """Fail early (before any work) if `path` cannot be written; return it as a Path."""
    text = _output_text(path)
    p = Path(text)
    shown = f"output path = {text!r}"
    if p.suffix.lower() not in (".h5", ".hdf5"):
        raise OutputError(f"{shown}: must end in .h5 or .hdf5")
    if p.is_dir():
        raise OutputError(f"{shown}: is a directory")
    if p.exists() and not overwrite:
        raise OutputError(f"{shown}: exists; pass --overwrite (overwrite=True) to replace it")
    partial = p.with_name(p.name + ".partial")
    if partial.exists() and not overwrite:
        raise OutputError(f"{shown}: {partial.name} exists (the chunks of an earlier interrupted "
                          "run); move it away, or pass --overwrite (overwrite=True) to replace it")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.exists():
        raise OutputError(f"{shown}: folder {str(parent)!r} does not exist")
    if not parent.is_dir():
        raise OutputError(f"{shown}: {str(parent)!r} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK) or (p.exists() and not os.access(p, os.W_OK)):
        raise OutputError(f"{shown}: not writable (permission denied)")
    return p


def _output_text(path) -> str:
    """The output path as text, or a one-line OutputError: a NUL character would cut the name short
    in the C library (and truncate whatever file the shorter name points to)."""
    try:
        text = os.fsdecode(path)
    except TypeError:
        raise OutputError(f"output path = {path!r}: must be a file name (text) ending in .h5 or .hdf5") from None
    if "\0" in text:
        raise OutputError(f"output path = {text!r}: must not contain a NUL character")
    return text


class OutputFile:
    """An HDF5 output file; use as a context manager so its status is always recorded."""

    def __init__(self, path, *, overwrite: bool, kind: str, device: str, scene_toml: str, seed=None,
                 precision=None):
        self.path = check_output_path(path, overwrite)
        self.overwrite = overwrite
        self.partial = self.path.with_name(self.path.name + ".partial")
        try:
            self.h5 = h5py.File(self.partial, "w")
        except OSError as exc:
            raise OutputError(f"output path = {str(self.path)!r}: cannot be created ({exc})") from None
        attrs = self.h5.attrs
        attrs["format"] = FORMAT_NAME
        attrs["format_version"] = FORMAT_VERSION
        attrs["kind"] = kind
        attrs["status"] = "running"
        attrs["package_version"] = __version__
        attrs["warp_version"] = wp.config.version
        attrs["h5py_version"] = h5py.version.version
        attrs["device"] = device
        attrs["created"] = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
        attrs["scene_toml"] = scene_toml
        attrs["units"] = "SI (m, s, kg, J, rad/s)"
        if seed is not None:
            attrs["seed"] = seed
        if precision is not None:
            attrs["precision"] = precision

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            status = "complete"
        elif issubclass(exc_type, KeyboardInterrupt):
            status = "interrupted"
        else:
            status = "failed"
        if exc is not None:
            exc.partial_path = str(self.partial)  # for the one-line message: where the chunks are
        try:
            self.h5.attrs["status"] = status
            self.h5.close()
        except Exception:  # the file is already unusable (e.g. disk full): keep the first error
            if exc_type is None:
                raise
            return False
        if exc_type is None:
            self._move_into_place()
        return False

    def _move_into_place(self):
        """Rename NAME.partial to NAME with Ctrl-C and SIGTERM held off: never half done."""
        import signal

        held = {signal.SIGINT, signal.SIGTERM}
        can_hold = hasattr(signal, "pthread_sigmask")
        if can_hold:
            signal.pthread_sigmask(signal.SIG_BLOCK, held)
        try:
            self._move()
        finally:
            if can_hold:
                signal.pthread_sigmask(signal.SIG_UNBLOCK, held)

    def _move(self):
        if self.overwrite:
            os.replace(self.partial, self.path)
            return
        try:
            os.link(self.partial, self.path)  # atomic, and fails if the target appeared meanwhile
        except FileExistsError:
            raise OutputError(f"output path = {str(self.path)!r}: appeared during the run; the result is in "
                              f"{str(self.partial)!r}") from None
        except OSError:  # no hard links here: check, then rename
            if self.path.exists():
                raise OutputError(f"output path = {str(self.path)!r}: appeared during the run; the result is in "
                                  f"{str(self.partial)!r}") from None
            os.replace(self.partial, self.path)
            return
        os.unlink(self.partial)


class RunWriter:
    """Writes one run into `group`: constants, per-pellet chunks, statistics."""

    def __init__(self, group: h5py.Group, model, *, scene, fields, pellets: int):
        self.group = group
        self.fields = tuple(fields)
        self.rows = 0
        group.attrs["scene_toml"] = scene.to_toml()
        group.attrs["precision"] = model.precision
        if scene.shot.file is None:
            group.attrs["seed"] = scene.shot.seed
        self._write_constants(group.create_group("constants"), model, scene, pellets)
        self.datasets = {}
        h5_rows = max(1, min(MAX_H5_CHUNK_ROWS, pellets))  # compute chunks are whole multiples of it
        for name in self.fields:
            _member, kind, per_bounce, unit, doc = FIELD_SPECS[name]
            shape = field_shape(kind, per_bounce, 0, model.bounces)
            ds = group.create_dataset(
                f"pellets/{name.replace('.', '/')}",
                shape=shape,
                maxshape=(None,) + shape[1:],
                chunks=(h5_rows,) + shape[1:],
                dtype=field_numpy_dtype(kind, model.precision),
            )
            ds.attrs["units"] = unit
            ds.attrs["description"] = doc
            self.datasets[name] = ds

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
        s = g.create_group("surfaces")
        planes = scene.surfaces
        for name, unit, values in (
            ("point", "m", [p.point for p in planes]),
            ("normal", "1", [p.normal for p in planes]),
            ("restitution", "1", [p.restitution for p in planes]),
            ("mu_s", "1", [p.mu_s for p in planes]),
            ("mu_d", "1", [p.mu_d for p in planes]),
        ):
            arr = np.asarray(values, dtype=np.float64)
            if name in ("point", "normal"):
                arr = arr.reshape(len(planes), 3)
            s.create_dataset(name, data=arr).attrs["units"] = unit

    def append(self, arrays: dict[str, np.ndarray], rows: int):
        """Append the first `rows` rows of each field's array, then flush."""
        start, stop = self.rows, self.rows + rows
        for name, ds in self.datasets.items():
            ds.resize(stop, axis=0)
            ds[start:stop] = arrays[name][:rows]
        self.rows = stop
        self.group.file.flush()

    def write_stats(self, stats: dict[str, float]):
        write_stats(self.group, stats)


_KEY_UNITS = {"diameter": "m", "envelope_radius": "m", "density": "kg/m^3", "speed": "m/s", "impact_duration": "s",
              "direction_jitter": "1", "restitution": "1", "mu_s": "1", "mu_d": "1", "count": "1", "seed": "1",
              "bounces": "1", "chunk_size": "1"}


def unit_of_key(key: str) -> str:
    """The SI unit of a scalar scene key such as "surfaces.0.mu_s" (swept values)."""
    return _KEY_UNITS.get(key.rsplit(".", 1)[-1], "see the scene key")


def write_stats(group: h5py.Group, stats: dict, index=None, size=None):
    """Write statistics under `group/stats`: scalars, or element `index` of arrays of `size`."""
    g = group.require_group("stats")
    for name, value in stats.items():
        unit, doc = STAT_UNITS[name]
        if index is None:
            ds = g.create_dataset(name, data=float(value))
        else:
            ds = g.require_dataset(name, shape=(size,), dtype="f8", fillvalue=np.nan)
            ds[index] = float(value)
        ds.attrs["units"] = unit
        ds.attrs["description"] = doc
