"""Pellet files: initial states (.npz, .h5/.hdf5) for `shot.file`, validated like the scene."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import SceneError, not_regular
from .keys import err as _err
from .schema import MAX_COORDINATE, MAX_SPEED, MAX_SPIN

_PELLET_ARRAYS = ("position", "velocity", "angular_velocity")


def _read_arrays(path: str) -> dict:
    suffix = Path(path).suffix.lower()
    if suffix == ".npz":
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in _PELLET_ARRAYS if k in data.files}
    if suffix in (".h5", ".hdf5"):
        import h5py  # lazily: only pellet files need it
        with h5py.File(path, "r") as f:
            group = f["pellets/initial"] if isinstance(f.get("pellets/initial"), h5py.Group) else f
            return {k: group[k][()] for k in _PELLET_ARRAYS if isinstance(group.get(k), h5py.Dataset)}
    raise _err("shot.file", path, "must be a .npz, .h5 or .hdf5 file")


_FILE_BOUNDS = {"position": (MAX_COORDINATE, "m"), "velocity": (MAX_SPEED, "m/s"), "angular_velocity": (MAX_SPIN, "rad/s")}


def load_pellet_file(path) -> dict[str, np.ndarray]:
    """Initial pellet state from .npz or .h5/.hdf5: position (N,3) m, velocity (N,3) m/s, angular_velocity
    (N,3) rad/s (zeros if absent), as float64. HDF5 arrays sit at the root or under /pellets/initial/."""
    path = os.fspath(path)
    special = not_regular(path)  # (a FIFO would wait for a writer)
    if special:
        raise _err("shot.file", path, special)
    try:
        arrays = _read_arrays(path)
    except SceneError:
        raise
    except Exception as exc:  # noqa: BLE001 - numpy, zipfile and h5py raise many kinds for a bad file
        raise _err("shot.file", path, f"cannot be read: {type(exc).__name__}: {exc}") from None
    out, n = {}, None
    for name in _PELLET_ARRAYS:
        key = f"shot.file:{name}"
        if name not in arrays:
            if name == "angular_velocity":
                out[name] = np.zeros((n, 3))
                continue
            raise _err(key, path, "is missing: the file needs position and velocity arrays of shape (N, 3)")
        a = np.asarray(arrays[name])
        if a.dtype.kind not in "iuf":
            raise _err(key, str(a.dtype), "must be a real numeric array")
        if a.ndim != 2 or a.shape[1] != 3:
            raise _err(key, a.shape, "must have shape (N, 3)")
        if a.shape[0] == 0:
            raise _err(key, a.shape, "must hold at least one pellet")
        if n is not None and a.shape[0] != n:
            raise _err(key, a.shape, f"must have the same N as position ({n})")
        n = a.shape[0]
        a = np.ascontiguousarray(a, dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(a).all(axis=1))
        if bad.size:
            raise _err(key, a[bad[0]].tolist(), f"must be finite (pellet {bad[0]})")
        bound, unit = _FILE_BOUNDS[name]
        bad = np.flatnonzero((np.abs(a) > bound).any(axis=1))
        if bad.size:
            raise _err(key, a[bad[0]].tolist(), f"each component must be within +-{bound:g} {unit} (pellet {bad[0]})")
        out[name] = a
    return out

