"""warp-ricochet: shotgun pellet ricochet (Zohdi 2021) in NVIDIA Warp kernels, SI units throughout."""

__version__ = "0.1.0"

from .errors import OutputError, RicochetError, SceneError  # noqa: E402

__all__ = ["__version__", "RicochetError", "SceneError", "OutputError", "impact", "load_scene", "run", "sweep"]


def __getattr__(name):
    # heavy imports (warp) only when used, so `warp-ricochet --help` and the scene loader start fast
    if name == "impact":
        from .api import impact

        return impact
    if name in ("run", "sweep"):
        from . import api

        return getattr(api, name)
    if name == "load_scene":
        from .scene import load_scene

        return load_scene
    raise AttributeError(name)
