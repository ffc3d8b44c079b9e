"""Checks of a run or sweep file given to `plot`, `xdmf`, `report` and `open_run`, made on the open
file before anything is read for output or written: a hostile or damaged file is refused in one
line instead of a traceback, a huge allocation or a silently empty table.

What is checked (docs/output.md, "Damaged files"): the root attributes (`format`, `kind`, a
`format_version` this package reads); every link is a hard link (our files have no soft or external
links: a soft-link loop or a link to another file is refused, never followed); every object's header
opens (HDF5 checks metadata checksums there); datasets are numbers (text only where the layout has
text) and declare no more than MAX_DECLARED_BYTES beyond MAX_COMPRESSION times the file's size (a
1.7 kB file declaring 111 TiB); the counts readers trust are scalar integers in range
(`/constants/pellets` up to INT32_MAX, `/progress/rows` up to it); per-pellet datasets have the
layout's shapes and at least `/progress/rows` rows; `/stats` and `/pellets` are groups, a run's
statistics scalars and a sweep's one value per point; a file marked complete has its statistics;
small datasets are read once (a damaged chunk fails here). Needs h5py and numpy only.
"""

from __future__ import annotations

import os

import h5py
import numpy as np

from ..fields import FIELDS
from .dimensions import is_dimension as _dimension
from .h5open import FORMAT_NAME, FORMAT_VERSIONS, KINDS, open_checked
from .shards import missing

INT32_MAX = 2**31 - 1  # the most pellets a run has (scene.schema: shot.count x shot.shots)
MAX_BOUNCES = 1 << 16  # ricochets followed, well above any scene's physics.bounces
MAX_DECLARED_BYTES = 1 << 30  # a dataset may declare this much whatever the file's size ...
MAX_COMPRESSION = 4096  # ... and beyond it at most this many times the file's size (deflate: ~1032 at most)
READ_BYTES = 1 << 20  # datasets this small are read once, to find damaged data
READ_TOTAL = 64 << 20  # at most this much in all
TEXT = (  # datasets of text in a run group
    "hazard/thresholds/name",
    "hazard/thresholds/kind",
    "hazard/references/name",
    "hazard/references/source",
    "hazard/points/name",  # (issue 26 contract: the named places)
)
TEXT += ("hazard/site/crs", "hazard/site/crs_wkt")  # [hazard.site]: the CRS as given and as WKT
TEXT += ("hazard/bound/threshold_name", "hazard/bound/threshold")  # [hazard.bound] (and its files before: io.bound_out)


class BadFile(ValueError):
    """A file refused by `check_file`: its message is the problem, in one line."""


def open_valid(path, shown: str, error=None) -> h5py.File:
    """`open_checked(path, shown, error)`, then `check_file`: the open file, or OutputError
    "<shown>: <problem>" (`error(problem)` where given)."""
    from ..errors import OutputError

    f = open_checked(path, shown, error)
    try:
        check_file(f)
    except BadFile as exc:
        f.close()
        raise (error(str(exc)) if error else OutputError(f"{shown}: {exc}")) from None
    except BaseException:
        f.close()
        raise
    return f


def check_file(f: h5py.File) -> None:
    """Check the open run or sweep file `f` (see the module notes); raise BadFile naming the first
    problem found."""
    try:
        _check(f)
    except BadFile:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError, OverflowError, MemoryError) as exc:
        from ..errors import hdf5_reason

        raise BadFile(f"is damaged: HDF5 cannot read it ({hdf5_reason(exc)})") from None


def _check(f: h5py.File) -> None:
    attrs = {k: _text(f.attrs[k]) for k in ("format", "kind", "format_version", "status") if k in f.attrs}
    if attrs.get("format") != FORMAT_NAME:
        raise BadFile(
            f"is not a warp-ricochet output file (root attribute format = {attrs.get('format')!r}, expected {FORMAT_NAME!r})"
        )
    if attrs.get("kind") not in KINDS:
        raise BadFile(f"has kind = {attrs.get('kind')!r}; expected one of {', '.join(map(repr, KINDS))}")
    version = attrs.get("format_version")
    if not isinstance(version, (int, np.integer)) or int(version) not in FORMAT_VERSIONS:
        raise BadFile(
            f"has format_version = {version!r}; this warp-ricochet reads format_version "
            f"{' and '.join(map(str, FORMAT_VERSIONS))} (a newer warp-ricochet wrote it?)"
        )
    _links(f)
    budget = [READ_TOTAL]
    size = os.path.getsize(f.filename)
    f.visititems(lambda name, obj: _object(name, obj, size, budget))
    status = attrs.get("status")
    if attrs["kind"] == "run":
        _run(f, "", status)
        return
    if not isinstance(f.get("sweep"), h5py.Group):
        raise BadFile("is a sweep file without a /sweep group")
    runs = f.get("runs")
    if runs is not None and not isinstance(runs, h5py.Group):
        raise BadFile("has /runs that is not a group")
    points = _points(f)
    for name, group in (runs or {}).items():
        if not isinstance(group, h5py.Group):
            raise BadFile(f"has /runs/{name} that is not a group")
        _run(group, f"/runs/{name}", group.attrs.get("status", status))
    for where in ("sweep", "stats"):
        shapes = ((points,), (points, 3)) if where == "sweep" else ((points,),)  # /sweep: a vector key's (points, 3)
        for name, ds in (f.get(where) or {}).items():
            if isinstance(ds, h5py.Dataset) and ds.shape not in shapes and not _dimension(ds):
                allowed = f"({points},)" + (f" or ({points}, 3)" if where == "sweep" else "")
                raise BadFile(f"has /{where}/{name} of shape {ds.shape}; a sweep of {points} points has {allowed}")


def _links(f: h5py.File) -> None:
    """Every link is a hard link: soft links (which can loop) and external links are refused."""
    found = []

    def visit(name, link):
        if not isinstance(link, h5py.HardLink):
            found.append((name, link))
            return True  # stop
        return None

    f.visit_links(lambda name: visit(name, f.get(name, getlink=True)))
    if found:
        name, link = found[0]
        what = "an external link (to another file)" if isinstance(link, h5py.ExternalLink) else "a soft link"
        raise BadFile(f"has /{name}, {what}; warp-ricochet files hold none")


def _object(name: str, obj, size: int, budget: list) -> None:
    """One object (its header opened by the visit): a dataset's type, declared size and data."""
    if not isinstance(obj, h5py.Dataset):
        return
    kind = obj.dtype.kind
    text = name.endswith(TEXT) or (name.rsplit("/", 1)[-1] == "xyz" and _dimension(obj))
    if kind not in "biuf" and not (text and kind in "SO"):
        raise BadFile(f"has /{name} of type {obj.dtype}; expected numbers")
    declared = int(np.prod(obj.shape, dtype=object)) * obj.dtype.itemsize if obj.shape is not None else 0
    if declared > max(MAX_DECLARED_BYTES, MAX_COMPRESSION * size):
        raise BadFile(
            f"has /{name} declaring shape {obj.shape} of {obj.dtype} ({declared:.3g} bytes) in a file of "
            f"{size} bytes: damaged or forged"
        )
    if declared <= READ_BYTES and declared <= budget[0]:
        budget[0] -= declared
        obj[()]  # raises for damaged data (a filter's or checksum's error)


def _count(group, path: str, where: str, top: int) -> int | None:
    ds = group.get(path)
    if ds is None:
        return None
    if not isinstance(ds, h5py.Dataset) or ds.shape != () or ds.dtype.kind not in "iu":
        raise BadFile(f"has {where}/{path} that is not a scalar integer")
    value = int(ds[()])
    if not 0 <= value <= top:
        raise BadFile(f"has {where}/{path} = {value}; expected 0 to {top}")
    return value


def _run(group, where: str, status) -> None:
    """A run group: its counts, per-pellet shapes and statistics."""
    for name in ("pellets", "stats", "constants", "progress"):
        if name in group and not isinstance(group[name], h5py.Group):
            raise BadFile(f"has {where}/{name} that is not a group")
    pellets = _count(group, "constants/pellets", where, INT32_MAX)
    top = INT32_MAX if pellets is None else pellets
    bounces = _count(group, "constants/bounces", where, MAX_BOUNCES)
    rows = _count(group, "progress/rows", where, top)
    for field in FIELDS.values():
        ds = group.get(field.path)
        if ds is None:
            continue
        if not isinstance(ds, h5py.Dataset):
            raise BadFile(f"has {where}/{field.path} that is not a dataset")
        tail = ((bounces,) if field.per_bounce and bounces is not None else ()) + ((3,) if field.kind == "vec3" else ())
        ndim = 1 + field.per_bounce + field.per_threshold + (field.kind == "vec3")
        if (
            len(ds.shape) != ndim
            or (tail and ds.shape[-len(tail) :] != tail)
            or ds.shape[0] > top
            or (rows is not None and ds.shape[0] < rows)
        ):
            raise BadFile(
                f"has {where}/{field.path} of shape {ds.shape}; expected {_expected(ndim, tail)} rows, "
                f"at least /progress/rows = {rows} and at most /constants/pellets = {pellets}"
            )
    gone = missing(group, rows if rows is not None else top)
    if gone is not None:
        raise BadFile(
            f"has {where}/{gone[0]} over a shard that is missing, {gone[1]} (moved or deleted?): "
            "its rows would read as fill values"
        )
    if where:  # a sweep's points: checked by shape above; their statistics by the sweep's
        return
    values = {}
    for name, ds in group.get("stats", {}).items():
        if isinstance(ds, h5py.Dataset):
            if ds.shape != ():
                raise BadFile(f"has /stats/{name} of shape {ds.shape}; a run's statistics are scalars")
            values[name] = float(ds[()])
    if status == "complete" and not np.isfinite(values.get("pellets", np.nan)):
        raise BadFile("is marked complete but holds no statistics (/stats/pellets is missing or NaN)")
    if status == "complete" and pellets is not None and values["pellets"] != pellets:
        raise BadFile(f"is damaged: /stats/pellets = {values['pellets']:.6g} in a run of /constants/pellets = {pellets}")


def _expected(ndim: int, tail: tuple) -> str:
    return "(" + ", ".join(["N"] + [str(n) for n in tail] + ["?"] * (ndim - 1 - len(tail))) + ")"


def _points(f) -> int:
    sweep = f["sweep"]
    shapes = {ds.shape for ds in sweep.values() if isinstance(ds, h5py.Dataset) and not _dimension(ds)}
    bad = [s for s in shapes if not s or s[1:] not in ((), (3,))]  # a scalar key's (points,), a vector key's (points, 3)
    lengths = {s[0] for s in shapes if s}
    if bad or len(lengths) != 1:
        raise BadFile(f"has /sweep datasets of shapes {sorted(shapes)}; expected (points,) or (points, 3) for all")
    return lengths.pop()


def _text(value):
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray) and value.shape == ():
        return value[()]
    return value
