"""Opening a run file for reading, also one whose writer was killed (needs no Warp: `report` uses it)."""

from __future__ import annotations


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
