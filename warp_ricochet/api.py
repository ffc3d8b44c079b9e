"""Public entry points: `impact` (the law on given states), `run` and `sweep` (whole scenes).

`run` checks its inputs and resources before any work, opens the output file (`io.runfile`),
makes the run's writer (`io.writer`) and hands the scene to the chunk loop (`pipeline`), which
returns the statistics; `--resume` continues an interrupted run from the plan `io.resume` reads
out of its file.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import os
import shutil
import time
import warnings
from pathlib import Path

import numpy as np

from . import interrupts
from .bound import BoundPlan, planned
from .chunks import check_chunk_memory, check_tallies, plan_shots
from .core.impact import impact_kernel_for
from .device import resolve_device, warp
from .errors import OutputError, PrecisionWarning, SceneError, SceneWarning, not_regular  # noqa: F401 - PrecisionWarning: part of the API
from .fields import REST_FIELDS, bytes_per_pellet
from .io import resume, sweepdir
from .io.runfile import OutputFile, check_output_path, check_resume_path, output_target
from .io.shards import folder_of as shards_of
from .io.shards import owned as owned_shards
from .io.shards import remove as remove_shards
from .io.space import check_space
from .io.writer import RunWriter
from .model import Model
from .physics.impact import SOLID_SPHERE_INERTIA_FACTOR
from .physics.types import SCALARS, types_for
from .pipeline import Resumed
from .pipeline import run as run_pipeline
from .scene import Scene, SweepPoints, load_pellet_file, load_scene, scene_from_dict, set_dotted
from .scene import schema as domain
from .spec import RunSpec
from .tallies.quantiles import summarize
from .tallies.sums import stat_names

log = logging.getLogger(__name__)  # informational lines (`warp-ricochet -v`)

# --------------------------------------------------------------------------- impact API


def _vectors(name, value, rows=None, bound=None, unit="", single=False):
    """An (N, 3) float64 array (N = rows when given); `single`: a (3,) vector is kept as (1, 3)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise SceneError(name, value, "must be an array of numbers") from None
    if arr.shape == (3,):
        arr = arr[None, :] if single or rows is None else np.broadcast_to(arr, (rows, 3))
    if arr.ndim != 2 or arr.shape[1] != 3 or (rows is not None and arr.shape[0] != rows):
        want = f"({rows}, 3) or (3,)" if rows is not None else "(N, 3)"
        raise SceneError(name, f"array of shape {arr.shape}", f"must have shape {want}")
    if not np.isfinite(arr).all():
        raise SceneError(name, "array with NaN or inf", "must be finite")
    if bound is not None and arr.size and np.abs(arr).max() > bound:
        raise SceneError(name, f"array with {np.abs(arr).max():g}", f"each component must be within +-{bound:g} {unit}")
    return arr


def _in_range(name, value, lo, hi, *, above=False):
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise SceneError(name, value, "must be a number") from None
    if not (math.isfinite(x) and (x > lo if above else x >= lo) and x <= hi):
        raise SceneError(name, value, f"must be a number in {'(' if above else '['}{lo:g}, {hi:g}]")
    return x


def impact(
    velocity,
    angular_velocity,
    normal,
    *,
    radius,
    density,
    restitution,
    mu_s,
    mu_d,
    gravity=(0.0, -9.81, 0.0),
    duration=0.0,
    device=None,
    precision="float32",
):
    """Apply the impact law (Zohdi 2021, eqs. 1-25) to pre-impact states.

    velocity, angular_velocity: (N, 3) arrays in m/s and rad/s; normal: (3,) or (N, 3), the
    plane's normal towards the pellets (normalised here). radius in m, density in kg/m^3,
    gravity in m/s^2, duration (the paper's delta t) in s. A pellet not moving into the plane
    is returned unchanged. Returns (velocity, angular_velocity, slipped) as NumPy arrays:
    float arrays of the requested precision and a bool array.
    """
    if precision not in SCALARS:
        raise SceneError("precision", precision, "must be 'float32' or 'float64'")
    v = _vectors("velocity", velocity, bound=domain.MAX_SPEED, unit="m/s")
    rows = v.shape[0]
    w = _vectors("angular_velocity", angular_velocity, rows, bound=domain.MAX_SPIN, unit="rad/s")
    n = _vectors("normal", normal, bound=domain.MAX_COORDINATE, single=True)
    if n.shape[0] not in (1, rows):
        raise SceneError("normal", f"array of shape {n.shape}", f"must have shape (3,) or ({rows}, 3)")
    n = n / np.maximum(np.abs(n).max(axis=1), np.finfo(np.float64).tiny)[:, None]  # scale first: no underflow
    lengths = np.linalg.norm(n, axis=1)
    if (lengths == 0).any():
        raise SceneError("normal", "zero vector", "must be non-zero")
    n = n / lengths[:, None]
    radius = _in_range("radius", radius, domain.MIN_DIAMETER / 2, domain.MAX_DIAMETER / 2)
    _in_range("density", density, domain.MIN_DENSITY, domain.MAX_DENSITY)
    restitution = _in_range("restitution", restitution, 0.0, 1.0)
    mu_s = _in_range("mu_s", mu_s, 0.0, domain.MAX_FRICTION)
    mu_d = _in_range("mu_d", mu_d, 0.0, mu_s)
    duration = _in_range("duration", duration, 0.0, domain.MAX_IMPACT_DURATION)
    g = _vectors("gravity", gravity, rows=1, bound=domain.MAX_GRAVITY, unit="m/s^2", single=True)[0]

    wp = warp()
    dev = resolve_device(device)
    t = types_for(precision)
    vec3, scalar = t.vec3, t.scalar
    np_dtype = np.dtype(precision)
    if rows == 0:
        return v.astype(np_dtype), w.astype(np_dtype), np.zeros(0, bool)
    inputs = [
        wp.array(v.astype(np_dtype), dtype=vec3, device=dev),
        wp.array(w.astype(np_dtype), dtype=vec3, device=dev),
        wp.array(n.astype(np_dtype), dtype=vec3, device=dev),
        scalar(radius),
        scalar(SOLID_SPHERE_INERTIA_FACTOR),
        scalar(restitution),
        scalar(mu_s),
        scalar(mu_d),
        vec3(*g),
        scalar(duration),
    ]
    outputs = [
        wp.empty(rows, dtype=vec3, device=dev),
        wp.empty(rows, dtype=vec3, device=dev),
        wp.empty(rows, dtype=wp.int8, device=dev),
    ]
    wp.launch(impact_kernel_for(precision), dim=rows, inputs=inputs, outputs=outputs, device=dev)
    return outputs[0].numpy(), outputs[1].numpy(), outputs[2].numpy().astype(bool)


# --------------------------------------------------------------------------- scenes

NO_HITS = (
    "no pellet hit any surface (all {:,} missed): check shot.direction and the surfaces' points and "
    "normals (a plane is hit only from the side its normal points to)"
)


def check_resources(scenes, dev, output, rows_done=0, copies=1) -> None:
    """Before any work: every explicit chunk size fits in memory, and the output (less `rows_done`
    rows already written, for a resumed run; `copies` times: a sweep's points, then the sweep file
    made of them) fits on its disk: else a one-line error (OutputError: bad input, exit status 2),
    no file made. A bounded run is checked as the run of its budget (`bound.planned`)."""
    scenes = [planned(sc) for sc in scenes]
    tallies = 0  # bytes of the tallies' datasets
    for sc in scenes:
        rest = [f for f in sc.output.fields if f in REST_FIELDS]
        if rest and sc.physics.until != "rest":  # (a scene made in code: a loaded one is refused already)
            raise SceneError("output.fields", rest[0], f'needs physics.until = "rest", not {sc.physics.until!r}')
        check_chunk_memory(sc, dev, output is not None)
        tallies += check_tallies(sc, dev, output)
        if sc.pair_collisions and sc.collisions.frame_every and output is not None:
            shots = sc.shot.shots  # H5MD frames hold every pellet of the run at each frame
            if plan_shots(sc, dev, shots) < shots:
                raise SceneError(
                    "collisions.frame_every",
                    sc.collisions.frame_every,
                    f"trajectory frames need the whole run in one chunk, and its {shots} shots take "
                    "more: fewer shots, or numerics.chunk_size, or frame_every = 0",
                )
    if output is not None:
        need = copies * (
            tallies
            + sum(
                (sc.shot.pellets - rows_done) * bytes_per_pellet(sc.output.fields, sc.numerics.precision, sc.physics.bounces)
                for sc in scenes
            )
        )
        try:
            check_space(output, need, "the output")
        except OSError as exc:  # bad input, found before any work (a disk filling during the run: exit 1)
            raise OutputError(f"output path = {os.fsdecode(output)!r}: cannot fit: {exc.strerror}") from None


def _compute(scene, dev, writer=None, progress=None, resumed=None, dense_options=None, study=None, job=None) -> dict:
    """Run `scene` on `dev` through the pipeline, its chunks to `writer` when given; returns the
    statistics (written to the writer too). A bounded run (`bound`) runs as its budget's scene, to
    the first check that meets its bound. `study`: on a cluster's workers (`cluster.Study`), its
    `job` submitted already when given."""
    asked, plan, scene = scene, BoundPlan.of(scene), planned(scene)
    model = Model.from_scene(scene, dev) if study is None else study.model(scene)
    spec = RunSpec.of(scene, with_output=writer is not None, device=dev)
    arrays = load_pellet_file(scene.shot.file) if scene.shot.file is not None else None
    frames = writer.append_frame if writer is not None and spec.collisions and scene.collisions.frame_every else None
    log.info(
        "%s pellets on %s, %s, %s%s%s",
        f"{scene.shot.pellets:,}" if plan is None else f"up to {scene.shot.pellets:,} (until bounded)",
        dev,
        scene.numerics.precision,
        "in air" if scene.in_air else "in vacuum",
        ", pellet-pellet collisions" if spec.collisions else "",
        f", resuming after {resumed.rows:,} rows" if resumed is not None else "",
    )
    start = time.perf_counter()
    if study is not None:
        job = job if job is not None else study.take(asked, resumed.rows if resumed is not None else 0)
        stats = study.fold(job, model, spec, sink=writer, resumed=resumed)
    else:
        stats = run_pipeline(
            scene,
            model,
            spec,
            arrays=arrays,
            sink=writer,
            resumed=resumed,
            progress=progress,
            options=dense_options,
            frames=frames,
            plan=plan,
        )
    seconds = time.perf_counter() - start
    log.info(
        "%s pellets in %.3g s (%.3g pellets/s)",
        f"{int(stats['pellets']):,}",
        seconds,
        stats["pellets"] / seconds if seconds > 0 else math.inf,
    )
    if writer is not None:
        writer.write_stats(stats)
    if stats.bound is not None and not stats.bound.met:
        warnings.warn(stats.bound.summary(), PrecisionWarning, stacklevel=3)
    if stats["hits"] == 0 and stats.get("entered", 0) == 0 and stats["pellets"] > 0 and scene.surfaces:
        warnings.warn(NO_HITS.format(int(stats["pellets"])), SceneWarning, stacklevel=3)
    elif stats["missed"] > 0 and (lost := launched_behind(scene, int(stats["missed"]), int(stats["pellets"]))):
        warnings.warn(lost, SceneWarning, stacklevel=3)
    return stats


def launched_behind(scene, missed: int, pellets: int) -> str | None:
    """The one-line warning for a sampled shot (no shot.file) whose launch envelope, about
    shot.envelope_center or a station's position, reaches behind the ground (the hazard map's
    surface, else the first; an infinite plane): a pellet whose centre starts there never meets it
    and is counted missed, so the statistics are of the others. None otherwise."""
    shot = scene.shot
    index = scene.hazard.map_surface if scene.hazard is not None else 0
    if shot.file is not None or index >= len(scene.surfaces) or scene.surfaces[index].kind not in (None, "plane"):
        return None
    ground = scene.surfaces[index]
    normal = np.asarray(ground.normal, dtype=np.float64)
    centres = [(f"stations.{i}.position", s.position) for i, s in enumerate(scene.stations)]
    heights = [
        (float(np.dot(np.subtract(c, ground.point), normal / np.linalg.norm(normal))), key, c)  # m
        for key, c in centres or [("shot.envelope_center", shot.envelope_center)]
    ]
    height, key, centre = min(heights, key=lambda h: h[0])
    if height - shot.envelope_radius >= 0.0:
        return None
    name = f" ({ground.name!r})" if ground.name else ""
    return (
        f"{key} = {[float(c) for c in centre]}: {missed:,} of {pellets:,} pellets missed "
        f"every surface: the launch envelope (radius {shot.envelope_radius:.4g} m) reaches "
        f"{shot.envelope_radius - height:.4g} m behind surfaces.{index}{name}, and a pellet launched behind a plane never "
        f"meets it; the statistics are of the others (put the envelope's centre at least "
        f"{shot.envelope_radius + shot.diameter / 2:.4g} m in front of the plane)"
    )


def _run_one(scene, dev, group=None, progress=None, dense_options=None, study=None, shards=None) -> dict:
    """One scene on `dev`: statistics, and with `group` (an HDF5 group) its pellets and statistics
    written there; `study`: on a cluster (`cluster.Study`), its per-pellet fields written by the
    tasks to the folder `shards` (`io.shards`)."""
    writer = job = None
    if group is not None:
        work = planned(scene)  # (a bounded run: its budget's layout, the scene asked recorded)
        if shards is not None:  # the tasks' bounds name the shards the file's virtual datasets read
            job = study.take(scene, shards=shards)
            shards = (shards, job["bounds"])
        writer = RunWriter(
            group,
            Model.from_scene(work, dev) if study is None else study.model(work),
            scene=work,
            fields=scene.output.fields,
            pellets=work.shot.pellets,
            stats=stat_names(scene.pair_collisions, scene.in_air, scene.physics.until == "rest"),
            scene_toml=scene.to_toml(),
            shards=shards,
        )
    return _compute(scene, dev, writer, progress, dense_options=dense_options, study=study, job=job)


def _study(client, device, progress, dense_options):
    """A `cluster.Study` on `client` (a `distributed.Client`, or a Study already: a sweep's points)."""
    from .cluster import Study

    return client if isinstance(client, Study) else Study(client, device, progress, dense_options)


@interrupts.honouring
def run(
    scene,
    output=None,
    device=None,
    *,
    overwrite=False,
    progress=None,
    resume=False,
    dense_options=None,
    sidecar=True,
    client=None,
    _shards=None,
) -> dict:
    """Run a scene (a `Scene` or a TOML path); write HDF5 to `output` (or the scene's
    `output.path`) when given. Returns the statistics (SI units, see `tallies.sums.STAT_UNITS`).
    `resume`: continue the interrupted run left in OUTPUT.partial (see `io.resume`).
    `dense_options`: how the CPU runs the dense phase (`dense.phase.DenseOptions`; the results
    are the same for every choice). Ctrl-C raises KeyboardInterrupt at the next safe point
    (`interrupts`), the completed chunks kept in OUTPUT.partial. `sidecar`: write OUTPUT.xmf (XDMF,
    for ParaView) when the run is published (a sweep's points do not: the sweep file gets one).
    `client`: a `distributed.Client`, the run's stretches computed on its workers and folded here,
    bitwise as a serial run on their kind of device (`cluster`, docs/cluster.md). `_shards`: the
    folder of the shards of a sweep's point, readied by `sweep` (default OUT.h5.shards, checked)."""
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    output = output if output is not None else scene.output.path
    check_run(scene, output, overwrite=overwrite, resume=resume, on_cluster=client is not None)  # before any work
    study = None if client is None else _study(client, device, progress, dense_options)
    if study is not None:
        progress = None
    if resume:
        return _resume(
            scene,
            output,
            device,
            overwrite=overwrite,
            progress=progress,
            dense_options=dense_options,
            sidecar=sidecar,
            study=study,
        )
    folder = None if study is None or output is None or not scene.output.fields else _shards or shard_folder(output, overwrite)
    dev = resolve_device(device) if study is None else study.remote
    check_resources([scene], dev, output)
    if folder is not None and _shards is None:  # (--overwrite: the old run's shards; a link, not its target)
        remove_shards(folder)
    if output is None:
        return _run_one(scene, dev, progress=progress, dense_options=dense_options, study=study)
    # --overwrite of a file whose fields were in shards, by a run that writes none there: its shards
    # go once the new file has replaced it (an interrupted or failed run leaves the old file whole)
    stale = owned_shards(output) if overwrite and folder is None else None
    with OutputFile(
        output,
        overwrite=overwrite,
        kind="run",
        device=str(dev),
        scene_toml=scene.to_toml(),
        seed=None if scene.shot.file else scene.shot.seed,
        precision=scene.numerics.precision,
        sidecar=sidecar,
    ) as out:
        stats = _run_one(scene, dev, out.h5, progress, dense_options, study, folder)
    if stale is not None:
        remove_shards(stale)
    return stats


def check_run(scene, output=None, *, overwrite=False, resume=False, on_cluster=False) -> None:
    """`run`'s checks that need no device, each one line before any work (the command line makes
    them before it starts a cluster): what a cluster does not run yet, what --resume needs (an
    interrupted run begun as this one is, on a cluster or not), and the output: the file, its
    .partial, its XDMF sidecar and, for per-pellet fields on a cluster, its shards' folder."""
    if on_cluster:
        from .cluster import refuse

        refuse(scene, output)
    if not resume:
        if output is not None:
            check_output_path(output, overwrite)
            if on_cluster and scene.output.fields:
                shard_folder(output, overwrite)
        return
    if output is None:
        raise SceneError("--resume", "no output", "needs the output file of the interrupted run (-o or output.path)")
    if scene.pair_collisions and scene.collisions.frame_every:  # see io.resume: frames are not resumed
        raise SceneError(
            "collisions.frame_every",
            scene.collisions.frame_every,
            "must be 0 for --resume (H5MD trajectory frames are not resumed); --overwrite starts a run with frames again",
        )
    path = check_resume_path(output, overwrite)
    from .io.h5open import open_for_reading

    try:  # (a partial HDF5 cannot open or that lacks /progress: refused in its line by OutputFile.reopen)
        with open_for_reading(Path(str(path) + ".partial"), locking=False) as f:
            resumed_shards(f, scene, on_cluster)
    except SceneError:
        raise
    except (OSError, KeyError, ValueError, TypeError):
        pass


def _resume(scene, output, device, *, overwrite, progress, dense_options, sidecar=True, study=None) -> dict:
    """Continue the run left in OUTPUT.partial; returns its statistics (as `run`)."""
    if output is None:
        raise SceneError("--resume", "no output", "needs the output file of the interrupted run (-o or output.path)")
    path = check_resume_path(output, overwrite)  # before any work
    dev = resolve_device(device) if study is None else study.remote
    found = {}

    def check(f):
        plan = resume.plan(f, scene, dev, str(path) + ".partial")
        same_chunks = scene  # the same chunk plan as before (the automatic size depends on free memory)
        if plan.chunk and BoundPlan.of(scene) is None:  # (a bounded run's bits do not depend on it: `bound`)
            same_chunks = scene.replace(numerics=dataclasses.replace(scene.numerics, chunk_size=plan.chunk))
        check_resources([same_chunks], dev, output, rows_done=plan.rows)
        found.update(plan=plan, scene=same_chunks, shards=resumed_shards(f, scene, study is not None))

    out, _ = OutputFile.reopen(output, overwrite=overwrite, check=check, sidecar=sidecar)
    with out:
        plan = found["plan"]
        writer = RunWriter.reopen(
            out.h5, fields=scene.output.fields, rows=plan.rows, segments=plan.segments, shots=plan.shots, pieces=plan.pieces
        )
        resumed = Resumed(plan.rows, plan.segment_results, plan.shot_totals, plan.tally, plan.shot_partials, plan.station_tally)
        job = None
        if found["shards"] is not None:  # the tasks left, with the bounds that name their shards
            folder, bounds = found["shards"]
            job = study.take(found["scene"], plan.rows, shards=folder, bounds=[b for b in bounds if b[0] >= plan.rows])
        return _compute(found["scene"], dev, writer, progress, resumed, dense_options, study, job)


def shard_folder(output, overwrite: bool):
    """The shards' folder of a run on a cluster with per-pellet fields (`io.shards`): one there
    already is refused without `overwrite` (one line, before any work)."""
    folder = shards_of(output)
    if not folder.is_dir() and (why := not_regular(folder)):  # (a FIFO, a device: never replaced, as the output)
        raise OutputError(f"output path = {os.fspath(output)!r}: its shards' folder {str(folder)!r} {why}; remove it")
    if (folder.exists() or folder.is_symlink()) and not overwrite:
        raise OutputError(
            f"output path = {os.fspath(output)!r}: its shards' folder {str(folder)!r} exists; --overwrite replaces it"
        )
    return folder


def resumed_shards(f, scene, on_cluster: bool):
    """(folder, [(start, stop)]) of an interrupted run whose fields are in shards, else None; a run
    begun on a cluster with per-pellet fields resumes on one, and only such a run does, and only
    with the shards of its committed rows where they were written (one line)."""
    from .io.shards import BOUNDS, FOLDER, missing

    attrs = f["progress"].attrs
    sharded = BOUNDS in attrs
    if on_cluster and scene.output.fields and not sharded:
        raise SceneError("--resume", "on a cluster", "the run was begun without one (its fields in the file): resume it so")
    if sharded and not on_cluster:
        raise SceneError(
            "--resume", "without a cluster", "the run was begun on one (its fields in shards): give --cluster or --scheduler"
        )
    gone = missing(f, int(f["progress/rows"][()])) if sharded else None
    if gone is not None:  # (its rows would read as fill values in the result: io.shards)
        raise OutputError(
            f"--resume = {gone[1]!r}: a shard of the interrupted run's committed rows is missing (moved or "
            "deleted?); put it back, or --overwrite starts the run again"
        )
    return (str(attrs[FOLDER]), [(int(a), int(b)) for a, b in attrs[BOUNDS]]) if sharded else None


def sweep_points(params: dict, ties=()) -> SweepPoints:
    """The points of a parameter sweep: a lazy sequence of {key: value} dicts (the Cartesian product
    of the values, tied keys set from them), counted first and refused above `MAX_SWEEP_POINTS`.

    params: {key: [values]}; ties: [(key, factor, source_key or None)].
    """
    return SweepPoints(params, ties)


def _point_scenes(scene, points, with_output: bool) -> list:
    """Every point's scene, validated before any work (one line for the first bad point)."""
    base, scenes = scene.to_dict(), []
    for point in points:
        raw = base
        for key, value in point.items():
            raw = set_dotted(raw, key, value)
        sc = scene_from_dict(raw)
        if with_output and sc.pair_collisions and sc.collisions.frame_every:
            raise SceneError(
                "collisions.frame_every",
                sc.collisions.frame_every,
                "must be 0 in a sweep written to a file (H5MD trajectory frames are written by `run`, one run per file)",
            )
        scenes.append(sc)
    return scenes


def sweep(
    scene,
    params: dict,
    ties=(),
    output=None,
    device=None,
    *,
    overwrite=False,
    progress=None,
    dense_options=None,
    resume=False,
    client=None,
) -> list:
    """Run `scene` at every point of a parameter sweep (e.g. the paper's mu_s in 0..0.5 with
    mu_d = 0.9 mu_s). Returns [(point, stats)]. With `output`, writes one HDF5 file: the sweep
    values in /sweep, each run in /runs/NNNN, and every statistic as an array in /stats; while it
    runs, each point is a run file in OUTPUT.partial/ (`io.sweepdir`), and `resume` continues a
    sweep interrupted or killed there. No point keeps its landing counts (`.tally`, megabytes a
    point) once it is done, so a sweep's memory stays flat (bench/sweep_memory.py): with `output`
    the file holds them and their results; without, each point's `stats.summary` holds their
    results (`tallies.quantiles.summarize`, arrays as lists) but the map's, which only a sweep file
    keeps. `client`: a `distributed.Client`, every point's stretches submitted at once to its
    workers (`run`'s `client`), one progress for the whole sweep; per-pellet fields then go to
    shards, OUT.h5.shards/NNNN/ a point's, that its /runs/NNNN reads as virtual datasets."""
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    output = output if output is not None else scene.output.path
    points, scenes = check_sweep(scene, params, ties, output, overwrite=overwrite, resume=resume, on_cluster=client is not None)
    study = None if client is None else _study(client, device, progress, dense_options)
    progress = progress if study is None else None
    if output is None:
        dev = resolve_device(device) if study is None else study.remote
        check_resources(scenes, dev, None)
        for sc in scenes if study is not None else ():
            study.submit(sc, ahead=True)
        results = []
        for i, sc in enumerate(scenes):
            with _point_warnings(i, points[i]):
                stats = _run_one(sc, dev, None, _point_progress(progress, i, len(scenes)), dense_options, study)
            results.append((points[i], _point_done(stats, summary=True)))
        return results
    path = output_target(output)  # (checked by check_sweep)
    dev = resolve_device(device) if study is None else study.remote
    manifest = sweepdir.make_manifest(scene.to_toml(), points, dev)
    # on a cluster, per-pellet fields in shards: OUT.h5.shards/NNNN/ a point's, named by absolute path
    # in the virtual datasets of its run file, and so of /runs/NNNN in the sweep file (`io.shards`)
    sharded = study is not None and any(sc.output.fields for sc in scenes)
    if resume:
        folder = sweepdir.SweepFolder(path, manifest, resume=True, overwrite=overwrite)  # refuses, changing nothing
        with _sweep_kept(folder, close=False):
            check_resources([sc for i, sc in enumerate(scenes) if not folder.point(i).exists()], dev, output, copies=2)
        shards, stale = shards_of(path) if sharded else None, None
    else:
        check_resources(scenes, dev, output, copies=2)
        shards = shard_folder(path, overwrite) if sharded else None  # (one there refused without --overwrite)
        stale = owned_shards(path) if overwrite and not sharded else None  # (as `run`'s: removed once replaced)
        folder = sweepdir.SweepFolder(path, manifest, resume=False, overwrite=overwrite)
        if shards is not None:  # (--overwrite: the old sweep's shards; a link, not its target)
            remove_shards(shards)
    with _sweep_kept(folder):
        results = []
        for i, sc in enumerate(scenes if study is not None else ()):  # every point not begun, submitted at once
            point_shards = None if shards is None else shards / sweepdir.point_name(i)
            if _begun(folder, i):
                continue
            if point_shards is not None and point_shards.exists():  # an interrupted sweep's, its point not begun
                shutil.rmtree(point_shards)
            if not Path(str(folder.point(i)) + ".partial").exists():
                study.submit(sc, ahead=True, shards=point_shards)
        for i, sc in enumerate(scenes):
            point_path, step = folder.point(i), _point_progress(progress, i, len(scenes))
            partial = Path(str(point_path) + ".partial")
            if point_path.exists():  # complete before an interruption
                stats = sweepdir.read_point_stats(point_path)
            else:
                if partial.exists() and not sweepdir.resumable_point(partial):  # no chunk in it: run it again
                    partial.unlink()
                with _point_warnings(i, points[i]):
                    stats = run(
                        sc,
                        point_path,
                        dev,
                        progress=step,
                        dense_options=dense_options,
                        resume=partial.exists(),
                        sidecar=False,
                        client=study,
                        _shards=None if shards is None else shards / sweepdir.point_name(i),
                    )
                stats = _point_done(stats, summary=False)
            results.append((points[i], stats))
        folder.assemble(
            points,
            [s for _, s in results],
            overwrite=overwrite,
            device=str(dev),
            scene_toml=scene.to_toml(),
            seed=None if scene.shot.file else scene.shot.seed,
            precision=scene.numerics.precision,
        )
    if stale is not None:
        remove_shards(stale)
    return results


def check_sweep(scene, params: dict, ties=(), output=None, *, overwrite=False, resume=False, on_cluster=False):
    """`sweep`'s checks that need no device, as `check_run`'s: the points and every point's scene,
    what a cluster does not run yet, and the output (the file, its folder to resume or replace,
    its XDMF sidecar and, for per-pellet fields on a cluster, its shards' folder). Returns
    (points, their scenes)."""
    points = sweep_points(params, ties)
    if resume and output is None:
        raise SceneError("--resume", "no output", "needs the output file of the interrupted sweep (-o or output.path)")
    scenes = _point_scenes(scene, points, output is not None)
    if output is not None:
        _numbers_only(points)
    if on_cluster:
        from .cluster import refuse

        for sc in scenes:
            refuse(sc, output)
    if output is not None and resume:
        path = output_target(output)
        sweepdir.check_resumable(path, overwrite)
        _check_partials(sweepdir.folder_of(path), scenes, on_cluster)
    elif output is not None:
        path = check_output_path(output, overwrite)
        if on_cluster and any(sc.output.fields for sc in scenes):
            shard_folder(path, overwrite)
    return points, scenes


def _begun(folder, index: int) -> bool:
    """Whether point `index` of a sweep's folder is complete, or resumable (`sweepdir.resumable_point`)."""
    partial = Path(str(folder.point(index)) + ".partial")
    return folder.point(index).exists() or partial.exists() and sweepdir.resumable_point(partial)


def _check_partials(folder: Path, scenes, on_cluster: bool) -> None:
    """Before any work: every interrupted point in a sweep's `folder` resumes as it was begun, on a
    cluster or not, when its fields are in shards or in its file (`resumed_shards`, one line); on a
    cluster, every complete point kept has its shards where they were written."""
    from .io.h5open import open_for_reading
    from .io.shards import missing

    for i, sc in enumerate(scenes):
        point = folder / (sweepdir.point_name(i) + ".h5")
        partial = Path(str(point) + ".partial")
        if on_cluster and point.is_file():
            with open_for_reading(point, locking=False) as f:
                gone = missing(f, sc.shot.pellets)
            if gone is not None:  # (the sweep file would read its rows as fill values: io.shards)
                raise OutputError(
                    f"--resume = {gone[1]!r}: a shard of the interrupted sweep's complete point {i} is missing "
                    "(moved or deleted?); put it back, or --overwrite starts the sweep again"
                )
        elif not point.exists() and partial.exists() and sweepdir.resumable_point(partial):
            with open_for_reading(partial, locking=False) as f:
                resumed_shards(f, sc, on_cluster)


def _numbers_only(points) -> None:
    """A sweep file's /sweep holds numbers, or vectors of 3 (docs/output.md): any other value
    (physics.until = "rest") is refused before any work."""
    for key, values in zip(points.keys, points.values):
        for v in values:
            if not (_is_number(v) or isinstance(v, (list, tuple)) and len(v) == 3 and all(map(_is_number, v))):
                raise SceneError(key, v, "a sweep written to a file takes numbers or vectors of 3 numbers (its /sweep)")


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _point_done(stats, summary: bool):
    """A sweep point's statistics, its landing counts dropped (the hazard's histograms: 0.5 MB a row),
    with `summary` their results first kept in `stats.summary`, less the map (a sweep file's only),
    as lists of Python numbers: NumPy's small arrays, kept, would pin pages of the heap that the
    summary's temporaries of megabytes leave, and the heap would grow a point at a time."""
    tally, stats.tally = stats.tally, None
    if summary and tally is not None:
        results = summarize(tally, int(stats["landed"]), with_map=False)
        stats.summary = _plain(results)
    return stats


def _plain(value):
    """`value` with its arrays as (nested) lists of Python numbers, in dicts and tuples."""
    if isinstance(value, dict):
        return {key: _plain(v) for key, v in value.items()}
    if isinstance(value, tuple):
        return tuple(_plain(v) for v in value)
    return value.tolist() if isinstance(value, np.ndarray) else value


@contextlib.contextmanager
def _point_warnings(index: int, point: dict):
    """The warnings of a sweep's point (a NOT BOUNDED budget, a precision warning) issued again with
    the point named, `sweep point 1 (air.density = 1.3): ...`: a sweep's are otherwise alike."""
    caught = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            yield
    finally:  # (also those of a point that failed or was interrupted)
        shown = ", ".join(f"{key} = {value}" for key, value in point.items())
        for w in caught:
            warnings.warn_explicit(f"sweep point {index} ({shown}): {w.message}", w.category, w.filename, w.lineno)


def _point_progress(progress, index: int, points: int):
    """progress(done, total) of point `index` as a part of the whole sweep."""
    return None if progress is None else (lambda d, n: progress(index * n + d, points * n))


@contextlib.contextmanager
def _sweep_kept(folder, close=True):
    """The one place a sweep meets an interruption or a failure: the folder's lock is released (at
    the end too, with `close`), and the one-line message names the folder and `sweep ... --resume`
    (cli._kept)."""
    try:
        yield
    except BaseException as exc:
        folder.close()
        exc.partial_path = str(folder.folder)
        exc.resumable = True
        exc.resume_command = "sweep"
        raise
    if close:
        folder.close()
