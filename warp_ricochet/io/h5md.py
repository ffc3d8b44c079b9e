"""H5MD trajectory frames of the dense phase (https://www.nongnu.org/h5md/): /h5md with its version,
author and creator, and particles/pellets/position/{step, time, value}."""

import numpy as np

from .._version import __version__


def create_frames(group, pellets: int, every: int):
    """The frame datasets, empty until the dense phase appends (made with the file: SWMR files
    create no objects once readers may open them)."""
    h5md = group.create_group("h5md")
    h5md.attrs["version"] = np.array([1, 1], dtype=np.int32)
    h5md.create_group("author").attrs["name"] = "warp-ricochet"
    creator = h5md.create_group("creator")
    creator.attrs["name"] = "warp-ricochet"
    creator.attrs["version"] = __version__
    position = group.create_group("particles/pellets/position")
    step = position.create_dataset("step", shape=(0,), maxshape=(None,), dtype=np.int64, chunks=(256,))
    time = position.create_dataset("time", shape=(0,), maxshape=(None,), dtype=np.float64, chunks=(256,))
    value = position.create_dataset("value", shape=(0, pellets, 3), maxshape=(None, pellets, 3), dtype=np.float64,
                                    chunks=(1, min(pellets, 65536), 3))
    time.attrs["unit"] = "s"
    value.attrs["unit"] = "m"
    step.attrs["description"] = "steps of the dense phase"
    value.attrs["description"] = (f"pellet centres every {every} steps of the dense phase (pellets whose flight "
                                  "ended: where it ended)")


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
