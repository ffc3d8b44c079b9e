"""Public entry points: `impact` (the law on given states), `run` and `sweep` (whole scenes).

`run` streams a scene through the device in chunks: each chunk is one launch of the fused
ricochet kernel and one of the segment reduction; on CUDA the results are copied
asynchronously into pinned host buffers (two, used in turn) while the host writes the previous
chunk to HDF5, so writing overlaps computing. Nothing syncs inside a chunk.
"""

from __future__ import annotations

import contextlib
import math
import threading
import warnings
from dataclasses import dataclass

import numpy as np

from .errors import RicochetError, SceneError
from .kernels import CUDA_BLOCK_DIM, LANES, SEGMENT
from .stats import combine, empty_totals, finalize

HOST_BUFFER_BYTES = 128 << 20  # per pinned host buffer (two are used): caps host memory
DEVICE_FRACTION = 0.5  # of the free device memory a chunk may use
MAX_CHUNK = 1 << 28  # pellets per chunk, statistics-only
CPU_STATS_CHUNK = 1 << 22  # CPU statistics-only chunk: progress granularity


_INIT_NOTE = ""  # what Warp's native library said while starting (e.g. why CUDA is unavailable)
_INITIALISED = False
_CUDA_MISSING = "Could not find or load the NVIDIA CUDA driver"


def _warp():
    import warp as wp

    global _INIT_NOTE, _INITIALISED
    if not _INITIALISED:
        if wp.config.log_level < wp.LOG_WARNING:
            wp.config.log_level = wp.LOG_WARNING  # no banner, no per-module load lines
        _INIT_NOTE = _init_capturing_native_stderr(wp)  # a no-op init if Warp already started
        _INITIALISED = True
    return wp


def _init_capturing_native_stderr(wp) -> str:
    """wp.init(), keeping what the native library writes to stderr (on a machine without a GPU:
    a CUDA-driver warning, which would make a one-line error two lines). Anything else it says
    is passed on; the CUDA note is given with a device error when CUDA was asked for."""
    import ctypes
    import os
    import sys
    import tempfile

    try:
        libc = ctypes.CDLL(None)  # the C library's stdio, to flush its buffered warnings
        saved = os.dup(2)
    except Exception:  # e.g. Windows (no CDLL(None)): let Warp print as it likes
        wp.init()
        return ""
    text = ""
    try:
        with tempfile.TemporaryFile() as captured:
            sys.stderr.flush()
            os.dup2(captured.fileno(), 2)
            try:
                wp.init()
            finally:
                libc.fflush(None)
                os.dup2(saved, 2)
                os.close(saved)
                captured.seek(0)
                text = captured.read().decode(errors="replace").strip()
    finally:
        kept = [line for line in text.splitlines() if _CUDA_MISSING not in line]
        if kept:
            print("\n".join(kept), file=sys.stderr)
    return " ".join(text.split())


def resolve_device(name=None):
    """A Warp device from "cpu", "cuda", "cuda:N" or None (CUDA if present, else CPU)."""
    wp = _warp()
    if name is None:
        return wp.get_preferred_device()
    try:
        if str(name).startswith("cuda") and wp.get_cuda_device_count() == 0:
            raise LookupError  # asking Warp would print native errors first
        return wp.get_device(str(name))
    except Exception:
        allowed = ", ".join(d.alias for d in wp.get_devices())
        why = f" ({_INIT_NOTE.removeprefix('Warp CUDA warning: ')})" if "cuda" in str(name) and _CUDA_MISSING in _INIT_NOTE else ""
        raise RicochetError(f"device = {str(name)!r}: not available here{why}; available: {allowed}") from None


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
    from .impact_law import SOLID_SPHERE_INERTIA_FACTOR
    from .kernels import SCALARS, kernels_for

    if precision not in SCALARS:
        raise SceneError("precision", precision, "must be 'float32' or 'float64'")
    from . import scene as dom

    v = _vectors("velocity", velocity, bound=dom.MAX_SPEED, unit="m/s")
    rows = v.shape[0]
    w = _vectors("angular_velocity", angular_velocity, rows, bound=dom.MAX_SPIN, unit="rad/s")
    n = _vectors("normal", normal, bound=dom.MAX_COORDINATE, single=True)
    if n.shape[0] not in (1, rows):
        raise SceneError("normal", f"array of shape {n.shape}", f"must have shape (3,) or ({rows}, 3)")
    n = n / np.maximum(np.abs(n).max(axis=1), np.finfo(np.float64).tiny)[:, None]  # scale first: no underflow
    lengths = np.linalg.norm(n, axis=1)
    if (lengths == 0).any():
        raise SceneError("normal", "zero vector", "must be non-zero")
    n = n / lengths[:, None]
    radius = _in_range("radius", radius, dom.MIN_DIAMETER / 2, dom.MAX_DIAMETER / 2)
    _in_range("density", density, dom.MIN_DENSITY, dom.MAX_DENSITY)
    restitution = _in_range("restitution", restitution, 0.0, 1.0)
    mu_s = _in_range("mu_s", mu_s, 0.0, dom.MAX_FRICTION)
    mu_d = _in_range("mu_d", mu_d, 0.0, mu_s)
    duration = _in_range("duration", duration, 0.0, dom.MAX_IMPACT_DURATION)
    g = _vectors("gravity", gravity, rows=1, bound=dom.MAX_GRAVITY, unit="m/s^2", single=True)[0]

    wp = _warp()
    dev = resolve_device(device)
    kern = kernels_for(precision)
    vec3, scalar = kern.vec3, kern.scalar
    np_dtype = np.dtype(precision)
    if rows == 0:
        return v.astype(np_dtype), w.astype(np_dtype), np.zeros(0, bool)
    inputs = [
        wp.array(v.astype(np_dtype), dtype=vec3, device=dev),
        wp.array(w.astype(np_dtype), dtype=vec3, device=dev),
        wp.array(n.astype(np_dtype), dtype=vec3, device=dev),
        scalar(radius), scalar(SOLID_SPHERE_INERTIA_FACTOR), scalar(restitution),
        scalar(mu_s), scalar(mu_d), vec3(*g), scalar(duration),
    ]
    outputs = [
        wp.empty(rows, dtype=vec3, device=dev),
        wp.empty(rows, dtype=vec3, device=dev),
        wp.empty(rows, dtype=wp.int8, device=dev),
    ]
    wp.launch(kern.impact_kernel, dim=rows, inputs=inputs, outputs=outputs, device=dev)
    return outputs[0].numpy(), outputs[1].numpy(), outputs[2].numpy().astype(bool)


# --------------------------------------------------------------------------- scenes


@dataclass
class Source:
    """Where launch states come from: the seed, or explicit arrays from a pellet file."""

    count: int
    arrays: dict | None = None  # position, velocity, angular_velocity (float64, (N, 3))

    @classmethod
    def from_scene(cls, scene):
        if scene.shot.file is None:
            return cls(count=scene.shot.pellets)
        from .scene import load_pellet_file

        arrays = load_pellet_file(scene.shot.file)
        return cls(count=len(arrays["position"]), arrays=arrays)


def plan_chunk(scene, model, pellets: int, fields) -> int:
    """Pellets per chunk: a multiple of SEGMENT that fits device and host memory budgets."""
    from .model import State

    if scene.numerics.chunk_size:
        rows = scene.numerics.chunk_size
    else:
        per_pellet_host = State.field_bytes_per_pellet(model.precision, fields, model.bounces)
        per_pellet_device = State.bytes_per_pellet(model.precision, fields, model.bounces)
        if scene.shot.file is not None:
            per_pellet_device += 9 * np.dtype(model.precision).itemsize
        if model.device.is_cuda:
            rows = min(int(DEVICE_FRACTION * model.device.free_memory / per_pellet_device), MAX_CHUNK)
        else:
            rows = CPU_STATS_CHUNK
        if fields:
            rows = min(rows, int(HOST_BUFFER_BYTES / per_pellet_host))
    rows = max(SEGMENT, -(-rows // SEGMENT) * SEGMENT)  # whole segments: chunk-size invariance
    return min(rows, max(pellets, 1))


_PINNED_POOL: dict = {}  # (field, shape, dtype, slot) -> pinned host array, reused: cudaHostAlloc is slow
_PINNED_LOCK = threading.Lock()  # one CUDA run at a time uses the pool


class _HostSlot:
    """One set of host buffers receiving a chunk (pinned on CUDA, so copies run async)."""

    def __init__(self, wp, state, pinned, index):
        def like(arr, name):
            if not pinned:
                return wp.empty(arr.shape, dtype=arr.dtype, device="cpu")
            key = (name, arr.shape, arr.dtype, index)
            if key not in _PINNED_POOL:
                if len(_PINNED_POOL) > 64:
                    _PINNED_POOL.clear()
                _PINNED_POOL[key] = wp.empty(arr.shape, dtype=arr.dtype, device="cpu", pinned=True)
            return _PINNED_POOL[key]

        self.arrays = {name: like(arr, name) for name, arr in state.arrays.items()}
        self.segment_results = like(state.segments, "segments")
        self.rows = 0
        self.segment_count = 0
        self.event = None


def source_struct(scene, model):
    """The kernels' Source struct of a scene's shot: sampling parameters, no explicit arrays."""
    wp = _warp()
    kern = model.kernels
    sh = scene.shot
    src = kern.Source()
    src.seed = sh.seed
    src.speed = kern.scalar(sh.speed)
    src.direction = kern.vec3(*sh.direction)
    src.jitter = kern.vec3(*sh.direction_jitter)
    src.envelope_center = kern.vec3(*sh.envelope_center)
    src.envelope_radius = kern.scalar(sh.envelope_radius)
    src.spin = kern.vec3(*sh.spin)
    src.position = src.velocity = src.angular_velocity = wp.empty(0, dtype=kern.vec3, device=model.device)
    return src


class PrecisionWarning(UserWarning):
    """A result the chosen precision is known not to resolve."""


# measured: docs/collisions.md (mean range 9 to 11% off the float64 reference on the paper's 450-pellet shot) and
# docs/stability.md (E = 0 clouds: release speeds 0.16 apart before the kept events, 0.024 after)
FLOAT32_COLLISIONS = ("pellet-pellet collisions in float32: contact times rounded in float32 change the order of "
                      "events in a dense cloud, and a shot's mean range differs from float64 by about 10% (docs/collisions.md); "
                      "set numerics.precision = \"float64\" for a study")


def run_scene(scene, model, *, writer=None, progress=None, source=None) -> dict:
    """Run every pellet of `scene` through `model`'s device; return the statistics."""
    with _PINNED_LOCK if model.device.is_cuda else contextlib.nullcontext():
        if scene.pair_collisions:  # (one pellet per shot: nothing to meet, the core alone)
            from .collisions import run_collision_scene
            if model.precision == "float32":
                warnings.warn(FLOAT32_COLLISIONS, PrecisionWarning, stacklevel=3)
            return run_collision_scene(scene, model, writer=writer, progress=progress, source=source)
        return _run_scene(scene, model, writer=writer, progress=progress, source=source)


def _run_scene(scene, model, *, writer, progress, source) -> dict:
    from .kernels import ricochet_kernel_for
    from .model import State, threads_for
    from .stats import NUM_EXTREMES, NUM_SUMS

    wp = _warp()
    source = source or Source.from_scene(scene)
    pellets = source.count
    fields = writer.fields if writer is not None else ()
    capacity = plan_chunk(scene, model, pellets, fields)
    state = model.state(capacity, fields) if model.device.is_cuda else State(model, capacity, fields)
    kern = model.kernels
    dev = model.device
    cuda = dev.is_cuda
    slots = [_HostSlot(wp, state, pinned=cuda, index=i) for i in range(2 if cuda else 1)]
    ricochet_kernel = ricochet_kernel_for(model.precision, bool(fields), source.arrays is not None,
                                          model.bounces, len(scene.surfaces),
                                          fast_math=scene.numerics.fast_math and model.precision == "float32")

    src = source_struct(scene, model)
    explicit = None
    if source.arrays is not None:
        explicit = {k: wp.empty(capacity, dtype=kern.vec3, device=dev) for k in ("position", "velocity", "angular_velocity")}
        src.position, src.velocity, src.angular_velocity = (explicit[k] for k in ("position", "velocity", "angular_velocity"))

    totals = empty_totals()
    done = 0
    if writer is not None and writer.rows:  # resuming: the rows written and their statistics partials
        totals = combine(totals, writer.completed_segment_results())
        done = writer.rows

    def consume(slot):
        nonlocal totals, done
        if slot.event is not None:
            wp.synchronize_event(slot.event)
        segment_results = slot.segment_results.numpy()[: slot.segment_count]
        totals = combine(totals, segment_results)
        if writer is not None:
            writer.append({name: arr.numpy() for name, arr in slot.arrays.items()}, slot.rows, segment_results)
        done += slot.rows
        if progress is not None:
            progress(done, pellets)

    pending = None
    for chunk, start in enumerate(range(done, pellets, capacity)):
        rows = min(capacity, pellets - start)
        threads = threads_for(rows)
        segments = threads // LANES
        if explicit is not None:
            dtype = np.dtype(model.precision)
            for key, arr in explicit.items():
                arr[:rows].assign(np.ascontiguousarray(source.arrays[key][start : start + rows], dtype=dtype))
        wp.launch(
            ricochet_kernel,
            dim=threads,
            inputs=[start, rows, src, model.surfaces, model.physics, state.outputs, state.cloud],
            outputs=[state.partial_sums, state.partial_min, state.partial_max],
            device=dev,
            block_dim=CUDA_BLOCK_DIM,
        )
        wp.launch(
            kern.reduce_kernel,
            dim=(segments, NUM_SUMS + NUM_EXTREMES),
            inputs=[state.partial_sums, state.partial_min, state.partial_max],
            outputs=[state.segments],
            device=dev,
        )
        slot = slots[chunk % len(slots)]
        if pending is slot:  # CPU: one slot, consume before reuse
            consume(pending)
            pending = None
        for name, arr in state.arrays.items():  # (element counts: contiguous rows, no views)
            wp.copy(slot.arrays[name], arr, count=rows * (arr.size // arr.shape[0]))
        wp.copy(slot.segment_results, state.segments, count=segments * state.segments.shape[1])
        slot.rows, slot.segment_count = rows, segments
        slot.event = dev.stream.record_event() if cuda else None
        if pending is not None:
            consume(pending)  # host work on the previous chunk while the device runs this one
        pending = slot
    if pending is not None:
        consume(pending)
    return finalize(totals, pellets=pellets, mass=model.mass, inertia=model.inertia)


def host_memory_available():
    """Bytes of host memory still free for a run (Linux MemAvailable, capped by a cgroup limit), or
    None where this cannot be read."""
    import re

    try:
        with open("/proc/meminfo") as f:
            free = int(re.search(r"^MemAvailable:\s+(\d+) kB", f.read(), re.M).group(1)) * 1024
    except (OSError, AttributeError, ValueError):
        return None
    for limit, usage in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                         ("/sys/fs/cgroup/memory/memory.limit_in_bytes", "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        try:
            with open(limit) as a, open(usage) as b:
                free = min(free, int(a.read()) - int(b.read()))
        except (OSError, ValueError):  # no such cgroup file, or "max"
            pass
    return free


def check_chunk_memory(scene, dev, with_output: bool) -> None:
    """An explicit `numerics.chunk_size` must fit in memory: refuse it in one line before any work
    (a chunk of 2e8 pellets with every output field needs 40 GB; the automatic size always fits)."""
    from .model import State

    chunk = scene.numerics.chunk_size
    if not chunk:
        return
    pellets = scene.shot.pellets
    rows = min(max(SEGMENT, -(-chunk // SEGMENT) * SEGMENT), max(pellets, 1))
    fields = scene.output.fields if with_output else ()
    precision, bounces = scene.numerics.precision, scene.physics.bounces
    on_device = State.bytes_per_pellet(precision, fields, bounces)
    if scene.shot.file is not None:
        on_device += 9 * np.dtype(precision).itemsize
    on_host = State.field_bytes_per_pellet(precision, fields, bounces) * (2 if dev.is_cuda else 1)
    if not dev.is_cuda:
        on_host, on_device = on_host + on_device, 0
    host_free = host_memory_available()
    for need, free, where in ((rows * on_device, dev.free_memory if dev.is_cuda else None, f"on {dev.alias}"),
                              (rows * on_host, host_free, "in host memory")):
        if free is not None and need > free:
            fits = int(free / max(need / rows, 1e-9)) // SEGMENT * SEGMENT
            raise SceneError("numerics.chunk_size", chunk,
                             f"a chunk of {rows} pellets needs {need / 2**30:.3g} GiB, {free / 2**30:.3g} GiB is free "
                             f"{where}: give at most {fits} or leave it out (automatic)")


def check_resources(scenes, dev, output, rows_done=0) -> None:
    """Before any work: every explicit chunk size fits in memory, and the output (less `rows_done`
    rows already written, for a resumed run) fits on its disk: else a one-line error, no file made."""
    from .model import State
    from .writer import check_space

    for sc in scenes:
        check_chunk_memory(sc, dev, output is not None)
        if sc.pair_collisions and sc.collisions.frame_every and output is not None:
            from .collisions import plan_shots

            shots = sc.shot.shots  # H5MD frames hold every pellet of the run at each frame
            if plan_shots(sc, dev, shots) < shots:
                raise SceneError("collisions.frame_every", sc.collisions.frame_every,
                                 f"trajectory frames need the whole run in one chunk, and its {shots} shots take "
                                 "more: fewer shots, or numerics.chunk_size, or frame_every = 0")
    if output is not None:
        need = sum((sc.shot.pellets - rows_done) * State.field_bytes_per_pellet(
            sc.numerics.precision, sc.output.fields, sc.physics.bounces) for sc in scenes)
        check_space(output, need, "the output")


def _run_one(scene, device, group=None, progress=None) -> dict:
    """One scene on `device`: statistics, and with `group` (an HDF5 group) its pellets and
    statistics written there."""
    from .model import Model
    from .writer import RunWriter

    model = Model.from_scene(scene, device)
    source = Source.from_scene(scene)
    writer = None if group is None else RunWriter(group, model, scene=scene, fields=scene.output.fields,
                                                  pellets=source.count)
    stats = run_scene(scene, model, writer=writer, progress=progress, source=source)
    if writer is not None:
        writer.write_stats(stats)
    return stats


def run(scene, output=None, device=None, *, overwrite=False, progress=None, resume=False) -> dict:
    """Run a scene (a `Scene` or a TOML path); write HDF5 to `output` (or the scene's
    `output.path`) when given. Returns the statistics (SI units, see `stats.STAT_UNITS`).
    `resume`: continue the interrupted run left in OUTPUT.partial (see `warp_ricochet.resume`)."""
    from .scene import Scene, load_scene
    from .writer import OutputFile, check_output_path

    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    output = output if output is not None else scene.output.path
    if resume:
        from .resume import resume_run
        if scene.pair_collisions and scene.collisions.frame_every:  # see resume.py: frames are not resumed
            raise SceneError("collisions.frame_every", scene.collisions.frame_every,
                             "must be 0 for --resume (H5MD trajectory frames are not resumed); --overwrite "
                             "starts a run with frames again")
        return resume_run(scene, output, device, overwrite=overwrite, progress=progress)
    if output is not None:
        check_output_path(output, overwrite)  # before any work
    dev = resolve_device(device)
    check_resources([scene], dev, output)
    if output is None:
        return _run_one(scene, dev, progress=progress)
    with OutputFile(output, overwrite=overwrite, kind="run", device=str(dev), scene_toml=scene.to_toml(),
                    seed=None if scene.shot.file else scene.shot.seed, precision=scene.numerics.precision) as out:
        return _run_one(scene, dev, out.h5, progress)


def sweep_points(params: dict, ties=()):
    """Cartesian product of parameter values, with tied keys: a list of {key: value} dicts.

    params: {key: [values]}; ties: [(key, factor, source_key or None)].
    """
    import itertools

    keys = list(params)
    points = []
    for combo in itertools.product(*(params[k] for k in keys)):
        point = dict(zip(keys, combo))
        for key, factor, src in ties:
            if src is None:
                if len(keys) != 1:
                    raise SceneError("--tie", key, "must name the parameter it follows (KEY=F*PARAM) when several are swept")
                src = keys[0]
            if src not in point:
                raise SceneError("--tie", f"{key}={factor}*{src}", f"{src} is not a swept parameter")
            point[key] = round(factor * point[src], 12)
        points.append(point)
    return points


def sweep(scene, params: dict, ties=(), output=None, device=None, *, overwrite=False, progress=None) -> list:
    """Run `scene` at every point of a parameter sweep (e.g. the paper's mu_s in 0..0.5 with
    mu_d = 0.9 mu_s). Returns [(point, stats)]. With `output`, writes one HDF5 file: the sweep
    values in /sweep, each run in /runs/NNNN, and every statistic as an array in /stats."""
    from .scene import Scene, load_scene, scene_from_dict, set_dotted
    from .writer import OutputFile, check_output_path, unit_of_key, write_stats

    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    output = output if output is not None else scene.output.path
    points = sweep_points(params, ties)
    scenes = []
    for point in points:  # validate every point before any work
        raw = scene.to_dict()
        for key, value in point.items():
            raw = set_dotted(raw, key, value)
        scenes.append(scene_from_dict(raw))
    if output is not None:
        check_output_path(output, overwrite)
    dev = resolve_device(device)
    check_resources(scenes, dev, output)
    results = []

    def one(i, sc, group=None):
        point_progress = None if progress is None else (lambda d, n: progress(i * n + d, len(scenes) * n))
        return _run_one(sc, dev, group, point_progress)

    if output is None:
        for i, sc in enumerate(scenes):
            results.append((points[i], one(i, sc)))
        return results
    with OutputFile(output, overwrite=overwrite, kind="sweep", device=str(dev), scene_toml=scene.to_toml(),
                    seed=None if scene.shot.file else scene.shot.seed, precision=scene.numerics.precision) as out:
        sw = out.h5.create_group("sweep")
        for key in points[0]:
            ds = sw.create_dataset(key, data=np.array([p[key] for p in points], dtype=np.float64))
            ds.attrs["units"] = unit_of_key(key)
        sw.attrs["parameters"] = list(params)
        sw.attrs["tied"] = [t[0] for t in ties]
        for i, sc in enumerate(scenes):
            stats = one(i, sc, out.h5.create_group(f"runs/{i:04d}"))
            write_stats(out.h5, stats, index=i, size=len(scenes))
            out.h5.flush()
            results.append((points[i], stats))
    return results
