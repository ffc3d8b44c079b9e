"""warp-ricochet: shotgun pellet ricochet (Zohdi 2021) in NVIDIA Warp kernels, SI units throughout.

The pipeline, one folder or module a stage: `scene` (TOML into validated dataclasses) ->
`launch` (launch states) -> `physics` (the laws: impact, pair, flight) -> `core` (the fused
kernel: flight, impact, landing) and `dense` (pellet-pellet collisions) -> `tallies`
(statistics) -> `io` (HDF5 run files, resume, H5MD, `open_run`: lazy xarray reading) -> `report` (tables). `pipeline` owns the
chunk loop, `spec` what a run compiles, `fields` the output fields; `api` and `cli` are the doors.
"""

from ._version import __version__
from .errors import OutputError, PrecisionWarning, RicochetError, SceneError, SceneWarning

__all__ = [
    "__version__",
    "RicochetError",
    "SceneError",
    "OutputError",
    "PrecisionWarning",
    "SceneWarning",
    "STAT_UNITS",
    "impact",
    "load_scene",
    "open_run",
    "run",
    "sweep",
]


def __getattr__(name):
    # heavy imports (warp) only when used, so `warp-ricochet --help` and the scene loader start fast
    if name in ("impact", "run", "sweep"):
        from . import api

        return getattr(api, name)
    if name == "open_run":  # xarray and dask: the optional extra warp-ricochet[xarray]
        from .io.reader import open_run

        return open_run
    if name == "STAT_UNITS":  # name -> (unit, description) of every statistic a run returns (SI units)
        from .tallies.sums import STAT_UNITS

        return STAT_UNITS
    if name == "load_scene":
        from .scene import load_scene

        return load_scene
    raise AttributeError(name)
