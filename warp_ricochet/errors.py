"""User-facing errors: each one prints as a single line naming the key, the value and what is allowed."""

import os
import re
import stat


class RicochetError(Exception):
    """Base class of every error the package reports to a user as one line (no traceback)."""


class SceneError(RicochetError, ValueError):
    """A scene, override or pellet file is invalid. The message names the key, the value and what is allowed."""

    def __init__(self, key: str, value, allowed: str):
        self.key, self.value, self.allowed = key, value, allowed
        super().__init__(shorten(f"{shorten(str(key), MAX_KEY)} = {_short(value)}: {allowed}", MAX_MESSAGE))


class OutputError(RicochetError, OSError):
    """The output path cannot be used (exists without overwrite, unwritable, not HDF5)."""


def in_use_error(shown: str, name: str) -> OutputError:
    """A partial file or sweep folder another process holds (a run or sweep writing it, a reader)."""
    return OutputError(
        f"{shown}: {name} is in use by another process (a run or sweep writing it, or a reader); wait for it to finish or stop it"
    )


MAX_KEY = 200  # characters of a key shown in a message (a 100,000-character unknown key is not echoed whole)
MAX_MESSAGE = 2000  # characters of a whole one-line message


def shorten(text: str, limit: int) -> str:
    """`text`, cut to `limit` characters (ending in "...") when longer."""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _short(value, limit: int = 60) -> str:
    return shorten(repr(value), limit)


_SPECIAL = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
)


def not_regular(path) -> str | None:
    """Why `path` cannot be read or written as a file when it exists but is no regular file ("is a
    FIFO (named pipe), not a regular file"), found by os.stat (following links) without opening it:
    opening a FIFO waits for a writer, a device may never end. None for a regular file or a path
    that cannot be looked at (the caller's own open reports that)."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, TypeError, ValueError):
        return None
    if stat.S_ISREG(mode):
        return None
    what = next((name for test, name in _SPECIAL if test(mode)), "a special file")
    return f"is {what}, not a regular file"


def hdf5_reason(exc: Exception) -> str:
    """The reason in an HDF5 (h5py) error as plain words ("Permission denied", "file signature not
    found"), without the library's call chain, flags and descriptors."""
    text = " ".join(str(exc).split())
    found = re.search(r"error message = '([^']*)'", text)
    if found:
        return found.group(1)
    found = re.search(r"errno = (\d+)", text)
    if found:
        return os.strerror(int(found.group(1)))
    found = re.search(r"\(([^()]*)\)$", text)  # "Unable to synchronously open file (file signature not found)"
    if found:
        return found.group(1)
    return shorten(re.sub(r"^\[Errno -?\d+\] ", "", text), MAX_KEY) or type(exc).__name__


class SceneWarning(UserWarning):
    """A valid scene that very likely does not do what was meant (no pellet hits anything)."""


class PrecisionWarning(UserWarning):
    """A result the chosen precision (or a step size) is known not to resolve."""


class ChaosWarning(PrecisionWarning):
    """A result that is one sample of a chaotic process: its figures need an ensemble to judge."""
