"""Scene builders and run-file checks shared by the tests."""

import contextlib
import fcntl
import hashlib
import io
import math
import os
import time
from pathlib import Path

import h5py
import numpy as np
import pytest


def busy_lattice(path):
    """A pellet file (npz): 20 pellets 10 cm apart fired as the paper's at the ground plane y = 0
    with topspin (none meets another) and, below the ground (never meeting it), a slow pair that
    meets 97 ms later: it keeps a collision run's shot in the dense phase, which leaps past its
    arrival window in air while the 20 fly on (tests/test_air_leaps.py). Returns the scene's
    tables of it in air (shot, surfaces, physics, air, numerics: float64)."""
    grid = np.stack(np.meshgrid(np.arange(5) * 0.1, np.arange(4) * 0.1, indexing="ij"), -1).reshape(-1, 2)
    one = np.ones(len(grid))
    position = np.concatenate([np.stack([grid[:, 0], one, grid[:, 1]], 1), [[0.2, -0.05, 0.15], [0.2, -0.05, 0.25]]])
    velocity = np.concatenate([np.stack([290.96 * one, -290.96 * one, 0 * one], 1), [[0.0, 0.0, 0.5], [0.0, 0.0, -0.5]]])
    spin = np.concatenate([np.stack([0 * one, 0 * one, -3e3 * one], 1), np.zeros((2, 3))])
    np.savez(path, position=position, velocity=velocity, angular_velocity=spin)
    return {
        "shot": {"file": str(path), "diameter": 0.0025, "density": 7000.0},
        "surfaces": [{"point": [0, 0, 0], "normal": [0, 1, 0], "restitution": 0.01, "mu_s": 0.28, "mu_d": 0.252}],
        "physics": {"bounces": 1},
        "air": {},
        "numerics": {"precision": "float64"},
    }


PAPER_SHOT = {
    "count": 450,
    "diameter": 0.0025,
    "density": 7000.0,
    "speed": 411.48,
    "direction": [1.0, -1.0, 0.0],
    "direction_jitter": [0.1, 0.1, 0.1],
    "envelope_radius": 0.025,
    "envelope_center": [0.0, 1.0, 0.0],
    "seed": 2021,
}
# the paper's plane, with a rolling resistance so that pellets followed to rest (the default) stop
# there rather than roll on for ever (docs/ground.md 12): the landing part is the paper's
GROUND = {
    "point": [0.0, 0.0, 0.0],
    "normal": [0.0, 1.0, 0.0],
    "restitution": 0.01,
    "mu_s": 0.5,
    "mu_d": 0.45,
    "rolling_resistance": 0.05,
}


def paper_raw(**physics):
    return {"shot": dict(PAPER_SHOT), "surfaces": [dict(GROUND)], "physics": {"impact_duration": 1e-5, **physics}}


def make_scene(raw=None, precision="float32", **sections):
    """A Scene from a raw dict (default: the paper's), with tables replaced by `sections`."""
    from warp_ricochet.scene import scene_from_dict

    raw = dict(raw or paper_raw())
    raw.update(sections)
    raw.setdefault("numerics", {})
    raw["numerics"] = {**raw["numerics"], "precision": precision}
    return scene_from_dict(raw)


def explicit_scene(
    tmp_path,
    position,
    velocity,
    angular_velocity=None,
    *,
    surfaces,
    precision="float64",
    diameter=0.0025,
    physics=None,
    name="pellets.npz",
):
    """A Scene whose pellets come from a .npz file written in tmp_path."""
    path = tmp_path / name
    arrays = {"position": np.asarray(position, float), "velocity": np.asarray(velocity, float)}
    if angular_velocity is not None:
        arrays["angular_velocity"] = np.asarray(angular_velocity, float)
    np.savez(path, **arrays)
    raw = {
        "shot": {"file": str(path), "diameter": diameter, "density": 7000.0},
        "surfaces": surfaces,
        "physics": physics or {},
        "numerics": {"precision": precision},
    }
    return make_scene(raw, precision=precision)


def cli(argv):
    """The command line in-process: (exit status, stdout, stderr)."""
    from warp_ricochet.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main([str(a) for a in argv])
    return rc, out.getvalue(), err.getvalue()


def digest(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def stats_equal(a, b):
    """Assert two statistics dicts bitwise equal (NaN equal to NaN), naming the first that differs;
    returns True (so `assert stats_equal(...)` reads as it does)."""
    assert a.keys() == b.keys(), sorted(set(a) ^ set(b))
    for k in a:
        assert a[k] == b[k] or (math.isnan(a[k]) and math.isnan(b[k])), (k, a[k], b[k])
    return True


def assert_same_stats(a, b):
    """Two /stats groups bitwise equal: every statistic, its interval attributes (ci_low, ci_high)
    and, in runs of several shots, every per-shot dataset of /stats/shots."""
    assert sorted(a) == sorted(b)
    for name in b:
        if isinstance(b[name], h5py.Group):
            assert_same_stats(a[name], b[name])
            continue
        x, y = a[name][()], b[name][()]
        if np.ndim(y):
            np.testing.assert_array_equal(x, y, err_msg=name)
        else:
            assert stats_equal({name: x}, {name: y}), (name, x, y)
        for attr in ("ci_low", "ci_high"):
            assert (attr in a[name].attrs) == (attr in b[name].attrs), (name, attr)
            if attr in b[name].attrs:
                assert stats_equal({attr: a[name].attrs[attr]}, {attr: b[name].attrs[attr]}), (name, attr)


def assert_same_run(path, ref, fields, progress=("segment_results",)):
    """Run file `path` is complete, and its per-pellet datasets `fields`, every statistic and the
    /progress partials named are bitwise equal to those of run file `ref`."""
    with h5py.File(path, "r") as a, h5py.File(ref, "r") as b:
        assert a.attrs["status"] == "complete"
        for name in fields:
            assert a[f"pellets/{name}"].dtype == b[f"pellets/{name}"].dtype
            np.testing.assert_array_equal(a[f"pellets/{name}"][()], b[f"pellets/{name}"][()], err_msg=name)
        assert_same_stats(a["stats"], b["stats"])
        for group in ("stats", "hazard"):
            names = [[], []]
            for f, found in zip((a, b), names):
                if group in f:
                    f[group].visititems(
                        lambda name, obj, found=found: found.append(name) if isinstance(obj, h5py.Dataset) else None
                    )
            assert sorted(names[0]) == sorted(names[1]), group
            for name in names[1]:
                x, y = a[group][name][()], b[group][name][()]
                np.testing.assert_array_equal(x, y, err_msg=f"{group}/{name}")
        for name in progress:
            np.testing.assert_array_equal(a[f"progress/{name}"][()], b[f"progress/{name}"][()], err_msg=name)


def assert_opens_in_xarray(path) -> dict:
    """xarray's own reader (`open_datatree`, h5netcdf) opens every group of the file at `path`, with
    no anonymous dimension, and reads every variable as h5py does (text as text); returns
    {path in the file: xarray Variable}."""
    xr = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    found = {}
    with xr.open_datatree(path, engine="h5netcdf") as tree, h5py.File(path, "r") as f:
        for node in tree.subtree:
            for name, var in node.to_dataset(inherit=False).variables.items():
                where = f"{node.path.rstrip('/')}/{name}".lstrip("/")
                ds = f[where]
                assert var.shape == ds.shape and not any(d.startswith("phony_dim") for d in var.dims), (where, var.dims)
                if h5py.check_string_dtype(ds.dtype):
                    assert np.asarray(var.values).astype(str).tolist() == np.asarray(ds.asstr()[()], dtype=str).tolist(), where
                else:
                    np.testing.assert_array_equal(var.values, ds[()], err_msg=where)
                found[where] = xr.Variable(var.dims, var.values, var.attrs)  # (in memory: holds no file open)
    return found


def wait_for_a_chunk(proc, partial, timeout=60.0):
    """Wait until the run `proc` (a subprocess) writing `partial` has committed a chunk
    (/progress/rows > 0, read as a SWMR reader), or has ended, or `timeout` s have passed."""
    deadline = time.time() + timeout
    while time.time() < deadline and proc.poll() is None:
        time.sleep(0.02)
        if partial.exists():
            with contextlib.suppress(OSError, KeyError), h5py.File(partial, "r", swmr=True) as f:
                if f["progress/rows"][()] > 0:
                    return


def interrupt_after(chunks, scene, out, device="cpu"):
    """Run `scene` to `out` on `device` and press Ctrl-C once `chunks` chunks are written."""
    import warp_ricochet as wr

    seen = []

    def progress(done, total):
        seen.append(done)
        if len(seen) == chunks:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        wr.run(scene, out, device=device, progress=progress)


def assert_resume_refused(argv, out, edit, start):
    """`warp-ricochet run ... -o OUT --resume` (`argv`) on OUT.partial, first changed by `edit(file)`
    when given, is refused in one line "warp-ricochet: error: START...", and leaves the partial
    unchanged and no OUT."""
    partial = Path(str(out) + ".partial")
    if edit is not None:
        with h5py.File(partial, "r+") as f:
            edit(f)
    before = digest(partial)
    rc, stdout, err = cli(argv)
    assert rc == 2 and stdout == ""
    assert len(err.splitlines()) == 1 and err.startswith("warp-ricochet: error: " + start), err
    assert digest(partial) == before and not Path(out).exists()


@contextlib.contextmanager
def held(path, exclusive=False):
    """Another process's lock on `path` (a file or folder), as a live run or reader holds it."""
    fd = os.open(path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH)
        yield
    finally:
        os.close(fd)


def first_contacts(tmp_path, precision, x, v, solid, plates, gravity, cover=True, device="cpu"):
    """(time, normal, model) of each pellet's first contact with the one surface `solid` (a scene
    surface dict), by a kernel of `plates` (`physics.geometry`'s flags) on `device` flying in vacuum
    under `gravity` (time < 0: none); `cover` False: no face covers a mesh's edges (every one searched)."""
    import warp as wp

    from warp_ricochet.model import Model
    from warp_ricochet.physics.flight import make_flight

    scene = explicit_scene(tmp_path, x, v, surfaces=[solid], precision=precision, physics={"gravity": list(gravity)})
    model = Model.from_scene(scene, wp.get_device(device))
    if not cover:
        model.surfaces.face_cover.zero_()
    t = model.types
    flight = make_flight(precision, None, "ballistic", plates=plates)

    @wp.kernel(enable_backward=False, module="unique")
    def first(
        surfaces: t.Surfaces,
        physics: t.Physics,
        x: wp.array(dtype=t.vec3),
        v: wp.array(dtype=t.vec3),
        times: wp.array(dtype=t.scalar),
        normals: wp.array(dtype=t.vec3),
    ):
        i = wp.tid()
        dt, k, n, _x, _v, _w, _steps = flight.to_contact(x[i], v[i], t.vec3(), wp.int32(-1), surfaces, physics)
        times[i] = wp.where(k == 0, dt, t.scalar(-1.0))
        normals[i] = n

    arrays = [wp.array(np.asarray(a).astype(precision), dtype=t.vec3, device=device) for a in (x, v)]
    times = wp.zeros(len(x), dtype=t.scalar, device=device)
    normals = wp.zeros(len(x), dtype=t.vec3, device=device)
    wp.launch(first, dim=len(x), inputs=[model.surfaces, model.physics, *arrays], outputs=[times, normals], device=device)
    return times.numpy().astype(np.float64), normals.numpy().astype(np.float64), model
