"""Continuing an interrupted run (`warp-ricochet run ... --resume`, `warp_ricochet.run(..., resume=True)`).

A run file records, after every chunk, the rows complete (`/progress/rows`), the chunk size
(`/progress/chunk_rows`) and each segment's statistics partials (`/progress/segment_results`: the
per-segment sums, minima and maxima that `tallies.sums.combine` folds in pellet order). To resume, the
partial file is checked against the run asked for (the same scene after overrides, seed included;
the same package and Warp versions; the same device; the same pellet file; a consistent chunk
plan), refused in one line otherwise, and nothing in it is changed before that. Then the rows after
the last complete chunk are cut off, the stored partials are folded in, and the run goes on with
the same chunk size from the first missing chunk. Launch states depend only on (seed, index) and
sums are added strictly in segment order, so the per-pellet datasets and /stats end bitwise equal
to those of an uninterrupted run on the same device.

Runs with pair collisions (`Scene.pair_collisions`) compute chunks of whole shots, each (but the
last) a multiple of `dense.schedule.shot_granule` shots, so every chunk starts on a statistics segment
boundary and a shot's results depend on the shot alone. Such a run also records, per chunk, each
shot's collision totals (`/progress/shot_totals`: collided pellets, pair collisions, energy lost,
dense-phase steps and end time), from which the collision statistics are made with exact sums
(math.fsum) and maxima; a resumed run reads back those of the complete shots, so its /stats are
bitwise those of an uninterrupted run as well. H5MD trajectory frames (`collisions.frame_every`) are
appended during a chunk's dense phase, before the chunk is committed: they are not resumed, and
such a run is refused (start it again with --overwrite).
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass

import warp as wp

from .._version import __version__
from ..bound import BoundPlan, piece_ends, planned
from ..dense.schedule import segments_of_shots, shot_granule
from ..errors import OutputError, SceneError
from ..tallies.by_station import segments_of
from ..tallies.collisions import SHOT_TOTALS
from ..tallies.ensemble import has_ensemble, pieces_per_shot
from ..tallies.reduce import SEGMENT, SEGMENT_WIDTH
from . import station_out, tally_out
from .h5open import file_kind


def _text(value):
    return value.decode() if isinstance(value, bytes) else value


def _flat(node, prefix=""):
    """{dotted key: value} of a TOML document (lists of tables by index)."""
    if isinstance(node, dict):
        items = node.items()
    elif isinstance(node, list) and any(isinstance(x, dict) for x in node):
        items = ((str(i), x) for i, x in enumerate(node))
    else:
        return {prefix: node}
    out = {}
    for key, value in items:
        out.update(_flat(value, f"{prefix}.{key}" if prefix else key))
    return out


def _first_difference(here: dict, there: dict):
    a, b = _flat(here), _flat(there)
    for key in sorted(set(a) | set(b)):
        if a.get(key, "(absent)") != b.get(key, "(absent)"):
            return key, a.get(key, "(absent)"), b.get(key, "(absent)")
    return None


def verify(f, scene, dev, partial_name: str) -> tuple[int, int, int, int]:
    """Check an interrupted run file `f` (open read-only) against the run asked for; return (rows
    complete, chunk size, segments complete, shots complete (pair collisions; else 0)). Raises
    SceneError / OutputError (one line)."""
    attrs = {k: _text(v) for k, v in f.attrs.items()}
    if file_kind(attrs) != "run":
        raise OutputError(
            f"output path = {partial_name!r}: is not a warp-ricochet run file (format = "
            f"{attrs.get('format')!r}, kind = {attrs.get('kind')!r}); it cannot be resumed"
        )
    if "progress" not in f:
        raise OutputError(
            f"output path = {partial_name!r}: holds no resume data (interrupted while it was set up, before any "
            "chunk, or written by an older version); "
            "--overwrite starts the run again"
        )
    for key, here in (("package_version", __version__), ("warp_version", wp.config.version)):
        if attrs.get(key) != here:
            raise SceneError(
                key,
                here,
                f"the interrupted run used {attrs.get(key)!r}; resume needs the same version (for bitwise-identical results)",
            )
    difference = _first_difference(tomllib.loads(scene.to_toml()), tomllib.loads(attrs.get("scene_toml", "")))
    if difference is not None:
        key, here, there = difference
        raise SceneError(key, here, f"the interrupted run had {there!r}; resume needs the same scene, seed and --set overrides")
    progress = f["progress"]
    there = (attrs.get("device"), _text(progress.attrs.get("device_name")))
    if there != (str(dev), dev.name):
        raise SceneError(
            "device",
            str(dev),
            f"the interrupted run ran on {there[0]!r} ({there[1]}); resume on the same device (devices differ in the last bits)",
        )
    if scene.shot.file is not None:
        st = os.stat(scene.shot.file)
        if (st.st_size, st.st_mtime_ns) != (progress.attrs.get("pellet_file_size"), progress.attrs.get("pellet_file_mtime_ns")):
            raise SceneError(
                "shot.file",
                scene.shot.file,
                "changed since the interrupted run (size or modification time); resume needs the same pellets",
            )
    if scene.pair_collisions and (
        "shot_totals" not in progress or list(progress["shot_totals"].attrs.get("columns", [])) != list(SHOT_TOTALS)
    ):
        raise OutputError(
            f"output path = {partial_name!r}: holds no per-shot collision totals (written by an older "
            "version); --overwrite starts the run again"
        )
    results = progress.get("segment_results")
    width = results.shape[-1] if results is not None and results.ndim == 2 else 0
    if width != SEGMENT_WIDTH:
        raise OutputError(
            f"output path = {partial_name!r}: holds statistics partials of another layout ({width} columns "
            f"for {SEGMENT_WIDTH}: written by an older version); --overwrite starts the run again"
        )
    rows, chunk = int(progress["rows"][()]), int(progress["chunk_rows"][()])
    pellets = int(f["constants/pellets"][()])
    bounded = BoundPlan.of(scene)  # (chunks end at its checks too, and segments start there)
    if scene.pair_collisions:  # chunks of whole shots, a multiple of shot_granule shots but the last
        count = scene.shot.count
        shots, unit = rows // count, count * shot_granule(count)
        segments = segments_of_shots(shots, count)
    else:
        shots, unit = 0, SEGMENT
        segments = math.ceil(rows / SEGMENT)
    if bounded is not None:
        segments = bounded.segments(rows, scene.pair_collisions)
    ends = piece_ends(scene) if scene.stations else None
    if scene.stations:  # (chunks end at each piece's end, and segments start there)
        segments = segments_of(ends, rows, scene.shot.count, scene.pair_collisions)
    damaged, budget = None, planned(scene).shot.pellets
    if not 0 <= rows <= pellets:
        damaged = f"{rows} rows complete of {pellets}"
    elif pellets != budget and not _stopped(f, bounded, rows):
        damaged = f"{pellets} pellets in /constants/pellets for a run of {budget}" + (", no bound met there" if bounded else "")
    elif bounded is not None:
        if not bounded.chunk_end(rows, scene.pair_collisions, ends):
            damaged = f"{rows} rows complete, neither a check of its bound nor whole chunks past one"
    elif rows and not scene.stations and (chunk <= 0 or (chunk % unit and chunk < pellets) or (rows % chunk and rows != pellets)):
        damaged = f"chunk plan of {chunk} pellets per chunk with {rows} rows complete"
    elif len(progress["segment_results"]) < segments:
        damaged = f"{len(progress['segment_results'])} segment results for {segments} segments"
    elif shots and len(progress["shot_totals"]) < shots:
        damaged = f"{len(progress['shot_totals'])} per-shot collision totals for {shots} shots"
    else:
        short = [n for n in scene.output.fields if f[f"pellets/{n.replace('.', '/')}"].shape[0] < rows]
        if short:
            damaged = f"pellets/{short[0].replace('.', '/')} is shorter than the {rows} rows complete"
    if damaged:
        raise OutputError(f"output path = {partial_name!r}: is inconsistent ({damaged}); it cannot be resumed")
    return rows, chunk, segments, shots


def _stopped(f, bounded, rows: int) -> bool:
    """Whether bounded run file `f` records that the run met its bound at `rows`, a check: its
    outcome written (`io.bound_out.write`: /constants/pellets and /hazard/bound/pellets the pellets
    run, /hazard/bound/met), then the file closed but not moved into place (killed, or its fields'
    `shards.cut` failed). Resumed, it meets the bound again at once from the counts kept (the
    pipeline's loop), and is finished as it would have been."""
    if bounded is None or rows not in bounded.checks() or "hazard/bound" not in f:
        return False
    b = f["hazard/bound"]
    return int(f["constants/pellets"][()]) == int(b["pellets"][()]) == rows and bool(b["met"][()])


@dataclass
class ResumePlan:
    """What a resumed run continues from: its rows, chunk size, segments and shots complete, and
    the statistics partials (and per-shot totals) of those rows, read from the file."""

    rows: int
    chunk: int
    segments: int
    shots: int
    segment_results: object
    shot_totals: object
    tally: object = None  # the landing counts of the rows complete (`io.tally_out.read_progress`)
    shot_partials: object = None  # per-shot partials of the complete shots (runs of several shots)
    pieces: int = 0
    station_tally: dict | None = None  # station runs: the counts at each complete piece's end


def plan(f, scene, dev, partial_name: str) -> ResumePlan:
    """Check the interrupted run file `f` (open read-only) against `scene` on `dev` (`verify`) and
    read what the run continues from."""
    rows, chunk, segments, shots = verify(f, scene, dev, partial_name)
    progress = f["progress"]
    totals = progress["shot_totals"][:shots] if scene.pair_collisions else None
    tally = tally_out.read_progress(progress, rows)
    if scene.output.quantiles and rows and tally is None:
        raise OutputError(
            f"output path = {partial_name!r}: holds no landing counts for its {rows} rows complete; "
            "it cannot be resumed (--overwrite starts the run again)"
        )
    partials, pieces = None, 0
    if has_ensemble(planned(scene)):
        pieces = rows // scene.shot.count * pieces_per_shot(scene.shot.count)
        if "shot_partials" not in progress or len(progress["shot_partials"]) < pieces:
            raise OutputError(
                f"output path = {partial_name!r}: is inconsistent (per-shot partials of fewer than "
                f"{rows // scene.shot.count} shots); it cannot be resumed"
            )
        partials = progress["shot_partials"][:pieces]
    stations = station_out.read_progress(progress, rows) if scene.stations else None
    return ResumePlan(
        rows, chunk, segments, shots, progress["segment_results"][:segments], totals, tally, partials, pieces, stations
    )
