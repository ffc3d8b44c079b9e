"""Run files on disk: creating, locking, publishing and moving them into place (writers write into them).

`OutputFile` owns the file: it refuses to replace an existing file unless asked, writes the
root attributes once, and marks the run `status` = "running" / "complete" / "interrupted" /
"failed". It writes to `NAME.partial` beside the target and moves it into place only when the
run is complete (atomically; without overwrite, never over a file that appeared meanwhile), so
the target is never half-written and a failed `--overwrite` run leaves the old result intact;
an interrupted or failed run leaves its completed chunks in `NAME.partial`. Once a file is in place
its XDMF sidecar `NAME.xmf` is written (`io.xdmf`; an existing one is replaced only with overwrite,
and refused before any work otherwise; a SIGKILL between the two leaves NAME without it, and
`warp-ricochet xdmf NAME` writes it: written first, it would name a file not yet there, and block a
resume of the complete partial). `io.writer.RunWriter` writes one run into a group of it. The layout is documented in
docs/output.md.

Faults. A run file is written in HDF5 SWMR mode (single writer, multiple readers): every dataset
is created first, then the file only grows, and the library orders its metadata writes so that the
file on disk can be opened at any moment, by a reader while the run writes (`h5py.File(path, "r",
swmr=True)`) or after the writer was killed. After each chunk the rows are written and flushed,
then the chunk's per-segment statistics partials (`/progress/segment_results`), then the count of
complete rows (`/progress/rows`), flushed again: readers and `--resume` trust the rows below that
count. A process lock (flock) on NAME.partial, exclusive while the file is set up (as
NAME.partial.new) and shared before it appears as NAME.partial (a reader's HDF5 takes a shared lock
as it opens it), keeps a second writer or a resume off a file in use.

A full disk: HDF5 does not survive a failed write (the file it leaves can be unreadable, and the
library crashes at exit), so it must never meet one. Before each chunk the file reserves the disk
space the chunk and a margin will take, beyond its end (Linux fallocate, FALLOC_FL_KEEP_SIZE): if
that fails the run stops before writing anything, with a one-line ENOSPC error, and closes the
file cleanly in the space still reserved; other writers filling the disk meanwhile cannot take the
reserved space. Where the file system cannot reserve, the free space is checked instead (a race
with another writer remains). Should the library hit a write error all the same, the file is
detached (its descriptor pointed at /dev/null) before it is closed: the file on disk stays as of its
last flush, which is readable (SWMR), instead of half an update.
"""

from __future__ import annotations

import datetime
import errno
import os
import socket
import warnings
from pathlib import Path

import h5py
import warp as wp

from .. import interrupts
from .._version import __version__
from ..errors import OutputError, RicochetError, hdf5_reason, in_use_error, not_regular
from .h5open import FORMAT_NAME, FORMAT_VERSION, open_for_reading
from .locks import in_use, share, try_lock
from .space import Reservation
from .xdmf import check_sidecar, sidecar_path, write_xdmf

ABANDONED = False  # a file could not be closed: the HDF5 library must not run its exit handlers

SWMR_FILE = {"libver": ("v110", "latest"), "locking": False}  # run files: SWMR-capable; our flock replaces HDF5's
SWEEP_FILE = {"locking": False}  # sweep files: the earliest format, which a killed writer leaves openable


def check_output_path(path, overwrite: bool) -> Path:
    """Fail early (before any work) if `path` cannot be written; return it as a Path."""
    p, shown = _target(path)
    if p.is_dir():
        raise OutputError(f"{shown}: is a directory")
    if why := not_regular(p):  # (a FIFO, a device: never replaced, even with overwrite)
        raise OutputError(f"{shown}: {why}")
    if p.exists() and not overwrite:
        raise OutputError(f"{shown}: exists; give --overwrite (overwrite=True) to replace it")
    if p.is_symlink() and not p.exists() and not overwrite:  # else found only when the run moves into place
        raise OutputError(
            f"{shown}: is a dangling symbolic link (to {os.readlink(p)!r}); remove it, or give "
            "--overwrite (overwrite=True) to replace the link"
        )
    partial = p.with_name(p.name + ".partial")
    if partial.exists():
        if not partial.is_dir() and (why := not_regular(partial)):  # (checking its lock would open it)
            raise OutputError(f"{shown}: {partial.name} {why}; remove it")
        if in_use(partial):
            raise in_use_error(shown, partial.name)
        if not overwrite:
            what = (
                ("the points of an earlier interrupted sweep", "sweep")
                if partial.is_dir()
                else ("the chunks of an earlier interrupted run", "run")
            )
            raise OutputError(
                f"{shown}: {partial.name} exists ({what[0]}); give --resume (resume=True) to continue "
                f"that {what[1]}, --overwrite (overwrite=True) to replace it, or move it away"
            )
    check_sidecar(p, overwrite, shown)
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.exists():
        raise OutputError(f"{shown}: folder {str(parent)!r} does not exist")
    if not parent.is_dir():
        raise OutputError(f"{shown}: {str(parent)!r} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK) or (p.exists() and not os.access(p, os.W_OK)):
        raise OutputError(f"{shown}: not writable (permission denied)")
    return p


def output_target(path) -> Path:
    """An output path as a Path, or a one-line OutputError (not .h5 or .hdf5, a NUL character)."""
    return _target(path)[0]


def _target(path) -> tuple[Path, str]:
    """An output path ending in .h5 or .hdf5, and how messages show it ("output path = '...'")."""
    text = _output_text(path)
    shown = f"output path = {text!r}"
    if Path(text).suffix.lower() not in (".h5", ".hdf5"):
        raise OutputError(f"{shown}: must end in .h5 or .hdf5")
    return Path(text), shown


def _output_text(path) -> str:
    """The output path as text, or a one-line OutputError: a NUL character would cut the name short
    in the C library (and truncate whatever file the shorter name points to)."""
    try:
        text = os.fsdecode(path)
    except TypeError:
        raise OutputError(f"output path = {path!r}: must be a file name (text) ending in .h5 or .hdf5") from None
    if "\0" in text:
        raise OutputError(f"output path = {text!r}: must not contain a NUL character")
    return text


class _PartialLock:
    """A process lock (flock) on NAME.partial: exclusive while the file is set up or checked, shared
    once SWMR readers (which take shared locks as they open it) may come. A second run or a resume
    asking for it exclusively is refused while it is held; the system drops it when the process dies."""

    def __init__(self, partial: Path, shown: str):
        self.fd = None
        try:
            self.fd = os.open(partial, os.O_RDWR)
        except OSError as exc:
            raise OutputError(f"{shown}: {partial.name} cannot be opened ({exc.strerror})") from None
        if not try_lock(self.fd):
            self.release()
            raise in_use_error(shown, partial.name)

    def share(self):
        if self.fd is not None:
            share(self.fd)

    def release(self):
        if self.fd is not None:
            os.close(self.fd)  # drops the lock
            self.fd = None


_OPEN: dict[str, OutputFile] = {}  # HDF5 file name -> its OutputFile while open (for RunWriter)


class OutputFile:
    """An HDF5 output file; use as a context manager so its status is always recorded."""

    def __init__(
        self, path, *, overwrite: bool, kind: str, device: str, scene_toml: str, seed=None, precision=None, sidecar: bool = True
    ):
        self.path = check_output_path(path, overwrite)
        self.overwrite, self.sidecar = overwrite, sidecar
        self.finishing = []  # callables(path) run on the closed file of a complete run, before it moves into place
        self.partial = self.path.with_name(self.path.name + ".partial")
        self.watchable = kind == "run"  # SWMR: a run file can be read while it is written
        self.broken = False
        # a run file is set up as NAME.partial.new and renamed NAME.partial once it is readable (SWMR on):
        # NAME.partial, if it exists, always opens, even after a SIGKILL during the set-up
        self.staging = self.partial.with_name(self.partial.name + ".new") if self.watchable else self.partial
        shown = f"output path = {str(self.path)!r}"
        if self.watchable and self.partial.is_dir():  # never replaced by a run's partial, even with overwrite
            raise OutputError(
                f"{shown}: {self.partial.name} is a sweep's folder (warp-ricochet sweep ... --resume "
                "continues it); remove it, or choose another output path"
            )
        if self.staging.exists():  # a set-up file of a killed run, or (overwrite) a sweep's earlier partial
            _PartialLock(self.staging, shown).release()  # refused while someone has it open
            os.unlink(self.staging)
        try:  # created, never truncated: ext4 flushes a file truncated to 0 on close (0.3 s per GB)
            self.h5 = h5py.File(self.staging, "w-", **(SWMR_FILE if self.watchable else SWEEP_FILE))
        except FileExistsError:
            raise OutputError(f"{shown}: {self.staging.name} appeared meanwhile (another run?)") from None
        except OSError as exc:
            raise OutputError(f"{shown}: {self.staging.name} cannot be created ({hdf5_reason(exc)})") from None
        try:
            self._lock = _PartialLock(self.staging, shown)
        except OutputError:
            self.h5.close()
            raise
        self._opened("the new file", discard=True)
        attrs = self.h5.attrs
        attrs["format"] = FORMAT_NAME
        attrs["format_version"] = FORMAT_VERSION
        attrs["kind"] = kind
        attrs["status"] = "running"
        attrs["package_version"] = __version__
        attrs["warp_version"] = wp.config.version
        attrs["h5py_version"] = h5py.version.version
        attrs["device"] = device
        attrs["created"] = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
        attrs["scene_toml"] = scene_toml
        attrs["units"] = "SI (m, s, kg, J, rad/s)"
        if seed is not None:
            attrs["seed"] = seed
        if precision is not None:
            attrs["precision"] = precision
        if self.watchable:
            _name_writer(attrs)

    @classmethod
    def reopen(cls, path, *, overwrite: bool, check, sidecar: bool = True):
        """The NAME.partial of an interrupted run, reopened to continue it: locked, then `check(f)`
        on it read-only (it raises to refuse; nothing is changed before it passes), then the status
        flags a killed writer left are cleared and it is opened for writing. Returns (file, check's
        result)."""
        from .superblock import clear_status_flags

        self = cls.__new__(cls)
        self.path = check_resume_path(path, overwrite)
        self.overwrite, self.sidecar = overwrite, sidecar
        self.finishing = []
        self.partial = self.staging = self.path.with_name(self.path.name + ".partial")
        self.watchable = True
        self.broken = False
        shown = f"output path = {str(self.path)!r}"
        self._lock = _PartialLock(self.partial, shown)
        try:
            try:
                f = open_for_reading(self.partial, locking=False)  # also with the flags of a killed writer set
            except OSError as exc:
                raise OutputError(
                    f"{shown}: {self.partial.name} cannot be resumed: HDF5 cannot open it "
                    f"({hdf5_reason(exc)}); --overwrite starts the run again"
                ) from None
            with f:
                try:
                    found = check(f)
                except (KeyError, ValueError, TypeError) as exc:
                    if isinstance(exc, RicochetError):
                        raise
                    raise OutputError(
                        f"{shown}: {self.partial.name} cannot be resumed: it lacks what a run file "
                        f"holds ({' '.join(str(exc).split())})"
                    ) from None
            try:
                clear_status_flags(self.partial)
                self.h5 = h5py.File(self.partial, "r+", **SWMR_FILE)
            except (OSError, ValueError) as exc:
                raise OutputError(f"{shown}: {self.partial.name} cannot be reopened for writing ({hdf5_reason(exc)})") from None
        except BaseException:
            self._lock.release()
            raise
        self._opened("the resumed file", discard=False)
        self.h5.attrs["status"] = "running"
        _name_writer(self.h5.attrs)
        return self, found

    def _opened(self, what: str, *, discard: bool):
        """Register the open file and reserve the space its closing needs; if there is none, close
        it unchanged (detached) and, for a new file (`discard`), remove it."""
        _OPEN[self.h5.filename] = self
        self.space = Reservation(self._lock.fd, self.staging)
        try:
            self.reserve(0, what)
        except OSError:
            _OPEN.pop(self.h5.filename, None)
            detach(self.h5)
            if discard:
                os.unlink(self.staging)
            self._lock.release()
            raise

    def reserve(self, need: int, what: str) -> None:
        """Hold `need` bytes (and a margin) of disk for the file's next writes, or OSError(ENOSPC)."""
        self.space.path = self.staging
        self.space.reserve(need, what)

    def start_watching(self):
        """Every object exists: from now on the file only grows, and readers may open it (SWMR)."""
        self.h5.swmr_mode = True
        self._lock.share()  # before the file appears: a reader opening it at once takes a shared lock too
        if self.staging != self.partial:
            publish(self.staging, self.partial, self.overwrite, f"output path = {str(self.path)!r}")
            self.staging = self.partial

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            status = "complete"
        elif issubclass(exc_type, KeyboardInterrupt):
            status = "interrupted"
        else:
            status = "failed"
        if exc is not None:
            exc.partial_path = str(self.partial)  # for the one-line message: where the chunks are
            exc.resumable = self.watchable
        _OPEN.pop(self.h5.filename, None)
        try:
            if self.broken:
                detach(self.h5)
            else:
                try:
                    self.h5.attrs["status"] = status
                    self.h5.close()
                except Exception as close_error:  # the library failed mid-close: keep the first error
                    abandon(self.h5)
                    if exc_type is None:
                        raise OSError(
                            errno.EIO,
                            "the output file could not be closed: " + " ".join(str(close_error).split()),
                            str(self.staging),
                        ) from None
                    return False
            self.space.release()
            if self.staging != self.partial:  # failed during the set-up: closed now, so it opens
                self._lock.share()  # (as in start_watching: a reader may open it the moment it appears)
                try:
                    publish(self.staging, self.partial, self.overwrite, f"output path = {str(self.path)!r}")
                except OutputError:  # NAME.partial appeared meanwhile: ours holds no chunk
                    os.unlink(self.staging)
            if exc_type is None:
                for step in self.finishing:  # (one that fails leaves NAME.partial complete, as closed)
                    step(self.partial)
                move_into_place(self.partial, self.path, self.overwrite)
        finally:
            self._lock.release()
        if exc_type is None and self.sidecar:
            publish_sidecar(self.path, self.overwrite)
        return False


def _name_writer(attrs) -> None:
    """Record the writing process (`writer_pid` on `writer_host`): `report` tells a run still
    writing from one whose writer was killed (io.locks.writer_gone)."""
    attrs["writer_pid"] = os.getpid()
    attrs["writer_host"] = socket.gethostname()


def publish_sidecar(path: Path, overwrite: bool) -> None:
    """Write the XDMF sidecar of a published file (io.xdmf); the result is in place already, so a
    sidecar that cannot be written is a warning naming the command that writes it later."""
    try:
        write_xdmf(path, overwrite=overwrite)
    except (OSError, RicochetError) as exc:
        warnings.warn(
            f"{sidecar_path(path).name} (the XDMF sidecar for ParaView) was not written: "
            f"{' '.join(str(exc).split())}; `warp-ricochet xdmf {path}` writes it",
            stacklevel=2,
        )


def publish(staging: Path, partial: Path, overwrite: bool, shown: str):
    """Rename a file set up as NAME.partial.new to NAME.partial (the lock goes with it): atomically,
    and without overwrite never over a NAME.partial that appeared meanwhile."""
    try:
        _publish(staging, partial, overwrite, shown)
    except FileNotFoundError:  # removed by another process meanwhile
        raise OutputError(f"{shown}: {staging.name} was removed during the set-up (by another process?); run it again") from None


def _publish(staging: Path, partial: Path, overwrite: bool, shown: str):
    if overwrite:
        if partial.exists():  # an earlier partial: not while someone has it open
            _PartialLock(partial, shown).release()
        os.replace(staging, partial)
        return
    try:
        os.link(staging, partial)  # atomic, and never over a file that appeared meanwhile
        os.unlink(staging)
    except FileExistsError:
        raise OutputError(f"{shown}: {partial.name} appeared during the set-up (another run?)") from None
    except OSError:  # no hard links here
        if partial.exists():
            raise OutputError(f"{shown}: {partial.name} appeared during the set-up (another run?)") from None
        os.replace(staging, partial)


def detach(h5):
    """After a failed write, point the file's descriptor at /dev/null and close it: what is on
    disk stays as of the last successful flush (readable, see the module notes), and the library
    neither writes half an update nor crashes at exit trying to flush."""
    try:
        _blind(h5)
        h5.close()
    except Exception:  # noqa: BLE001 - best effort: the first error is what the user sees
        abandon(h5)


def _blind(h5):
    fd = h5.id.get_vfd_handle()
    null = os.open(os.devnull, os.O_RDWR)
    os.dup2(null, fd)
    os.close(null)


def abandon(h5):
    """A close that failed leaves the library in a state where closing again, or its exit
    handler, crashes: blind the descriptor (nothing more reaches the disk) and say so, so the
    command line can end without the library's exit handlers (cli.main)."""
    global ABANDONED
    ABANDONED = True
    try:
        _blind(h5)
    except Exception:  # noqa: BLE001
        pass


def move_into_place(partial: Path, path: Path, overwrite: bool):
    """Rename NAME.partial to NAME with Ctrl-C and SIGTERM held off (`interrupts.held`: recorded,
    acted on after it): never half done. (Blocking the signals in this thread would not do: the
    kernel may deliver one to another thread, and Python then runs its handler here.)"""
    with interrupts.held():
        _move(partial, path, overwrite)


def _move(partial: Path, path: Path, overwrite: bool):
    try:
        _replace(partial, path, overwrite)
    except FileNotFoundError:  # removed by another process while the run wrote it: its rows are gone
        raise OutputError(
            f"output path = {str(path)!r}: {partial.name} was removed during the run (by another "
            "process?); its results are lost: run it again"
        ) from None


def _replace(partial: Path, path: Path, overwrite: bool):
    if overwrite:
        os.replace(partial, path)
        return
    try:
        os.link(partial, path)  # atomic, and fails if the target appeared meanwhile
    except FileExistsError:
        raise OutputError(f"output path = {str(path)!r}: appeared during the run; the result is in {str(partial)!r}") from None
    except OSError:  # no hard links here: check, then rename
        if path.exists():
            raise OutputError(
                f"output path = {str(path)!r}: appeared during the run; the result is in {str(partial)!r}"
            ) from None
        os.replace(partial, path)
        return
    os.unlink(partial)


def check_resume_path(path, overwrite: bool) -> Path:
    """Fail early if there is no NAME.partial to continue, or NAME exists without overwrite."""
    p, shown = _target(path)
    if p.exists() and not overwrite:
        raise OutputError(f"{shown}: exists; give --overwrite (overwrite=True) to replace it with the resumed run")
    check_sidecar(p, overwrite, shown)
    partial = p.with_name(p.name + ".partial")
    if partial.is_dir():
        raise OutputError(f"{shown}: {partial.name} is a sweep's folder; warp-ricochet sweep ... --resume continues it")
    if why := not_regular(partial):
        raise OutputError(f"{shown}: {partial.name} {why}; it cannot be resumed")
    if not partial.is_file():
        raise OutputError(f"{shown}: nothing to resume: {partial.name} does not exist")
    if in_use(partial):
        raise in_use_error(shown, partial.name)
    if not os.access(partial, os.R_OK | os.W_OK) or not os.access(partial.parent, os.W_OK | os.X_OK):
        raise OutputError(f"{shown}: {partial.name} or its folder is not writable (permission denied)")
    if not h5py.is_hdf5(partial):
        raise OutputError(f"{shown}: {partial.name} is not an HDF5 file; it cannot be resumed (--overwrite starts the run again)")
    return p
