"""Opening a run file for reading, also one whose writer was killed (needs no Warp: `report` uses it)."""

from __future__ import annotations

FORMAT_NAME = "warp-ricochet"  # the root attribute `format` of run and sweep files
KINDS = ("run", "sweep")  # their root attribute `kind`
FORMAT_VERSION = 2  # the root attribute `format_version` written (2: dimension scales in their datasets' groups)
FORMAT_VERSIONS = (1, 2)  # those read (1: every dimension scale in the run's group)


def file_kind(attrs) -> str | None:
    """ "run" or "sweep" for the root attributes (text) of a warp-ricochet output file, else None."""
    kind = attrs.get("kind")
    return kind if attrs.get("format") == FORMAT_NAME and kind in KINDS else None


def open_for_reading(path, **kwargs):
    """`h5py.File(path, "r")`; a file whose writer died with it open for writing (SWMR: HDF5 refuses
    a plain open, "file is already open for write") is opened as a SWMR reader instead. Only then:
    a SWMR reader retries reads that fail their checksums for a long time, so a truncated or
    damaged file must fail the plain open first. Raises OSError as h5py does."""
    import h5py

    try:
        return h5py.File(path, "r", **kwargs)
    except OSError as exc:
        if "already open for write" not in str(exc):
            raise
    return h5py.File(path, "r", swmr=True, **kwargs)


def open_checked(path, shown: str, error=None):
    """`open_for_reading(path)` for a user's path: a path that is no file, unreadable, no HDF5 file,
    or that HDF5 cannot open is refused in one line (OutputError "<shown>: <problem>", `shown`: the
    key and value, e.g. "open_run path = 'x.h5'"; or `error(problem)` where given)."""
    import os

    import h5py

    from ..errors import OutputError, not_regular

    fail = error or (lambda problem: OutputError(f"{shown}: {problem}"))
    path = os.fsdecode(path)
    if why := not_regular(path):  # (a FIFO would wait for a writer)
        raise fail(why)
    if not os.path.isfile(path):
        raise fail("is a directory" if os.path.isdir(path) else "does not exist")
    try:
        with open(path, "rb"):
            pass
        hdf5 = h5py.is_hdf5(path)
    except OSError as exc:
        raise fail(f"cannot be read: {exc.strerror or exc}") from None
    if not hdf5:
        raise fail("is not an HDF5 file (expected a warp-ricochet .h5 output)")
    try:
        return open_for_reading(path)
    except OSError as exc:
        raise fail(f"HDF5 cannot open it ({' '.join(str(exc).split())})") from None


def rows_final(group, refresh: bool = False) -> int:
    """Rows final in a run group's per-pellet datasets: /progress/rows (an unfinished file's; read
    after a SWMR refresh with `refresh`, so the datasets read next are never shorter), else its
    pellet count (0 without one)."""
    import numpy as np

    progress = group.get("progress/rows")
    if progress is None:
        progress = group.get("constants/pellets")
        if progress is None:
            return 0
    elif refresh:
        progress.refresh()
    return int(np.asarray(progress[()]).reshape(-1)[0])
