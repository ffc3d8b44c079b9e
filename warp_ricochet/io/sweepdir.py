"""A sweep while it runs: the folder NAME.h5.partial/, one run file per point, assembled at the end.

`warp-ricochet sweep ... -o NAME.h5` writes each point as its own run file `NAME.h5.partial/NNNN.h5`
(`io.runfile.OutputFile` and `io.writer.RunWriter`, exactly as `run` writes one: committed chunk by
chunk, a point interrupted or killed leaves `NNNN.h5.partial`, which `--resume` continues). Beside
them `sweep.json` (the manifest) records what the sweep is: the base scene, the swept values, the
ties, the device and the versions. When every point is complete the points are copied into one
sweep file (layout unchanged: /sweep, /stats, /runs/NNNN, docs/output.md), set up as
`NAME.h5.partial/sweep.h5` and moved into place as NAME.h5; then the folder is removed.

`sweep ... --resume` checks the folder against the sweep asked for (the manifest, read-only) and
refuses in one line, changing nothing, when they differ or the folder is in use; then it skips the
points complete, resumes the one interrupted, runs the rest and assembles: the sweep file ends
bitwise equal (every dataset and attribute but `created`) to an uninterrupted sweep's.

A process lock (flock) on the folder, held for the whole sweep, keeps a second sweep or a
`--resume` off a folder in use. This module needs no Warp (`folder_progress` serves `report`).
"""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

from ..errors import OutputError, SceneError, in_use_error
from ..scene.keys import _Shown
from .atomic import replaced
from .locks import try_lock

MANIFEST = "sweep.json"
ASSEMBLY = "sweep.h5"
FOLDER_FORMAT = "warp-ricochet sweep folder"
FOLDER_VERSION = 1
FILE_ATTRIBUTES = (
    "format",
    "format_version",
    "kind",
    "status",
    "package_version",
    "warp_version",
    "h5py_version",
    "device",
    "created",
    "units",
)  # root attributes of a run file that its group in a sweep lacks
_POINT = re.compile(r"^(\d{4,})\.h5$")


def point_name(index: int) -> str:
    """The run file of point `index` in the folder (and its group /runs/NNNN in the sweep file)."""
    return f"{index:04d}"


def folder_of(path: Path) -> Path:
    return path.with_name(path.name + ".partial")


def folder_progress(folder) -> tuple[int, int] | None:
    """(points complete, points) of a sweep folder, or None when `folder` is not one."""
    folder = Path(folder)
    try:
        manifest = json.loads((folder / MANIFEST).read_text())
        points = int(manifest["points"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    done = sum(1 for p in folder.iterdir() if _POINT.match(p.name) and int(p.name[:-3]) < points)
    return done, points


def lock_folder(folder: Path, shown: str) -> int | None:
    """Hold an exclusive process lock on the folder (returns its descriptor), or refuse in one line
    when another process holds it."""
    fd = os.open(folder, os.O_RDONLY)
    if not try_lock(fd):
        os.close(fd)
        raise in_use_error(shown, folder.name)
    return fd


def make_manifest(scene_toml: str, points, dev) -> dict:
    """What identifies a sweep: base scene (after --set), swept values, ties, device, versions."""
    import warp as wp

    from .._version import __version__

    return {
        "format": FOLDER_FORMAT,
        "format_version": FOLDER_VERSION,
        "points": len(points),
        "scene_toml": scene_toml,
        "parameters": dict(zip(points.keys, points.values)),
        "ties": [list(t) for t in points.ties],
        "device": str(dev),
        "device_name": dev.name,
        "package_version": __version__,
        "warp_version": wp.config.version,
    }


def check_resumable(path: Path, overwrite: bool) -> None:
    """Refuse (one line) a sweep file `path` to resume whose folder is missing or a run's partial,
    or whose file or XDMF sidecar exists without `overwrite` (the manifest: `SweepFolder`)."""
    folder, shown = folder_of(path), f"output path = {str(path)!r}"
    if path.exists() and not overwrite:
        raise OutputError(f"{shown}: exists; give --overwrite (overwrite=True) to replace it with the resumed sweep")
    if folder.is_file():
        raise OutputError(
            f"{shown}: {folder.name} is a run's partial file, not a sweep's folder; warp-ricochet run ... --resume continues it"
        )
    if not folder.is_dir():
        raise OutputError(f"{shown}: nothing to resume: {folder.name} does not exist")
    from .xdmf import check_sidecar

    check_sidecar(path, overwrite, shown)  # NAME.xmf is written at the end


class SweepFolder:
    """The folder of a sweep being written, locked while open (`close()` releases it)."""

    def __init__(self, path: Path, manifest: dict, *, resume: bool, overwrite: bool):
        self.path, self.folder = path, folder_of(path)
        self.shown = f"output path = {str(path)!r}"
        self.manifest = json.loads(json.dumps(manifest))  # as it reads back
        self.fd = None
        if resume:
            self._check_resume(overwrite)
        else:
            self._create(overwrite)

    def _check_resume(self, overwrite: bool):
        """Refuse, changing nothing, a folder that is missing, in use or of another sweep."""
        folder, shown = self.folder, self.shown
        check_resumable(self.path, overwrite)
        self.fd = lock_folder(folder, shown)
        try:
            try:
                there = json.loads((folder / MANIFEST).read_text())
            except (OSError, ValueError):
                raise OutputError(
                    f"{shown}: {folder.name} holds no readable {MANIFEST}: it is not a sweep's folder "
                    "and cannot be resumed (--overwrite starts the sweep again)"
                ) from None
            _compare(self.manifest, there, f"{shown}: {folder.name}")
        except BaseException:
            self.close()
            raise

    def _create(self, overwrite: bool):
        """A new folder (an earlier one, or a run's partial, replaced only with `overwrite` and only
        when no process holds it), locked, with its manifest."""
        folder, shown = self.folder, self.shown
        if folder.is_dir():
            fd = lock_folder(folder, shown)
            try:
                shutil.rmtree(folder)
            finally:
                os.close(fd)
        elif folder.exists() or folder.is_symlink():
            from .runfile import _PartialLock  # a run's partial: not while a process holds it

            _PartialLock(folder, shown).release()
            os.unlink(folder)
        try:
            folder.mkdir()
        except FileExistsError:
            raise OutputError(f"{shown}: {folder.name} appeared meanwhile (another sweep?)") from None
        self.fd = lock_folder(folder, shown)
        with replaced(folder / MANIFEST) as tmp:
            Path(tmp).write_text(json.dumps(self.manifest, indent=1))

    def point(self, index: int) -> Path:
        return self.folder / (point_name(index) + ".h5")

    def close(self):
        if self.fd is not None:
            os.close(self.fd)  # drops the lock
            self.fd = None

    def assemble(self, points, stats: list[dict], *, overwrite: bool, device: str, scene_toml: str, seed, precision) -> None:
        """Copy every point's run file into one sweep file, move it into place, remove the folder."""
        import h5py
        import numpy as np

        from .runfile import OutputFile, move_into_place, publish_sidecar
        from .writer import unit_of_key, write_stats_table

        target = self.folder / ASSEMBLY
        with OutputFile(
            target,
            overwrite=True,
            kind="sweep",
            device=device,
            scene_toml=scene_toml,
            seed=seed,
            precision=precision,
            sidecar=False,
        ) as out:
            sw = out.h5.create_group("sweep")
            columns = points.columns
            for key in columns:  # (P,), or (P, 3) for a vector key (shot.envelope_center, surfaces.0.normal)
                values = np.array([p[key] for p in points], dtype=np.float64)
                sw.create_dataset(key, data=values).attrs["units"] = unit_of_key(key)
            sw.attrs["parameters"] = list(points.keys)
            sw.attrs["tied"] = [t[0] for t in points.ties]
            for i in range(len(stats)):
                source = self.point(i)
                out.reserve(os.path.getsize(source), "the sweep file")
                with h5py.File(source, "r") as src:  # the whole root at once: references within it (dimension
                    src.copy(src["/"], out.h5.require_group("runs"), name=point_name(i))  # scales) follow
                group = out.h5[f"runs/{point_name(i)}"]
                _attach_dimensions_again(group)
                for name in FILE_ATTRIBUTES:  # the run file's own, not a run group's (io.runfile.OutputFile)
                    if name in group.attrs:
                        del group.attrs[name]
                out.h5.flush()
            write_stats_table(out.h5, stats)
            point_intervals(out.h5, len(stats))
        move_into_place(target, self.path, overwrite)
        publish_sidecar(self.path, overwrite)
        self.close()
        shutil.rmtree(self.folder, ignore_errors=True)


def point_intervals(h5, points: int) -> None:
    """Each sweep statistic's 95% intervals over shots, one per point, as the array attributes
    `ci_low` and `ci_high` of `/stats/<name>` (from each point's `/runs/NNNN/stats`; NaN where a point
    has none: runs of one shot), with the points' `ci_method`."""
    import numpy as np

    from .ensemble import read_ensemble

    intervals = [read_ensemble(h5[f"runs/{point_name(i)}/stats"]) for i in range(points)]
    for name, ds in h5["stats"].items():
        if not any(name in found for found in intervals):
            continue
        ds.attrs["ci_low"] = np.array([found.get(name, (np.nan, np.nan))[0] for found in intervals])
        ds.attrs["ci_high"] = np.array([found.get(name, (np.nan, np.nan))[1] for found in intervals])
        methods = {h5[f"runs/{point_name(i)}/stats/{name}"].attrs.get("ci_method") for i in range(points)} - {None}
        if len(methods) == 1:
            ds.attrs["ci_method"] = methods.pop()


def resumable_point(partial: Path) -> bool:
    """Whether a point's NNNN.h5.partial can be resumed: it opens and has its /progress (a point
    interrupted while its file was set up has none, and holds no chunk: it is run again)."""
    from .h5open import open_for_reading

    try:
        with open_for_reading(partial, locking=False) as f:
            return "progress/rows" in f
    except OSError:
        return False


def _attach_dimensions_again(group) -> None:
    """HDF5 copies the object references of dimension scales (attributes DIMENSION_LIST and
    REFERENCE_LIST) as they were, addresses in the point's file: drop them and attach the copied
    scales again (io.dimensions), as the writer attached them in the point's file."""
    import h5py

    from .dimensions import name_run_dimensions

    def drop(_name, obj):
        if isinstance(obj, h5py.Dataset):
            for attr in ("DIMENSION_LIST", "REFERENCE_LIST"):
                if attr in obj.attrs:
                    del obj.attrs[attr]

    group.visititems(drop)
    name_run_dimensions(group)


def read_point_stats(path: Path) -> dict:
    """The statistics of a complete point's run file: the scalars of /stats (tallies.sums.STAT_UNITS;
    the landing tallies' groups beside them stay in the file)."""
    import h5py

    from ..tallies.sums import STAT_UNITS

    with h5py.File(path, "r") as f:
        return {
            name: float(ds[()])
            for name, ds in f["stats"].items()
            if name in STAT_UNITS and isinstance(ds, h5py.Dataset) and ds.shape == ()
        }


def _compare(here: dict, there: dict, shown: str) -> None:
    """Refuse (one line) a folder whose manifest differs from the sweep asked for."""
    import tomllib

    from .resume import _first_difference

    if there.get("format") != FOLDER_FORMAT:
        raise OutputError(
            f"{shown} is not a warp-ricochet sweep folder (format = {there.get('format')!r}); it cannot "
            "be resumed (--overwrite starts the sweep again)"
        )
    difference = _first_difference(tomllib.loads(here["scene_toml"]), tomllib.loads(str(there.get("scene_toml", ""))))
    if difference is not None:
        key, mine, theirs = difference
        raise SceneError(
            key, mine, f"the interrupted sweep had {theirs!r}; resume needs the same scene, seed and --set overrides"
        )
    mine, theirs = here["parameters"], there.get("parameters")
    if not isinstance(theirs, dict) or list(mine) != list(theirs):
        raise SceneError(
            "--param", _Shown(", ".join(mine)), f"the interrupted sweep swept {_keys(theirs)}; resume needs the same sweep"
        )
    for key, values in mine.items():
        if values != theirs[key]:
            j = next((j for j, (a, b) in enumerate(zip(values, theirs[key])) if a != b), min(len(values), len(theirs[key])))
            raise SceneError(
                key,
                _Shown(f"{len(values)} values" + (f", value {j} = {values[j]!r}" if j < len(values) else "")),
                f"the interrupted sweep had {len(theirs[key])} values"
                + (f", value {j} = {theirs[key][j]!r}" if j < len(theirs[key]) else "")
                + "; resume needs the same --param values",
            )
    for key, what in (
        ("ties", "--tie"),
        ("device", "device"),
        ("device_name", "device"),
        ("package_version", "package_version"),
        ("warp_version", "warp_version"),
    ):
        if here.get(key) != there.get(key):
            raise SceneError(
                what,
                here.get(key),
                f"the interrupted sweep had {there.get(key)!r}; resume needs the "
                "same sweep (scene, --param, --tie, device and versions)",
            )


def _keys(value) -> str:
    return ", ".join(value) if isinstance(value, dict) and value else repr(value)
