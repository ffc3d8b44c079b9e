"""Host memory free for a run (`host_memory_available`), and disk space for HDF5 writes: a full
disk must never meet the HDF5 library (the file a failed write leaves can be unreadable, and the
library crashes at exit), so the space a chunk will take is reserved before it is written (Linux
fallocate, FALLOC_FL_KEEP_SIZE: other writers filling the disk meanwhile cannot take it), or,
where the file system cannot reserve, checked.
"""

from __future__ import annotations

import ctypes
import errno
import functools
import os
import re

FALLOC_FL_KEEP_SIZE, FALLOC_FL_PUNCH_HOLE = 1, 2
SPACE_MARGIN = 1 << 20  # bytes kept free beyond a chunk's data: HDF5 metadata and the final close


class Reservation:
    """Disk space held beyond the end of the file open at descriptor `fd` (None: checks only)."""

    def __init__(self, fd, path):
        self.fd, self.path = fd, path
        self.reserved_end = 0
        self.can_reserve = True

    def reserve(self, need: int, what: str) -> None:
        """Hold `need` + SPACE_MARGIN bytes beyond the end of the file for its next writes, or raise
        OSError(ENOSPC) naming the file (nothing written). Falls back to a free-space check where
        the file system cannot reserve."""
        total = need + SPACE_MARGIN
        fallocate = _fallocate()
        if self.fd is not None and fallocate is not None and self.can_reserve:
            size = os.fstat(self.fd).st_size
            if fallocate(self.fd, FALLOC_FL_KEEP_SIZE, size, total) == 0:
                self.reserved_end = max(self.reserved_end, size + total)
                return
            code = ctypes.get_errno()
            if code in (errno.ENOSPC, errno.EDQUOT):
                free = free_bytes(self.path)
                raise OSError(
                    errno.ENOSPC,
                    f"No space left on device ({what} needs {size_text(total)}"
                    + (f", {size_text(free)} is free)" if free is not None else ")"),
                    str(self.path),
                )
            self.can_reserve = False  # e.g. EOPNOTSUPP: check instead
        check_space(self.path, need, what)

    def release(self):
        """Give back what is still reserved beyond the end of the closed file."""
        fallocate = _fallocate()
        if self.fd is not None and fallocate is not None and self.reserved_end:
            size = os.fstat(self.fd).st_size
            if self.reserved_end > size:
                fallocate(self.fd, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, size, self.reserved_end - size)
        self.reserved_end = 0


@functools.cache
def _fallocate():
    """libc's fallocate(fd, mode, offset, length) (Linux), or None."""
    try:
        f = ctypes.CDLL(None, use_errno=True).fallocate
    except (OSError, AttributeError, TypeError):
        return None
    f.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int64, ctypes.c_int64]
    f.restype = ctypes.c_int
    return f


def free_bytes(path) -> int | None:
    """Bytes free for an unprivileged writer on the file system holding `path`, or None if unknown."""
    try:
        st = os.statvfs(os.path.dirname(os.path.abspath(path)))
    except (OSError, AttributeError):
        return None
    return st.f_bavail * st.f_frsize


def check_space(path, need: int, what: str) -> None:
    """OSError(ENOSPC) naming the file if fewer than `need` (+ a margin) bytes are free next to it."""
    free = free_bytes(path)
    if free is not None and need + SPACE_MARGIN > free:
        raise OSError(
            errno.ENOSPC,
            f"No space left on device ({what} needs {size_text(need + SPACE_MARGIN)}, {size_text(free)} is free)",
            os.fspath(path),
        )


def size_text(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.3g} {unit}" if unit != "B" else f"{int(n)} B"
        n /= 1000
    return f"{n:.3g} TB"  # pragma: no cover


def host_memory_available():
    """Bytes of host memory still free for a run (Linux MemAvailable, capped by a cgroup limit), or
    None where this cannot be read."""
    try:
        with open("/proc/meminfo") as f:
            free = int(re.search(r"^MemAvailable:\s+(\d+) kB", f.read(), re.M).group(1)) * 1024
    except (OSError, AttributeError, ValueError):
        return None
    for limit, usage in (
        ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
        ("/sys/fs/cgroup/memory/memory.limit_in_bytes", "/sys/fs/cgroup/memory/memory.usage_in_bytes"),
    ):
        try:
            with open(limit) as a, open(usage) as b:
                free = min(free, int(a.read()) - int(b.read()))
        except (OSError, ValueError):  # no such cgroup file, or "max"
            pass
    return free
