"""Per-pellet output of a run on a cluster (docs/cluster.md): each task's worker writes its stretch's
rows into a shard of its own, OUT.h5.shards/rows-A-B.h5 (`ShardSink`), and the run file presents
every field as one HDF5 virtual dataset over the shards (`create_virtual`), made with the file (a
SWMR file takes no new objects later) from the run's task bounds, which /progress keeps for
--resume. Sources are named by absolute path; rows whose shard is missing read as the fill value
(NaN, or -1 for integers), never as zeros, and every reader of the package refuses a file whose
committed rows have a shard missing (`missing`, through `inputcheck`).

A bounded run's (`bound`) datasets are made over its budget's tasks, growable as the serial run's;
once it stopped at a check, `cut` makes them present the rows it ran: their tasks' shards only.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from pathlib import Path

import h5py
import numpy as np

from ..fields import FIELDS, numpy_dtype, shape
from ..scene.schema import COMPRESSIONS
from .atomic import replaced

BOUNDS = "shard_bounds"  # /progress attribute: the tasks' [start, stop) rows, (K, 2)
FOLDER = "shard_folder"  # /progress attribute: the shards' folder (absolute)


def folder_of(output) -> Path:
    """The shards' folder of run file `output`: OUT.h5.shards beside it, absolute."""
    return Path(os.path.abspath(os.fspath(output) + ".shards"))


def owned(output) -> Path | None:
    """OUT.h5.shards when run or sweep file `output`, or its OUT.h5.partial (a run's file, or a
    sweep's folder of point files), reads rows from it (a `/progress` `shard_folder` naming it, or
    a sweep point's folder in it); else None, also when they cannot be read (kept on doubt)."""
    folder = folder_of(output)
    if not (folder.is_dir() or folder.is_symlink()):
        return None
    partial = Path(str(folder)[: -len(".shards")] + ".partial")
    files = [Path(str(folder)[: -len(".shards")]), partial] + (sorted(partial.glob("*.h5*")) if partial.is_dir() else [])
    return folder if any(path.is_file() and _names(path, folder) for path in files) else None


def _names(path: Path, folder: Path) -> bool:
    """Whether the run or sweep file `path` reads rows from shards in `folder`."""
    from .h5open import open_for_reading

    try:
        with open_for_reading(path, locking=False) as f:
            runs = f.get("runs")
            for group in [f] + (list(runs.values()) if isinstance(runs, h5py.Group) else []):
                progress = group.get("progress") if isinstance(group, h5py.Group) else None
                named = progress.attrs.get(FOLDER) if isinstance(progress, h5py.Group) else None
                if named is not None:
                    named = Path(named.decode() if isinstance(named, bytes) else str(named))
                    if folder in (named, named.parent):
                        return True
    except (OSError, ValueError, KeyError, TypeError, UnicodeDecodeError):
        return False
    return False


def remove(folder: Path) -> None:
    """Remove a shards' folder; anything else in its place (a link, a file): that, never a link's
    target (rmtree opens what it is given, and opening a FIFO waits for a writer)."""
    if folder.is_symlink() or folder.exists() and not folder.is_dir():
        folder.unlink()
    elif folder.exists():
        shutil.rmtree(folder)


def shard_path(folder, start: int, stop: int) -> str:
    return os.path.join(os.fspath(folder), f"rows-{start:012d}-{stop:012d}.h5")


def fill_value(dtype) -> float | int:
    """What a row of a missing shard reads as: NaN, or -1 for an integer field (never a result)."""
    return np.nan if np.dtype(dtype).kind == "f" else -1


def create_virtual(group, name: str, model, pellets: int, folder, bounds, growing: bool = False) -> h5py.Dataset:
    """Field `name` of a run of `pellets` rows as a virtual dataset over the shards of `bounds`;
    `growing`: its rows unlimited (a bounded run's, `cut` when it stops: the serial run's are)."""
    tail = shape(name, 0, model.bounces, model.thresholds)[1:]
    return _virtual(group, name, tail, numpy_dtype(name, model.precision), pellets, folder, bounds, growing)


def _virtual(group, name: str, tail: tuple, dtype, pellets: int, folder, bounds, growing: bool) -> h5py.Dataset:
    layout = h5py.VirtualLayout(shape=(pellets,) + tail, dtype=dtype, maxshape=((None,) if growing else (pellets,)) + tail)
    for start, stop in bounds:
        source = h5py.VirtualSource(shard_path(folder, start, stop), FIELDS[name].path, shape=(stop - start,) + tail)
        layout[start:stop] = source
    return group.create_virtual_dataset(FIELDS[name].path, layout, fillvalue=fill_value(dtype))


def cut(path, group: str = "/") -> None:
    """Make the sharded fields of the run in `group` of the closed run file `path` (a bounded run's,
    made over its budget's tasks) present its rows complete (`/progress/rows`: the checks it ran):
    virtual datasets over those tasks' shards, their attributes and dimensions kept, and the shards
    of any task past them removed. The file is edited as a copy moved onto it (`atomic.replaced`):
    a kill or an error leaves it as it was closed (complete, its fields the budget's rows)."""
    with h5py.File(path, "r", locking=False) as f:
        g = f[group]
        if BOUNDS not in g["progress"].attrs:
            return
        rows, folder = int(g["progress/rows"][()]), g["progress"].attrs[FOLDER]
        bounds = [(int(a), int(b)) for a, b in g["progress"].attrs[BOUNDS]]
        names = [n for n, field in FIELDS.items() if _is_virtual(g.get(field.path)) and len(g[field.path]) != rows]
    kept, dropped = [b for b in bounds if b[1] <= rows], [b for b in bounds if b[1] > rows]
    assert sum(b - a for a, b in kept) == rows, (rows, kept)  # (tasks never cross a check)
    if names:
        with replaced(path) as tmp:
            shutil.copyfile(path, tmp)
            with h5py.File(tmp, "r+", locking=False) as f:
                g = f[group]
                for name in names:
                    _recut(g, name, rows, folder, kept)
                record(g["progress"], (folder, kept))
    for a, b in dropped:  # (none is written: a check's tasks are submitted once the one before is not met)
        for stale in (shard_path(folder, a, b), shard_path(folder, a, b) + ".partial"):
            with contextlib.suppress(FileNotFoundError):
                os.unlink(stale)


def _is_virtual(ds) -> bool:
    return isinstance(ds, h5py.Dataset) and ds.is_virtual


def _recut(g, name: str, rows: int, folder, bounds) -> None:
    """Field `name` of run group `g` made again as a virtual dataset of `rows` rows over `bounds`,
    with its attributes and dimension scales."""
    old = g[FIELDS[name].path]
    tail, dtype = old.shape[1:], old.dtype
    attrs = {k: v for k, v in old.attrs.items() if k != "DIMENSION_LIST"}
    scales = [list(dim.values()) for dim in old.dims]
    for dim, found in zip(old.dims, scales):  # (each scale lists the datasets attached: detached first)
        for scale in found:
            dim.detach_scale(scale)
    del old, g[FIELDS[name].path]
    ds = _virtual(g, name, tail, dtype, rows, folder, bounds, growing=True)
    ds.attrs.update(attrs)
    for dim, found in zip(ds.dims, scales):
        for scale in found:
            dim.attach_scale(scale)


def record(progress, shards) -> None:
    """Keep a sharded run's (folder, [(start, stop)]) in its /progress group (None: not sharded)."""
    if shards is not None:
        progress.attrs[FOLDER] = str(shards[0])
        progress.attrs[BOUNDS] = np.asarray(shards[1], dtype=np.int64).reshape(-1, 2)


def missing(group, rows: int) -> tuple[str, str] | None:
    """(dataset, shard) of the first virtual per-pellet dataset of `group` whose shard holding some
    of its first `rows` rows is not there; None when every one is."""
    for field in FIELDS.values():
        ds = group.get(field.path)
        if not isinstance(ds, h5py.Dataset) or not ds.is_virtual:
            continue
        for mapping in ds.virtual_sources():
            first = mapping.vspace.get_select_bounds()[0][0]
            if first < rows and not os.path.exists(mapping.file_name):
                return field.path, mapping.file_name
    return None


class ShardSink:
    """A task's shard: the per-pellet rows of its chunks (`pipeline._loop`'s sink), written to
    PATH.partial and renamed PATH when the task is complete (a rerun task starts it again)."""

    def __init__(self, path: str, fields, model, rows: int, compression: str):
        self.path, self.rows, self.done = path, rows, 0
        os.makedirs(os.path.dirname(path), exist_ok=True)
        self.file = h5py.File(path + ".partial", "w")
        self.datasets = {}
        for name in fields:
            full = shape(name, rows, model.bounces, model.thresholds)
            self.datasets[name] = self.file.create_dataset(
                FIELDS[name].path,
                shape=full,
                chunks=(max(1, min(rows, 1 << 16)),) + full[1:] if rows else None,
                dtype=numpy_dtype(name, model.precision),
                **COMPRESSIONS[compression],
            )

    def append(self, arrays, rows, segment_results, shot_totals=None, tally=None, shot_partials=None):
        for name, ds in self.datasets.items():
            ds[self.done : self.done + rows] = arrays[name][:rows]
        self.done += rows

    def close(self, complete: bool):
        self.file.close()
        if complete:
            assert self.done == self.rows, (self.done, self.rows)
            os.replace(self.path + ".partial", self.path)
        else:
            with contextlib.suppress(OSError):
                os.unlink(self.path + ".partial")
