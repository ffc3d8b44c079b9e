"""H5MD 1.1 trajectory frames of the dense phase (https://www.nongnu.org/h5md/h5md.html, version 1.1.0,
with its `units` module 1.0): the H5MD root is the run's group (the file's root for a run file).

    h5md                       +-- version [1, 1]
     \\-- author                +-- name (the login name of the user who ran it)
     \\-- creator               +-- name "warp-ricochet", version
     \\-- modules/units         +-- version [1, 0], system "SI"
    particles/pellets
     \\-- box                   +-- dimension 3, boundary ["none", "none", "none"] (open space: no edges)
     \\-- position
     |    \\-- step: int64[F]   (steps of the dense phase)
     |    \\-- time: float64[F] +-- unit "s" (since launch)
     |    \\-- value: float64[F][N][3] +-- unit "m" (pellet centres)
     \\-- species: int32[N]     (0: the pellets of a run are identical)
     \\-- id: int64[N]          (the pellet's row in /pellets)

Every dataset also carries the project's `units` attribute. The spec's strings: `name`, `version`
and `boundary` are fixed-length ASCII, `unit` and `system` variable-length ASCII.
"""

import getpass

import h5py
import numpy as np

from .._version import __version__

_VL_ASCII = h5py.string_dtype("ascii")


def _fixed(text: str) -> np.bytes_:
    """A fixed-length ASCII string (h5py stores np.bytes_ as such)."""
    return np.bytes_(text.encode("ascii", "replace"))


def _author() -> str:
    try:
        return getpass.getuser()
    except (KeyError, OSError):  # no login name (a container without a passwd entry)
        return "unknown"


def create_frames(group, pellets: int, every: int):
    """The H5MD metadata, box, species, ids and the empty frame datasets, which the dense phase
    appends to (made with the file: SWMR files create no objects once readers may open them)."""
    h5md = group.create_group("h5md")
    h5md.attrs["version"] = np.array([1, 1], dtype=np.int32)
    h5md.create_group("author").attrs["name"] = _fixed(_author())
    creator = h5md.create_group("creator")
    creator.attrs["name"] = _fixed("warp-ricochet")
    creator.attrs["version"] = _fixed(__version__)
    units = h5md.create_group("modules/units")
    units.attrs["version"] = np.array([1, 0], dtype=np.int32)
    units.attrs.create("system", "SI", dtype=_VL_ASCII)
    particles = group.create_group("particles/pellets")
    box = particles.create_group("box")
    box.attrs["dimension"] = np.int32(3)
    box.attrs["boundary"] = np.array([b"none"] * 3, dtype="S4")
    particles.create_dataset("species", data=np.zeros(pellets, dtype=np.int32)).attrs["description"] = (
        "0 for every pellet: the pellets of a run are identical"
    )
    particles.create_dataset("id", data=np.arange(pellets, dtype=np.int64)).attrs["description"] = "the pellet's row in /pellets"
    position = particles.create_group("position")
    step = position.create_dataset("step", shape=(0,), maxshape=(None,), dtype=np.int64, chunks=(256,))
    time = position.create_dataset("time", shape=(0,), maxshape=(None,), dtype=np.float64, chunks=(256,))
    value = position.create_dataset(
        "value", shape=(0, pellets, 3), maxshape=(None, pellets, 3), dtype=np.float64, chunks=(1, min(pellets, 65536), 3)
    )
    time.attrs.create("unit", "s", dtype=_VL_ASCII)
    value.attrs.create("unit", "m", dtype=_VL_ASCII)
    for ds, unit in ((step, "1"), (time, "s"), (value, "m"), (particles["species"], "1"), (particles["id"], "1")):
        ds.attrs["units"] = unit  # the project's attribute; H5MD's is `unit`
    step.attrs["description"] = "steps of the dense phase"
    time.attrs["description"] = "time since launch"
    value.attrs["description"] = (
        f"pellet centres every {every} steps of the dense phase (pellets whose flight ended: where it ended)"
    )


def append_frame(group, step: int, time: float, positions):
    """One frame: the dense phase's step, its time (s) and every pellet's centre (m)."""
    position = group["particles/pellets/position"]
    k = position["step"].shape[0]
    for name, item in (("step", step), ("time", time)):
        position[name].resize((k + 1,))
        position[name][k] = item
    position["value"].resize((k + 1, *positions.shape))
    position["value"][k] = positions
    group.file.flush()
