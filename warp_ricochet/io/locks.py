"""Process locks (flock) on run files and sweep folders: a second run, resume or sweep of the same
output is refused while one holds it, and the system drops a lock when its process dies."""

from __future__ import annotations

import os

try:
    import fcntl
except ImportError:  # Windows: no process lock (HDF5's own file locking still applies to sweeps)
    fcntl = None


def try_lock(fd: int) -> bool:
    """Take an exclusive lock on the open descriptor `fd` without waiting: False when another
    process holds one (True where there is no flock)."""
    if fcntl is None:
        return True
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False
    return True


def share(fd: int) -> None:
    """Turn the lock held on `fd` into a shared one (SWMR readers take shared locks)."""
    if fcntl is not None:
        fcntl.flock(fd, fcntl.LOCK_SH)


def in_use(path) -> bool:
    """Whether another process holds a lock on `path` (a partial file or a sweep's folder): a run or
    sweep writing it (flock, see `io.runfile`, `io.sweepdir`) or an HDF5 reader."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:
        return not try_lock(fd)
    finally:
        os.close(fd)


def writer_state(meta) -> str:
    """Where the writer a file records (root attributes `writer_pid` on `writer_host`, io.runfile)
    is: "elsewhere" (another host: its lock may not be seen here, NFS/Lustre), "alive" or "dead"
    (a process of this host), "unknown" (not recorded)."""
    import socket

    pid, host = meta.get("writer_pid"), meta.get("writer_host")
    if host is not None and host != socket.gethostname():
        return "elsewhere"
    if pid is None or host is None:
        return "unknown"
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return "dead"
    except (OSError, OverflowError, ValueError):  # (another user's process: alive)
        return "alive"
    return "alive"


def writer_gone(meta, held: bool) -> bool:
    """Whether the writer of a file marked "running" is gone: a live writer holds its lock on the
    file (io.runfile), and where the file names it (`writer_pid` on this `writer_host`) its process
    exists (a reader's lock alone does not keep a dead writer "running")."""
    return not held or writer_state(meta) == "dead"
