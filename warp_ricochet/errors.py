"""User-facing errors: each one prints as a single line naming the key, the value and what is allowed."""


class RicochetError(Exception):
    """Base class of every error the package reports to a user as one line (no traceback)."""


class SceneError(RicochetError, ValueError):
    """A scene, override or pellet file is invalid. The message names the key, the value and what is allowed."""

    def __init__(self, key: str, value, allowed: str):
        self.key, self.value, self.allowed = key, value, allowed
        super().__init__(f"{key} = {_short(value)}: {allowed}")


class OutputError(RicochetError, OSError):
    """The output path cannot be used (exists without overwrite, unwritable, not HDF5)."""


def _short(value, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


class PrecisionWarning(UserWarning):
    """A result the chosen precision (or a step size) is known not to resolve."""


class ChaosWarning(PrecisionWarning):
    """A result that is one sample of a chaotic process: its figures need an ensemble to judge."""
