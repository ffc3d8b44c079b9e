"""HDF5 output, kept apart from compute (as HOOMD-blue does).

`OutputFile` owns the file: it refuses to replace an existing file unless asked, writes the
root attributes once, and marks the run `status` = "running" / "complete" / "interrupted" /
"failed". It writes to `NAME.partial` beside the target and moves it into place only when the
run is complete (atomically; without overwrite, never over a file that appeared meanwhile), so
the target is never half-written and a failed `--overwrite` run leaves the old result intact;
an interrupted or failed run leaves its completed chunks in `NAME.partial`. `RunWriter` writes one run into a group (the root of a run file, or
`/runs/NNNN` of a sweep file): per-pellet datasets that are chunked, resizable and appended per
chunk, constants written once, statistics at the end. Every dataset has a `units` attribute.
The layout is documented in docs/output.md.

Faults. A run file is written in HDF5 SWMR mode (single writer, multiple readers): every dataset
is created first, then the file only grows, and the library orders its metadata writes so that the
file on disk can be opened at any moment, by a reader while the run writes (`h5py.File(path, "r",
swmr=True)`) or after the writer was killed. After each chunk the rows are written and flushed,
then the chunk's per-segment statistics partials (`/progress/segment_results`), then the count of
complete rows (`/progress/rows`), flushed again: readers and `--resume` trust the rows below that
count. A process lock (flock) on NAME.partial, exclusive while the file is set up and shared
once readers may open it, keeps a second writer or a resume off a file in use.

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

import ctypes
import datetime
import errno
import functools
import os
import re
from pathlib import Path

import h5py
import numpy as np
import warp as wp

from . import __version__
from .errors import OutputError, RicochetError
from .model import FIELD_SPECS, field_numpy_dtype, field_shape
from .stats import STAT_UNITS

try:
    import fcntl
except ImportError:  # Windows: no process lock (HDF5's own file locking still applies to sweeps)
    fcntl = None

FALLOC_FL_KEEP_SIZE, FALLOC_FL_PUNCH_HOLE = 1, 2
ABANDONED = False  # a file could not be closed: the HDF5 library must not run its exit handlers

FORMAT_NAME = "warp-ricochet"
FORMAT_VERSION = 1
MAX_H5_CHUNK_ROWS = 1 << 16
SWMR_FILE = {"libver": ("v110", "latest"), "locking": False}  # run files: SWMR-capable; our flock replaces HDF5's
SWEEP_FILE = {"locking": False}  # sweep files: the earliest format, which a killed writer leaves openable
SPACE_MARGIN = 1 << 20  # bytes kept free beyond a chunk's data: HDF5 metadata and the final close


def check_output_path(path, overwrite: bool) -> Path:
    """Fail early (before any work) if `path` cannot be written; return it as a Path."""
    p, shown = _target(path)
    if p.is_dir():
        raise OutputError(f"{shown}: is a directory")
    if p.exists() and not overwrite:
        raise OutputError(f"{shown}: exists; pass --overwrite (overwrite=True) to replace it")
    partial = p.with_name(p.name + ".partial")
    if partial.exists() and not overwrite:
        raise OutputError(f"{shown}: {partial.name} exists (the chunks of an earlier interrupted run); pass "
                          "--resume (resume=True) to continue that run, --overwrite (overwrite=True) to replace "
                          "it, or move it away")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.exists():
        raise OutputError(f"{shown}: folder {str(parent)!r} does not exist")
    if not parent.is_dir():
        raise OutputError(f"{shown}: {str(parent)!r} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK) or (p.exists() and not os.access(p, os.W_OK)):
        raise OutputError(f"{shown}: not writable (permission denied)")
    return p


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
        if fcntl is None:
            return
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self.release()
            raise OutputError(f"{shown}: {partial.name} is in use by another process (a run writing it, or a "
                              "reader); wait for it to finish or stop it") from None

    def share(self):
        if self.fd is not None and fcntl is not None:
            fcntl.flock(self.fd, fcntl.LOCK_SH)

    def release(self):
        if self.fd is not None:
            os.close(self.fd)  # drops the lock
            self.fd = None


_OPEN: dict[str, "OutputFile"] = {}  # HDF5 file name -> its OutputFile while open (for RunWriter)


class OutputFile:
    """An HDF5 output file; use as a context manager so its status is always recorded."""

    def __init__(self, path, *, overwrite: bool, kind: str, device: str, scene_toml: str, seed=None,
                 precision=None):
        self.path = check_output_path(path, overwrite)
        self.overwrite = overwrite
        self.partial = self.path.with_name(self.path.name + ".partial")
        self.watchable = kind == "run"  # SWMR: a run file can be read while it is written
        self.broken = False
        # a run file is set up as NAME.partial.new and renamed NAME.partial once it is readable (SWMR on):
        # NAME.partial, if it exists, always opens, even after a SIGKILL during the set-up
        self.staging = self.partial.with_name(self.partial.name + ".new") if self.watchable else self.partial
        shown = f"output path = {str(self.path)!r}"
        if self.staging.exists():  # a set-up file of a killed run, or (overwrite) a sweep's earlier partial
            _PartialLock(self.staging, shown).release()  # refused while someone has it open
            os.unlink(self.staging)
        try:  # created, never truncated: ext4 flushes a file truncated to 0 on close (0.3 s per GB)
            self.h5 = h5py.File(self.staging, "w-", **(SWMR_FILE if self.watchable else SWEEP_FILE))
        except FileExistsError:
            raise OutputError(f"{shown}: {self.staging.name} appeared meanwhile (another run?)") from None
        except OSError as exc:
            raise OutputError(f"{shown}: cannot be created ({exc})") from None
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
        attrs["created"] = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
        attrs["scene_toml"] = scene_toml
        attrs["units"] = "SI (m, s, kg, J, rad/s)"
        if seed is not None:
            attrs["seed"] = seed
        if precision is not None:
            attrs["precision"] = precision

    @classmethod
    def reopen(cls, path, *, overwrite: bool, check):
        """The NAME.partial of an interrupted run, reopened to continue it: locked, then `check(f)`
        on it read-only (it raises to refuse; nothing is changed before it passes), then the status
        flags a killed writer left are cleared and it is opened for writing. Returns (file, check's
        result)."""
        from .superblock import clear_status_flags

        self = cls.__new__(cls)
        self.path = check_resume_path(path, overwrite)
        self.overwrite = overwrite
        self.partial = self.staging = self.path.with_name(self.path.name + ".partial")
        self.watchable = True
        self.broken = False
        shown = f"output path = {str(self.path)!r}"
        self._lock = _PartialLock(self.partial, shown)
        try:
            try:
                try:  # swmr: opens even with the flags of a killed writer set
                    f = h5py.File(self.partial, "r", swmr=True, locking=False)
                except OSError:
                    f = h5py.File(self.partial, "r", locking=False)
            except OSError as exc:
                raise OutputError(f"{shown}: {self.partial.name} cannot be resumed: HDF5 cannot open it "
                                  f"({' '.join(str(exc).split())})") from None
            with f:
                try:
                    found = check(f)
                except (KeyError, ValueError, TypeError) as exc:
                    if isinstance(exc, RicochetError):
                        raise
                    raise OutputError(f"{shown}: {self.partial.name} cannot be resumed: it lacks what a run file "
                                      f"holds ({' '.join(str(exc).split())})") from None
            try:
                clear_status_flags(self.partial)
                self.h5 = h5py.File(self.partial, "r+", **SWMR_FILE)
            except (OSError, ValueError) as exc:
                raise OutputError(f"{shown}: {self.partial.name} cannot be reopened for writing "
                                  f"({' '.join(str(exc).split())})") from None
        except BaseException:
            self._lock.release()
            raise
        self._opened("the resumed file", discard=False)
        self.h5.attrs["status"] = "running"
        return self, found

    def _opened(self, what: str, *, discard: bool):
        """Register the open file and reserve the space its closing needs; if there is none, close
        it unchanged (detached) and, for a new file (`discard`), remove it."""
        _OPEN[self.h5.filename] = self
        self._reserved_end = 0
        self._can_reserve = True
        try:
            self.reserve(0, what)
        except OSError:
            _OPEN.pop(self.h5.filename, None)
            self._detach()
            if discard:
                os.unlink(self.staging)
            self._lock.release()
            raise

    def reserve(self, need: int, what: str) -> None:
        """Hold `need` + SPACE_MARGIN bytes of disk beyond the end of the file for its next writes,
        or raise OSError(ENOSPC) naming the file (nothing written). Falls back to a free-space check
        where the file system cannot reserve."""
        total = need + SPACE_MARGIN
        fd, fallocate = self._lock.fd, _fallocate()
        if fd is not None and fallocate is not None and self._can_reserve:
            size = os.fstat(fd).st_size
            if fallocate(fd, FALLOC_FL_KEEP_SIZE, size, total) == 0:
                self._reserved_end = max(self._reserved_end, size + total)
                return
            code = ctypes.get_errno()
            if code in (errno.ENOSPC, errno.EDQUOT):
                free = free_bytes(self.staging)
                raise OSError(errno.ENOSPC, f"No space left on device ({what} needs {_size(total)}"
                                            + (f", {_size(free)} is free)" if free is not None else ")"),
                              str(self.staging))
            self._can_reserve = False  # e.g. EOPNOTSUPP: check instead
        check_space(self.staging, need, what)

    def _release(self):
        """Give back what is still reserved beyond the end of the closed file."""
        fd, fallocate = self._lock.fd, _fallocate()
        if fd is not None and fallocate is not None and self._reserved_end:
            size = os.fstat(fd).st_size
            if self._reserved_end > size:
                fallocate(fd, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, size, self._reserved_end - size)
        self._reserved_end = 0

    def start_watching(self):
        """Every object exists: from now on the file only grows, and readers may open it (SWMR)."""
        self.h5.swmr_mode = True
        self._publish()
        self._lock.share()

    def _publish(self):
        """Rename the file set up as NAME.partial.new to NAME.partial (the lock goes with it)."""
        if self.staging == self.partial:
            return
        shown = f"output path = {str(self.path)!r}"
        if self.overwrite:
            if self.partial.exists():  # an earlier partial: not while someone has it open
                _PartialLock(self.partial, shown).release()
            os.replace(self.staging, self.partial)
        else:
            try:
                os.link(self.staging, self.partial)  # atomic, and never over a file that appeared meanwhile
                os.unlink(self.staging)
            except FileExistsError:
                raise OutputError(f"{shown}: {self.partial.name} appeared during the set-up (another run?)") from None
            except OSError:  # no hard links here
                if self.partial.exists():
                    raise OutputError(f"{shown}: {self.partial.name} appeared during the set-up (another run?)") from None
                os.replace(self.staging, self.partial)
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
                self._detach()
            else:
                try:
                    self.h5.attrs["status"] = status
                    self.h5.close()
                except Exception as close_error:  # the library failed mid-close: keep the first error
                    self._abandon()
                    if exc_type is None:
                        raise OSError(errno.EIO, "the output file could not be closed: "
                                      + " ".join(str(close_error).split()), str(self.staging)) from None
                    return False
            self._release()
            if self.staging != self.partial:  # failed during the set-up: closed now, so it opens
                try:
                    self._publish()
                except OutputError:  # NAME.partial appeared meanwhile: ours holds no chunk
                    os.unlink(self.staging)
            if exc_type is None:
                self._move_into_place()
        finally:
            self._lock.release()
        return False

    def _detach(self):
        """After a failed write, point the file's descriptor at /dev/null and close it: what is on
        disk stays as of the last successful flush (readable, see the module notes), and the library
        neither writes half an update nor crashes at exit trying to flush."""
        try:
            self._blind()
            self.h5.close()
        except Exception:  # noqa: BLE001 - best effort: the first error is what the user sees
            self._abandon()

    def _blind(self):
        fd = self.h5.id.get_vfd_handle()
        null = os.open(os.devnull, os.O_RDWR)
        os.dup2(null, fd)
        os.close(null)

    def _abandon(self):
        """A close that failed leaves the library in a state where closing again, or its exit
        handler, crashes: blind the descriptor (nothing more reaches the disk) and say so, so the
        command line can end without the library's exit handlers (cli.main)."""
        global ABANDONED
        ABANDONED = True
        try:
            self._blind()
        except Exception:  # noqa: BLE001
            pass

    def _move_into_place(self):
        """Rename NAME.partial to NAME with Ctrl-C and SIGTERM held off: never half done."""
        import signal

        held = {signal.SIGINT, signal.SIGTERM}
        can_hold = hasattr(signal, "pthread_sigmask")
        if can_hold:
            signal.pthread_sigmask(signal.SIG_BLOCK, held)
        try:
            self._move()
        finally:
            if can_hold:
                signal.pthread_sigmask(signal.SIG_UNBLOCK, held)

    def _move(self):
        if self.overwrite:
            os.replace(self.partial, self.path)
            return
        try:
            os.link(self.partial, self.path)  # atomic, and fails if the target appeared meanwhile
        except FileExistsError:
            raise OutputError(f"output path = {str(self.path)!r}: appeared during the run; the result is in "
                              f"{str(self.partial)!r}") from None
        except OSError:  # no hard links here: check, then rename
            if self.path.exists():
                raise OutputError(f"output path = {str(self.path)!r}: appeared during the run; the result is in "
                                  f"{str(self.partial)!r}") from None
            os.replace(self.partial, self.path)
            return
        os.unlink(self.partial)


def check_resume_path(path, overwrite: bool) -> Path:
    """Fail early if there is no NAME.partial to continue, or NAME exists without overwrite."""
    p, shown = _target(path)
    if p.exists() and not overwrite:
        raise OutputError(f"{shown}: exists; pass --overwrite (overwrite=True) to replace it with the resumed run")
    partial = p.with_name(p.name + ".partial")
    if not partial.is_file():
        raise OutputError(f"{shown}: nothing to resume: {partial.name} does not exist")
    if not os.access(partial, os.R_OK | os.W_OK) or not os.access(partial.parent, os.W_OK | os.X_OK):
        raise OutputError(f"{shown}: {partial.name} or its folder is not writable (permission denied)")
    if not h5py.is_hdf5(partial):
        raise OutputError(f"{shown}: {partial.name} is not an HDF5 file; it cannot be resumed "
                          "(--overwrite starts the run again)")
    return p


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
        raise OSError(errno.ENOSPC, f"No space left on device ({what} needs {_size(need + SPACE_MARGIN)}, "
                                    f"{_size(free)} is free)", os.fspath(path))


def _size(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.3g} {unit}" if unit != "B" else f"{int(n)} B"
        n /= 1000
    return f"{n:.3g} TB"  # pragma: no cover


def _write_failure(exc: Exception, group) -> Exception:
    """An HDF5 write error as a one-line OSError (errno and reason from the library's text, EIO
    and the library's own words when it names no errno) and the file marked broken (detached when
    closed: a library that failed a write is not asked to write again)."""
    text = " ".join(str(exc).split())
    found = re.search(r"errno = (\d+)", text)
    out = _OPEN.get(group.file.filename)
    if out is not None:
        out.broken = True
    if found is None:
        return OSError(errno.EIO, f"{os.strerror(errno.EIO)} ({text[:200]})", _shown_name(group))
    code = int(found.group(1))
    return OSError(code, os.strerror(code), _shown_name(group))


def _shown_name(group) -> str:
    """The name of the file `group` is in, as the user knows it (NAME.partial, not a set-up name)."""
    out = _OPEN.get(group.file.filename)
    return str(out.staging) if out is not None else group.file.filename


class RunWriter:
    """Writes one run into `group`: constants, per-pellet chunks, statistics, and the progress a
    reader or `--resume` relies on (/progress: the rows complete, the chunk size, the per-segment
    statistics partials of every complete chunk and, in a run with pair collisions, the per-shot
    totals its collision statistics are made of)."""

    def __init__(self, group: h5py.Group, model, *, scene, fields, pellets: int):
        self.group = group
        self.fields = tuple(fields)
        self.rows = 0
        group.attrs["scene_toml"] = scene.to_toml()
        group.attrs["precision"] = model.precision
        if scene.shot.file is None:
            group.attrs["seed"] = scene.shot.seed
        self._write_constants(group.create_group("constants"), model, scene, pellets)
        h5_rows = max(1, min(MAX_H5_CHUNK_ROWS, pellets))  # compute chunks are whole multiples of it
        for name in self.fields:
            _member, kind, per_bounce, unit, doc = FIELD_SPECS[name]
            shape = field_shape(kind, per_bounce, 0, model.bounces)
            ds = group.create_dataset(
                f"pellets/{name.replace('.', '/')}",
                shape=shape,
                maxshape=(None,) + shape[1:],
                chunks=(h5_rows,) + shape[1:],
                dtype=field_numpy_dtype(kind, model.precision),
            )
            ds.attrs["units"] = unit
            ds.attrs["description"] = doc
        self._create_progress(group.create_group("progress"), model, scene)
        for name, (unit, doc) in STAT_UNITS.items():  # written at the end: NaN until then
            ds = group.create_dataset(f"stats/{name}", data=np.nan)
            ds.attrs["units"] = unit
            ds.attrs["description"] = doc
        if scene.pair_collisions and scene.collisions.frame_every:
            self._create_frames(group, pellets, scene.collisions.frame_every)
        self._open_datasets()
        self._start_watching()

    @staticmethod
    def _create_frames(group, pellets: int, every: int):
        """H5MD trajectory frames (https://www.nongnu.org/h5md/): /h5md with its version, and
        particles/pellets/position/{step, time, value}, empty until the dense phase appends."""
        from . import __version__

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

    @property
    def last_frame_step(self):
        """The step of the last trajectory frame appended (None: none yet)."""
        step = self.group["particles/pellets/position/step"]
        return int(step[-1]) if step.shape[0] else None

    def append_frame(self, step: int, time: float, positions):
        """One H5MD frame: the dense phase's step, its time (s) and every pellet's centre (m)."""
        position = self.group["particles/pellets/position"]
        k = position["step"].shape[0]
        for name, item in (("step", step), ("time", time)):
            position[name].resize((k + 1,))
            position[name][k] = item
        position["value"].resize((k + 1, *positions.shape))
        position["value"][k] = positions
        self.group.file.flush()

    @classmethod
    def reopen(cls, group: h5py.Group, *, fields, rows: int, segments: int, shots: int = 0):
        """The writer of a run in an existing file, continuing after `rows` complete rows (and their
        `segments` segment results and, with pair collisions, the totals of their `shots` shots):
        anything written after them is cut off."""
        self = cls.__new__(cls)
        self.group = group
        self.fields = tuple(fields)
        self._open_datasets()
        for ds in self.datasets.values():
            ds.resize(rows, axis=0)
        self.segment_results.resize(segments, axis=0)
        if self.shot_totals is not None:
            self.shot_totals.resize(shots, axis=0)
        self.rows = rows
        self.progress_rows[()] = rows
        group.file.flush()
        self._start_watching()
        return self

    def _open_datasets(self):
        g = self.group
        self.datasets = {name: g[f"pellets/{name.replace('.', '/')}"] for name in self.fields}
        self.progress_rows = g["progress/rows"]
        self.chunk_rows = g["progress/chunk_rows"]
        self.segment_results = g["progress/segment_results"]
        self.shot_totals = g.get("progress/shot_totals")  # runs with pair collisions

    def _start_watching(self):
        out = _OPEN.get(self.group.file.filename)
        if out is not None and out.watchable and self.group.name == "/":
            out.start_watching()

    @staticmethod
    def _create_progress(g, model, scene):
        from .kernels import SEGMENT
        from .stats import NUM_EXTREMES, NUM_SUMS

        g.attrs["description"] = ("rows complete (every /pellets dataset and statistics partial below them is "
                                  "final), the chunk size, and the per-segment statistics partials, in pellet "
                                  "order: what readers of a running run and --resume rely on")
        g.attrs["segment_rows"] = SEGMENT
        g.attrs["device_name"] = model.device.name
        if scene.shot.file is not None:
            st = os.stat(scene.shot.file)
            g.attrs["pellet_file_size"] = st.st_size
            g.attrs["pellet_file_mtime_ns"] = st.st_mtime_ns
        g.create_dataset("rows", data=np.int64(0)).attrs["units"] = "1"
        g.create_dataset("chunk_rows", data=np.int64(0)).attrs["units"] = "1"
        width = NUM_SUMS + 2 * NUM_EXTREMES
        ds = g.create_dataset("segment_results", shape=(0, width), maxshape=(None, width), chunks=(256, width),
                              dtype="f8")
        ds.attrs["units"] = "SI (sums of the quantities of warp_ricochet.stats.SUM_NAMES, then range minima and maxima, m)"
        if scene.pair_collisions:
            from .collisions import SHOT_TOTALS

            ds = g.create_dataset("shot_totals", shape=(0, len(SHOT_TOTALS)), maxshape=(None, len(SHOT_TOTALS)),
                                  chunks=(1024, len(SHOT_TOTALS)), dtype="f8")
            ds.attrs["columns"] = list(SHOT_TOTALS)
            ds.attrs["units"] = "1, 1, J, 1, s, 1 (per shot, in shot order: the columns named in `columns`)"
            ds.attrs["description"] = ("per shot: pellets that collided, pellet-pellet collisions counted by both "
                                       "pellets, energy lost in them, steps and end time of its dense phase")

    @staticmethod
    def _write_constants(g, model, scene, pellets):
        def scalar(name, value, unit, doc):
            ds = g.create_dataset(name, data=value)
            ds.attrs["units"] = unit
            ds.attrs["description"] = doc

        scalar("pellets", pellets, "1", "pellets launched")
        scalar("radius", model.radius, "m", "pellet radius R")
        scalar("mass", model.mass, "kg", "pellet mass m = rho 4/3 pi R^3")
        scalar("inertia", model.inertia, "kg m^2", "moment of inertia 2/5 m R^2 (eq. 17)")
        scalar("gravity", np.asarray(scene.physics.gravity), "m/s^2", "gravity vector")
        scalar("impact_duration", scene.physics.impact_duration, "s", "delta t of eq. (1)")
        scalar("bounces", scene.physics.bounces, "1", "ricochets followed per pellet")
        s = g.create_group("surfaces")
        planes = scene.surfaces
        for name, unit, values in (
            ("point", "m", [p.point for p in planes]),
            ("normal", "1", [p.normal for p in planes]),
            ("restitution", "1", [p.restitution for p in planes]),
            ("mu_s", "1", [p.mu_s for p in planes]),
            ("mu_d", "1", [p.mu_d for p in planes]),
        ):
            arr = np.asarray(values, dtype=np.float64)
            if name in ("point", "normal"):
                arr = arr.reshape(len(planes), 3)
            s.create_dataset(name, data=arr).attrs["units"] = unit

    def append(self, arrays: dict[str, np.ndarray], rows: int, segment_results: np.ndarray, shot_totals=None):
        """Append the first `rows` rows of each field's array, the chunk's segment results and (pair
        collisions) the totals of its shots; flush; then count the rows complete and flush again
        (the commit point of the chunk)."""
        start, stop = self.rows, self.rows + rows
        need = sum(arrays[name][:rows].nbytes for name in self.datasets) + segment_results.nbytes
        need += 0 if shot_totals is None else shot_totals.nbytes
        out = _OPEN.get(self.group.file.filename)
        if out is not None:
            out.reserve(need, "the next chunk")
        else:
            check_space(self.group.file.filename, need, "the next chunk")
        try:
            for name, ds in self.datasets.items():
                ds.resize(stop, axis=0)
                ds[start:stop] = arrays[name][:rows]
            for ds, block in ((self.segment_results, segment_results), (self.shot_totals, shot_totals)):
                if block is not None:
                    done = len(ds)
                    ds.resize(done + len(block), axis=0)
                    ds[done:] = block
            if start == 0:
                self.chunk_rows[()] = rows
            self.group.file.flush()
            self.progress_rows[()] = stop
            self.group.file.flush()
        except (OSError, RuntimeError) as exc:
            raise _write_failure(exc, self.group) from None
        self.rows = stop

    def completed_segment_results(self) -> np.ndarray:
        """The segment results of the rows already complete (a resumed run folds them in first)."""
        return self.segment_results[()]

    def completed_shot_totals(self) -> np.ndarray:
        """The per-shot collision totals of the whole shots already complete (pair collisions)."""
        return self.shot_totals[()]

    def write_stats(self, stats: dict[str, float]):
        try:
            write_stats(self.group, stats)
            self.group.file.flush()
        except (OSError, RuntimeError) as exc:
            raise _write_failure(exc, self.group) from None


_KEY_UNITS = {"diameter": "m", "envelope_radius": "m", "density": "kg/m^3", "speed": "m/s", "impact_duration": "s",
              "direction_jitter": "1", "restitution": "1", "mu_s": "1", "mu_d": "1", "count": "1", "seed": "1",
              "bounces": "1", "chunk_size": "1"}


def unit_of_key(key: str) -> str:
    """The SI unit of a scalar scene key such as "surfaces.0.mu_s" (swept values)."""
    return _KEY_UNITS.get(key.rsplit(".", 1)[-1], "see the scene key")


def write_stats(group: h5py.Group, stats: dict, index=None, size=None):
    """Write statistics under `group/stats`: scalars, or element `index` of arrays of `size`."""
    g = group.require_group("stats")
    for name, value in stats.items():
        unit, doc = STAT_UNITS[name]
        if index is None:
            ds = g.require_dataset(name, shape=(), dtype="f8")  # a run's writer made it (SWMR: no new objects)
            ds[()] = float(value)
        else:
            ds = g.require_dataset(name, shape=(size,), dtype="f8", fillvalue=np.nan)
            ds[index] = float(value)
        if "units" not in ds.attrs:
            ds.attrs["units"] = unit
            ds.attrs["description"] = doc
