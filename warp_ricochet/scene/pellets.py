"""Pellet files: initial states (.npz, .h5/.hdf5) for `shot.file`, validated like the scene.

A file's declared shapes and dtypes (the .npy headers of an .npz, the datasets' of an HDF5 file) are
checked before any data is read: real numbers, (N, 3), one N, at most INT32_MAX pellets, and the
float64 arrays a run holds within the host memory available. The data is then read and validated in
pieces of PIECE_ROWS rows, so a file that declares more than it holds, or holds bad values, costs
at most a piece of memory.
"""

from __future__ import annotations

import contextlib
import math
import os
import zipfile
from pathlib import Path

import numpy as np

from ..errors import SceneError, not_regular
from ..io.space import host_memory_available
from .keys import err as _err
from .schema import INT32_MAX, MAX_COORDINATE, MAX_SPEED, MAX_SPIN

_PELLET_ARRAYS = ("position", "velocity", "angular_velocity")
_FILE_BOUNDS = {"position": (MAX_COORDINATE, "m"), "velocity": (MAX_SPEED, "m/s"), "angular_velocity": (MAX_SPIN, "rad/s")}
PIECE_ROWS = 1 << 20  # rows read and validated at a time (24 MiB as float64)
MAX_H5_CHUNK_BYTES = 1 << 28  # an HDF5 dataset's storage chunk is read whole: at most this
HELD_BYTES_PER_PELLET = 3 * 3 * 8  # a run holds position, velocity, angular_velocity as (N, 3) float64
HOST_FRACTION = 0.5  # of the available host memory those arrays may take


class _Npz:
    """The .npy members of an .npz, read through their headers (numpy.lib.format): nothing is
    loaded until `pieces` reads rows."""

    def __init__(self, path):
        self.zip = zipfile.ZipFile(path)
        self.names = {(m[:-4] if m.endswith(".npy") else m): m for m in self.zip.namelist()}

    def close(self):
        self.zip.close()

    def _open(self, name):
        fp = self.zip.open(self.names[name])
        version = np.lib.format.read_magic(fp)
        reader = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}.get(version)
        if reader is None:
            raise ValueError(f".npy format version {version} (1.0 and 2.0 are read)")
        shape, fortran, dtype = reader(fp)
        return fp, tuple(shape), bool(fortran), np.dtype(dtype)

    def declared(self, name):
        """(shape, dtype) of array `name`, or None if absent."""
        if name not in self.names:
            return None
        fp, shape, _fortran, dtype = self._open(name)
        fp.close()
        return shape, dtype

    def pieces(self, name, n: int):
        """(start, stop, column or None, values) of array `name` (n, 3), PIECE_ROWS rows at a time: whole
        rows in C order; in Fortran order a column at a time (the file holds it so)."""
        fp, _shape, fortran, dtype = self._open(name)
        with fp:
            for column in (0, 1, 2) if fortran else (None,):
                for start in range(0, n, PIECE_ROWS):
                    stop = min(n, start + PIECE_ROWS)
                    count = (stop - start) * (1 if fortran else 3)
                    data = fp.read(count * dtype.itemsize)
                    if len(data) < count * dtype.itemsize:
                        raise ValueError(f"the file ends inside array {name!r} (it declares more than it holds)")
                    values = np.frombuffer(data, dtype=dtype)
                    yield start, stop, column, values if fortran else values.reshape(-1, 3)


class _H5:
    """The datasets of an HDF5 pellet file, at its root or under /pellets/initial/."""

    def __init__(self, path):
        import h5py  # lazily: only pellet files need it

        self.h5py = h5py
        self.file = h5py.File(path, "r")
        initial = self.file.get("pellets/initial")
        self.group = initial if isinstance(initial, h5py.Group) else self.file

    def close(self):
        self.file.close()

    def declared(self, name):
        ds = self.group.get(name)
        if not isinstance(ds, self.h5py.Dataset):
            return None
        if ds.chunks is not None and math.prod(ds.chunks) * ds.dtype.itemsize > MAX_H5_CHUNK_BYTES:
            raise _err(
                f"shot.file:{name}",
                ds.chunks,
                f"storage chunks of {math.prod(ds.chunks) * ds.dtype.itemsize:,} "
                f"bytes are read whole: at most {MAX_H5_CHUNK_BYTES:,}",
            )
        return tuple(ds.shape), ds.dtype

    def pieces(self, name, n: int):
        ds = self.group[name]
        for start in range(0, n, PIECE_ROWS):
            stop = min(n, start + PIECE_ROWS)
            yield start, stop, None, ds[start:stop]


@contextlib.contextmanager
def _opened(path: str):
    """The file as an `_Npz` or `_H5`; every library error a one-line SceneError naming the file."""
    suffix = Path(path).suffix.lower()
    if suffix not in (".npz", ".h5", ".hdf5"):
        raise _err("shot.file", path, "must be a .npz, .h5 or .hdf5 file")
    special = not_regular(path)  # (a FIFO would wait for a writer)
    if special:
        raise _err("shot.file", path, special)
    reader = None
    try:
        reader = _Npz(path) if suffix == ".npz" else _H5(path)
        yield reader
    except SceneError:
        raise
    except Exception as exc:  # noqa: BLE001 - numpy, zipfile and h5py raise many kinds for a bad file
        raise _err("shot.file", path, f"cannot be read: {type(exc).__name__}: {exc}") from None
    finally:
        if reader is not None:
            reader.close()


def _rows(reader, path: str) -> int:
    """N, from the arrays' declared shapes and dtypes alone (nothing read); one-line errors."""
    n = None
    for name in _PELLET_ARRAYS:
        key, declared = f"shot.file:{name}", reader.declared(name)
        if declared is None:
            if name == "angular_velocity":
                continue
            raise _err(key, path, "is missing: the file needs position and velocity arrays of shape (N, 3)")
        shape, dtype = declared
        if dtype.kind not in "iuf" or dtype.fields is not None:
            raise _err(key, str(dtype), "must be a real numeric array")
        if len(shape) != 2 or shape[1] != 3:
            raise _err(key, shape, "must have shape (N, 3)")
        if shape[0] == 0:
            raise _err(key, shape, "must hold at least one pellet")
        if n is not None and shape[0] != n:
            raise _err(key, shape, f"must have the same N as position ({n})")
        n = shape[0]
    if n > INT32_MAX:
        raise _err("shot.file:position", (n, 3), f"{path} declares {n:,} pellets; at most {INT32_MAX:,} are allowed")
    return n


def _check_memory(path: str, n: int) -> None:
    """The arrays a run holds must fit in HOST_FRACTION of the host memory available (the rest is
    the run's: its chunks, the tallies, a launch speed's temporaries)."""
    need, free = n * HELD_BYTES_PER_PELLET, host_memory_available()
    if free is not None and need > HOST_FRACTION * free:
        most = int(HOST_FRACTION * free) // HELD_BYTES_PER_PELLET
        raise _err(
            "shot.file:position",
            (n, 3),
            f"{path} declares {n:,} pellets: a run holds them in "
            f"{need / 2**30:.3g} GiB (position, velocity, angular_velocity as float64), more than half the "
            f"{free / 2**30:.3g} GiB of host memory available: at most {most:,} pellets",
        )


def _read(reader, n: int, keep: bool) -> dict:
    """Every array read and validated piece by piece; with `keep`, returned as (n, 3) float64."""
    out = {}
    for name in _PELLET_ARRAYS:
        key, (bound, unit) = f"shot.file:{name}", _FILE_BOUNDS[name]
        if reader.declared(name) is None:  # (only angular_velocity may be absent)
            out[name] = np.zeros((n, 3)) if keep else None
            continue
        whole = np.empty((n, 3)) if keep else None
        bad, shown = n, None  # the first bad pellet, and its values
        for start, stop, column, values in reader.pieces(name, n):
            piece = np.asarray(values, dtype=np.float64)
            if keep:
                whole[start:stop, slice(None) if column is None else column] = piece
            rows = piece if column is None else piece[:, None]
            wrong = np.flatnonzero(~np.isfinite(rows).all(axis=1) | (np.abs(rows) > bound).any(axis=1))
            if wrong.size and start + wrong[0] < bad:
                bad = start + int(wrong[0])
                if column is None:  # (whole rows, in order: the first found is the first)
                    shown = piece[wrong[0]].tolist()
                    break
        if bad < n:
            if shown is None:  # (Fortran order: the pellet's three values from their columns)
                shown = [
                    float(np.asarray(v, dtype=np.float64)[bad - s]) for s, e, _c, v in reader.pieces(name, n) if s <= bad < e
                ]
            if not all(map(math.isfinite, shown)):
                raise _err(key, shown, f"must be finite (pellet {bad})")
            raise _err(key, shown, f"each component must be within +-{bound:g} {unit} (pellet {bad})")
        out[name] = whole
    return out


def pellet_file_rows(path) -> int:
    """The pellets a file declares, from its headers alone (nothing read): one-line errors for
    arrays of the wrong kind, shape or N, or more than INT32_MAX pellets."""
    path = os.fspath(path)
    with _opened(path) as reader:
        return _rows(reader, path)


def check_pellet_file(path) -> int:
    """`pellet_file_rows`, the host memory a run would hold them in, then every value read and
    validated a piece at a time (none kept): the pellets."""
    path = os.fspath(path)
    with _opened(path) as reader:
        n = _rows(reader, path)
        _check_memory(path, n)
        _read(reader, n, keep=False)
    return n


def position_pieces(path):
    """(start, positions (m, 3) float64, m) of a checked pellet file's pellets, PIECE_ROWS rows at a
    time (an .npz array in Fortran order is read a column at a time into the whole array first)."""
    path = os.fspath(path)
    with _opened(path) as reader:
        n = _rows(reader, path)
        whole = None
        for start, stop, column, values in reader.pieces("position", n):
            if column is None:
                yield start, np.asarray(values, dtype=np.float64)
                continue
            whole = np.empty((n, 3)) if whole is None else whole
            whole[start:stop, column] = values
        for start in range(0, n if whole is not None else 0, PIECE_ROWS):
            yield start, whole[start : start + PIECE_ROWS]


def load_pellet_file(path) -> dict[str, np.ndarray]:
    """Initial pellet state from .npz or .h5/.hdf5: position (N,3) m, velocity (N,3) m/s, angular_velocity
    (N,3) rad/s (zeros if absent), as float64. HDF5 arrays sit at the root or under /pellets/initial/."""
    path = os.fspath(path)
    with _opened(path) as reader:
        n = _rows(reader, path)
        _check_memory(path, n)
        return _read(reader, n, keep=True)
