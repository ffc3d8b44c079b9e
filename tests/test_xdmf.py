"""XDMF sidecars opened by a real reader: VTK's vtkXdmfReader (the `vtk` wheel, ParaView's XDMF 2
reader) must see every point cloud with one point per pellet and arrays equal to the HDF5 file's
(speeds and energies: NumPy float64 from the same datasets), the surfaces as quads on their planes,
and the trajectory frames as time steps."""

import contextlib
import shutil

import h5py
import numpy as np
import pytest
from helpers import cli, interrupt_after, make_scene, paper_raw

xdmf2 = pytest.importorskip("vtkmodules.vtkIOXdmf2")  # the vtk wheel's XDMF 2 reader, no rendering modules
from vtkmodules.util.numpy_support import vtk_to_numpy  # noqa: E402
from vtkmodules.vtkCommonDataModel import vtkCompositeDataSet  # noqa: E402
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline  # noqa: E402

from warp_ricochet import api  # noqa: E402
from warp_ricochet.io.xdmf import quad_corners, sidecar_path, write_xdmf  # noqa: E402

ALL = ["initial", "impact", "landing"]


def _scene(count=40, precision="float64", bounces=2, fields=ALL, **sections):
    raw = paper_raw(bounces=bounces)
    raw["shot"]["count"] = count
    raw["output"] = {"fields": list(fields)}
    raw.update(sections)
    return make_scene(raw, precision=precision)


def _read(xmf, time=None):
    """{block name: vtkDataSet} of the sidecar as vtkXdmfReader reads it (at `time`), and its time steps."""
    reader = xdmf2.vtkXdmfReader()
    reader.SetFileName(str(xmf))
    reader.UpdateInformation()
    steps = reader.GetOutputInformation(0).Get(vtkStreamingDemandDrivenPipeline.TIME_STEPS())
    if time is None:
        reader.Update()
    else:
        reader.UpdateTimeStep(time)
    blocks = {}

    def walk(obj, name):
        if obj.IsA("vtkMultiBlockDataSet"):
            for i in range(obj.GetNumberOfBlocks()):
                walk(obj.GetBlock(i), obj.GetMetaData(i).Get(vtkCompositeDataSet.NAME()))
        else:
            blocks[name] = obj

    walk(reader.GetOutputDataObject(0), "root")
    return blocks, (list(steps) if steps is not None else [])


def _arrays(ds, cells=False):
    data = ds.GetCellData() if cells else ds.GetPointData()
    return {data.GetArrayName(i): vtk_to_numpy(data.GetArray(i)) for i in range(data.GetNumberOfArrays())}


def _norm(v):
    return np.linalg.norm(np.asarray(v, np.float64), axis=-1)


def _expected(g, stage, bounce=None):
    """The point data a cloud must carry, computed here from the HDF5 datasets of group `g`."""
    m, inertia = g["constants/mass"][()], g["constants/inertia"][()]
    out = {}
    for name, ds in g[f"pellets/{stage}"].items():
        value = ds[()] if bounce is None else ds[:, bounce]
        if name == "position":
            continue
        out[name] = value
        base, tail = name.removesuffix("_before"), "_before" if name.endswith("_before") else ""
        if base == "velocity":
            out["speed" + tail] = _norm(value)
            out["energy_translational" + tail] = 0.5 * m * _norm(value) ** 2
        elif base == "angular_velocity":
            out["spin" + tail] = _norm(value)
            out["energy_rotational" + tail] = 0.5 * inertia * _norm(value) ** 2
    for extra in (
        "landing/range",
        "collisions/count",
        "collisions/last_time",
        "hazard/energy",
        "hazard/energy_density",
        "hazard/exceeds",
    ):
        if f"pellets/{extra}" in g and not extra.startswith(stage):
            out[extra.replace("/", ".")] = g[f"pellets/{extra}"][()]
    return out


def _check_clouds(blocks, g, suffix=""):
    """Every cloud of run group `g`: one point per pellet at its position, arrays equal to the HDF5's."""
    rows = int(g["progress/rows"][()])
    clouds = [("launch", "initial", None), ("landing", "landing", None), ("release", "release", None)]
    clouds += [(f"impact_{b + 1}", "impact", b) for b in range(int(g["constants/bounces"][()]))]
    for name, stage, bounce in clouds:
        if f"pellets/{stage}/position" not in g:
            assert name + suffix not in blocks
            continue
        ds = blocks[name + suffix]
        assert ds.GetNumberOfPoints() == rows == ds.GetNumberOfCells(), name
        position = g[f"pellets/{stage}/position"][()]
        position = position if bounce is None else position[:, bounce]
        points = vtk_to_numpy(ds.GetPoints().GetData())
        np.testing.assert_array_equal(points, position[:rows], err_msg=name)
        got, want = _arrays(ds), _expected(g, stage, bounce)
        assert sorted(got) == sorted(want), name
        for key, value in want.items():
            value = np.asarray(value)[:rows]
            assert got[key].shape[0] == rows, (name, key)
            if value.dtype.kind in "iu":
                np.testing.assert_array_equal(got[key].reshape(value.shape), value, err_msg=f"{name}.{key}")
            else:  # speeds and energies: XDMF functions evaluated in the dataset's precision
                rtol = 1e-13 if got[key].dtype == np.float64 else 1e-6
                np.testing.assert_allclose(
                    got[key].reshape(value.shape), value, rtol=rtol, atol=0, equal_nan=True, err_msg=f"{name}.{key}"
                )


def _check_surfaces(ds, g):
    points, normals = g["constants/surfaces/point"][()], g["constants/surfaces/normal"][()]
    assert ds.GetNumberOfCells() == len(points) and ds.GetNumberOfPoints() == 4 * len(points)
    corners = vtk_to_numpy(ds.GetPoints().GetData()).reshape(len(points), 4, 3)
    landed = g["pellets/landing/position"][()]
    landed = landed[np.isfinite(landed).all(axis=1)]
    for p, n, quad in zip(points, normals, corners):
        assert np.abs((quad - p) @ n).max() < 1e-12 * max(1.0, np.abs(quad).max())  # on its plane
        lo, hi = quad.min(axis=0), quad.max(axis=0)  # a horizontal ground here: its landings inside
        assert np.all(landed[:, [0, 2]] > lo[[0, 2]]) and np.all(landed[:, [0, 2]] < hi[[0, 2]])
    cells = _arrays(ds, cells=True)
    np.testing.assert_array_equal(cells["surface"], np.arange(len(points)))
    for name in ("restitution", "mu_s", "mu_d"):
        np.testing.assert_array_equal(cells[name], g[f"constants/surfaces/{name}"][()])


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_a_published_run_opens_in_vtk(tmp_path, precision):
    out = tmp_path / "shot.h5"
    api.run(_scene(precision=precision), output=str(out), device="cpu")
    xmf = tmp_path / "shot.xmf"
    assert sidecar_path(out) == xmf and xmf.is_file()
    blocks, steps = _read(xmf)
    assert steps == [] and sorted(blocks) == ["impact_1", "impact_2", "landing", "launch", "surfaces"]
    with h5py.File(out) as f:
        _check_clouds(blocks, f)
        _check_surfaces(blocks["surfaces"], f)
    assert ('NumberType="Float" Precision="4"' in xmf.read_text()) == (precision == "float32")


def test_only_datasets_in_the_file_are_referenced(tmp_path):
    """A run writing landings only has one cloud (launch and impacts absent); a statistics-only
    run file has the surfaces alone."""
    out = tmp_path / "landing.h5"
    api.run(_scene(fields=["landing.position", "landing.range"]), output=str(out), device="cpu")
    blocks, _ = _read(sidecar_path(out))
    assert sorted(blocks) == ["landing", "surfaces"]
    assert sorted(_arrays(blocks["landing"])) == ["range"]
    out = tmp_path / "stats.h5"
    api.run(_scene(fields=[]), output=str(out), device="cpu")
    blocks, _ = _read(sidecar_path(out))
    assert list(blocks) == ["surfaces"] and blocks["surfaces"].GetNumberOfCells() == 1


def test_trajectory_frames_are_time_steps(tmp_path):
    scene = _scene(30, bounces=1, fields=ALL + ["collisions", "release"], collisions={"enabled": True, "frame_every": 8})
    out = tmp_path / "frames.h5"
    api.run(scene, output=str(out), device="cpu")
    with h5py.File(out) as f:
        times, frames = f["particles/pellets/position/time"][()], f["particles/pellets/position/value"]
        blocks, steps = _read(sidecar_path(out))
        assert len(times) > 1 and steps == list(times)
        _check_clouds(blocks, f)
        for k in (0, len(times) // 2, len(times) - 1):
            blocks, _ = _read(sidecar_path(out), time=times[k])
            ds = blocks["frames"]
            np.testing.assert_array_equal(vtk_to_numpy(ds.GetPoints().GetData()), frames[k])
            got = _arrays(ds)
            np.testing.assert_array_equal(got["id"], np.arange(30))
            np.testing.assert_array_equal(got["collisions.count"], f["pellets/collisions/count"][()])


def test_a_sweep_has_one_collection_per_point(tmp_path, monkeypatch):
    """One sidecar, the sweep file's, with a collection per point (none is written for the points'
    own files in the folder, nor for the file before it is moved into place)."""
    from warp_ricochet.io import runfile

    written = []
    monkeypatch.setattr(runfile, "write_xdmf", lambda path, **kw: written.append(str(path)) or write_xdmf(path, **kw))
    out = tmp_path / "sweep.h5"
    api.sweep(
        _scene(20, bounces=1), {"surfaces.0.mu_s": [0.5, 0.2]}, [("surfaces.0.mu_d", 0.9, None)], output=str(out), device="cpu"
    )
    assert written == [str(out)]
    blocks, _ = _read(sidecar_path(out))
    assert len(blocks) == 2 * 4
    with h5py.File(out) as f:
        for point in ("0000", "0001"):
            _check_clouds(blocks, f[f"runs/{point}"], suffix=f" point_{point}")
            _check_surfaces(blocks[f"surfaces point_{point}"], f[f"runs/{point}"])


def test_sidecar_rules(tmp_path):
    """Never over an existing sidecar unless asked (refused before any work, like the output);
    `warp-ricochet xdmf` writes it again; an interrupted run has none, its partial can have one
    of the rows complete, and the resumed run publishes it."""
    out = tmp_path / "shot.h5"
    xmf = tmp_path / "shot.xmf"
    xmf.write_text("mine")
    scene_file = tmp_path / "scene.toml"
    scene_file.write_text(_scene(20).to_toml())
    rc, _, err = cli(["run", scene_file, "-o", out, "--device", "cpu"])
    assert rc == 2 and "shot.xmf (its XDMF sidecar) exists; give --overwrite" in err
    assert not out.exists() and xmf.read_text() == "mine"
    assert cli(["run", scene_file, "-o", out, "--device", "cpu", "--overwrite"])[0] == 0
    text = xmf.read_text()
    assert text.startswith("<?xml") and "shot.h5:/pellets/landing/position" in text
    rc, _, err = cli(["xdmf", out])
    assert rc == 2 and "--overwrite" in err and xmf.read_text() == text
    xmf.unlink()
    assert cli(["xdmf", out]) == (0, f"{xmf}\n", "")
    assert xmf.read_text() == text
    rc, _, err = cli(["xdmf", scene_file])
    assert rc == 2 and "is not an HDF5 file" in err

    big = tmp_path / "big.h5"
    count = 3 * 65536 - 1000  # three chunks
    scene = _scene(count, fields=["initial.position", "landing.position", "landing.range"], numerics={"chunk_size": 65536})
    interrupt_after(2, scene, str(big))
    partial = tmp_path / "big.h5.partial"
    assert partial.exists() and not sidecar_path(big).exists()
    copy = tmp_path / "copy.h5"
    shutil.copy(partial, copy)
    with h5py.File(copy, "r+") as f:
        f.attrs["status"] = "interrupted"
        rows = int(f["progress/rows"][()])
        assert 0 < rows < count
    blocks, _ = _read(write_xdmf(copy))
    with h5py.File(copy) as f:
        _check_clouds(blocks, f)
    api.run(scene, output=str(big), device="cpu", resume=True)
    blocks, _ = _read(sidecar_path(big))
    assert blocks["landing"].GetNumberOfPoints() == count


@pytest.mark.parametrize("normal", [(0, 1, 0), (1, 0, 0), (0.3, -0.2, 0.9), (0, 0, -1)])
def test_quad_corners_span_the_projections(normal):
    """quad_corners: on the plane, a rectangle (equal diagonals, right angles), counter-clockwise
    about the normal, holding every projected point inside."""
    rng = np.random.default_rng(1)
    point, points = rng.normal(size=3), rng.normal(size=(50, 3)) * 5
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    q = quad_corners(point, normal, points)
    assert np.abs((q - point) @ n).max() < 1e-12
    edges = np.roll(q, -1, axis=0) - q
    assert np.abs(np.einsum("ij,ij->i", edges, np.roll(edges, -1, axis=0))).max() < 1e-9
    assert np.cross(edges[0], edges[1]) @ n > 0
    u, v = edges[0] / np.linalg.norm(edges[0]), edges[1] / np.linalg.norm(edges[1])
    rel = points - q[0]
    assert np.all(rel @ u > 0) and np.all(rel @ u < np.linalg.norm(edges[0]))
    assert np.all(rel @ v > 0) and np.all(rel @ v < np.linalg.norm(edges[1]))


def test_a_sidecar_that_cannot_be_written_is_a_warning(tmp_path, monkeypatch):
    """The run's file is in place when its sidecar is written: a failure there (a full disk) warns,
    naming the command that writes it later, and the run succeeds."""
    import errno

    from warp_ricochet.io import runfile

    def full(path, overwrite):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(runfile, "write_xdmf", full)
    out = tmp_path / "shot.h5"
    with pytest.warns(UserWarning, match=r"shot.xmf .* was not written: .*No space left.*warp-ricochet xdmf"):
        api.run(_scene(10, bounces=1), output=str(out), device="cpu")
    with h5py.File(out) as f:
        assert f.attrs["status"] == "complete"
    assert not sidecar_path(out).exists()


def test_a_scene_without_planes_has_no_surfaces_block(tmp_path):
    """Pellets in free flight (no [[surfaces]]): the sidecar has their launch cloud and no quads."""
    out = tmp_path / "free.h5"
    api.run(_scene(fields=["initial"], surfaces=[]), output=str(out), device="cpu")
    blocks, _ = _read(sidecar_path(out))
    assert sorted(blocks) == ["launch"] and blocks["launch"].GetNumberOfPoints() == 40


KILL_AFTER_A_CHUNK = """
import os, signal, sys
import warp_ricochet as wr
from warp_ricochet.scene import load_scene

def progress(done, total):  # the first chunk is complete and counted: die as SIGKILL leaves a run
    os.kill(os.getpid(), signal.SIGKILL)

wr.run(load_scene(sys.argv[1]), sys.argv[2], device="cpu", progress=progress)
"""


def test_a_killed_runs_partial_opens_in_vtk_with_the_rows_complete(tmp_path):
    """A SIGKILLed run leaves its writer's flags set, and HDF5 refuses a plain open of such a file,
    which is how VTK (ParaView) opens it ("Failed to read attribute data"): `warp-ricochet xdmf`
    clears them (as h5clear -s), and the sidecar shows /progress/rows rows; --resume still works."""
    import os
    import signal
    import subprocess
    import sys
    from pathlib import Path

    scene = _scene(2 * 65536 + 100, fields=["initial.position", "landing"], numerics={"chunk_size": 65536})
    scene_file, out = tmp_path / "scene.toml", tmp_path / "killed.h5"
    scene_file.write_text(scene.to_toml())
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    proc = subprocess.run(
        [sys.executable, "-c", KILL_AFTER_A_CHUNK, str(scene_file), str(out)],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    partial = tmp_path / "killed.h5.partial"
    with pytest.raises(OSError, match="already open for write"):
        h5py.File(partial, "r").close()
    code, _, err = cli(["xdmf", partial])  # (the command line logs its warnings: cli.configure_logging)
    assert code == 0 and "its writer was killed; cleared the flags" in err, err
    blocks, _ = _read(sidecar_path(partial))
    with h5py.File(partial) as f:
        assert f.attrs["status"] == "running" and 0 < f["progress/rows"][()] < len(f["pellets/landing/range"]) + 1
        _check_clouds(blocks, f)
        assert blocks["landing"].GetNumberOfPoints() == f["progress/rows"][()] == 65536
    api.run(scene, output=str(out), device="cpu", resume=True)
    assert _read(sidecar_path(out))[0]["landing"].GetNumberOfPoints() == 2 * 65536 + 100


def test_the_hazard_at_landing_is_on_every_cloud(tmp_path):
    """energy, energy_density and exceeds (/pellets/hazard) are point data, so ParaView colours by them."""
    hazard = {"energy_density": {"eye": 1503.0}, "speed": {"skin": 101.0}}
    out = tmp_path / "hazard.h5"
    api.run(_scene(fields=["initial", "landing", "hazard"], hazard=hazard), output=str(out), device="cpu")
    blocks, _ = _read(sidecar_path(out))
    with h5py.File(out) as f:
        for cloud in ("launch", "landing"):
            got = _arrays(blocks[cloud])
            for name in ("energy", "energy_density", "exceeds"):
                want = f[f"pellets/hazard/{name}"][()]
                np.testing.assert_array_equal(got[f"hazard.{name}"].reshape(want.shape), want, err_msg=name)
        assert f["pellets/hazard/exceeds"][()].any()


LEAVE_FLAGS = """
import os, sys, h5py
f = h5py.File(sys.argv[1], "r+", libver="latest")
f.attrs["status"], f.attrs["writer_pid"], f.attrs["writer_host"] = "running", int(sys.argv[2]), sys.argv[3]
f.swmr_mode = True
f.flush()
os._exit(0)  # (as a killed writer: its superblock's status flags stay set)
"""


def _left_open(tmp_path, pid, host):
    """A run file marked "running" by writer `pid` on `host`, its SWMR flags left set (HDF5 refuses a plain open)."""
    import socket
    import subprocess
    import sys

    out = tmp_path / "left.h5.partial"
    api.run(_scene(), output=str(tmp_path / "left.h5"), device="cpu")
    shutil.move(tmp_path / "left.h5", out)
    subprocess.run([sys.executable, "-c", LEAVE_FLAGS, str(out), str(pid), host or socket.gethostname()], check=True)
    with pytest.raises(OSError, match="already open for write"):
        h5py.File(out, "r").close()
    return out


@pytest.mark.parametrize("case", ["held", "alive", "elsewhere", "read-only"])
def test_the_flags_of_a_file_that_may_be_written_or_cannot_be_are_left(tmp_path, monkeypatch, case):
    """`xdmf` clears a killed writer's flags only when no process holds the file, the writer it
    records is not alive here nor on another host (a flock is local on NFS/Lustre), and the file is
    writable: else one line, exit 2, nothing written."""
    import os
    import subprocess
    import sys

    from helpers import held

    proc = subprocess.Popen([sys.executable, "-c", "0"])
    proc.wait()  # (a writer that has ended)
    pid = os.getpid() if case == "alive" else proc.pid
    partial = _left_open(tmp_path, pid, "elsewhere.example" if case == "elsewhere" else None)
    before = partial.read_bytes()
    if case == "read-only":  # (as the file's mode would refuse a user; root is never refused)
        plain = os.open

        def refuse(path, flags, *args, **kwargs):
            if flags & os.O_RDWR and os.fspath(path) == str(partial):
                raise PermissionError(13, "Permission denied", str(path))
            return plain(path, flags, *args, **kwargs)

        monkeypatch.setattr(os, "open", refuse)
    with held(partial) if case == "held" else contextlib.nullcontext():
        code, out, err = cli(["xdmf", partial])
    said = {
        "held": "another process has it open",
        "alive": "another process has it open",
        "elsewhere": "its writer ran on host 'elsewhere.example'",
        "read-only": "needs write access to it",
    }[case]
    assert code == 2 and said in err and len(err.strip().splitlines()) == 1, err
    assert partial.read_bytes() == before and not sidecar_path(partial).exists()


def test_finite_plates_are_drawn_as_their_triangles(tmp_path):
    """A plane, a rectangle and a disc: the plane stays one quad in `surfaces`, the plates are
    triangles in `plates` (2 and DISC_SIDES), on their planes and within their outlines, with their
    surface's index and coefficients as cell data; /constants/surfaces keeps their shapes."""
    from warp_ricochet.io.xdmf import DISC_SIDES

    raw = paper_raw()
    raw["shot"]["count"] = 64
    rect = {"kind": "rectangle", "point": [4.0, 1.0, 0.5], "normal": [-1.0, 0.0, 0.0], "axis_u": [0.0, 0.0, 1.0]}
    rect.update(size=[2.0, 1.0], restitution=0.3, mu_s=0.2)
    disc = {
        "kind": "disc",
        "point": [6.0, 0.5, -1.0],
        "normal": [0.0, 1.0, 0.0],
        "radius": 0.75,
        "two_sided": True,
        "restitution": 0.6,
        "mu_s": 0.4,
    }
    raw["surfaces"] = [raw["surfaces"][0], rect, disc]
    raw["output"] = {"fields": ["landing"]}
    scene = make_scene(raw, precision="float64")
    api.run(scene, tmp_path / "plates.h5", device="cpu")
    with h5py.File(tmp_path / "plates.h5") as f:
        g = f[next(iter(f))] if "constants" not in f else f
        s = g["constants/surfaces"]
        np.testing.assert_array_equal(s["kind"][()], [0, 1, 2])
        np.testing.assert_array_equal(s["size"][()], [[0.0, 0.0, 0.0], [2.0, 1.0, 0.0], [1.5, 1.5, 0.0]])
        np.testing.assert_array_equal(s["two_sided"][()], [0, 0, 1])
        restitution = s["restitution"][()]
    blocks, _steps = _read(tmp_path / "plates.xmf")
    assert blocks["surfaces"].GetNumberOfCells() == 1
    plates = blocks["plates"]
    assert plates.GetNumberOfCells() == 2 + DISC_SIDES
    cells = _arrays(plates, cells=True)
    np.testing.assert_array_equal(cells["surface"], [1, 1] + [2] * DISC_SIDES)
    np.testing.assert_array_equal(cells["restitution"], restitution[cells["surface"]])
    corners = vtk_to_numpy(plates.GetPoints().GetData()).reshape(-1, 3, 3)
    rect_corners, disc_corners = corners[:2].reshape(-1, 3), corners[2:].reshape(-1, 3)
    np.testing.assert_allclose(rect_corners[:, 0], 4.0, rtol=0, atol=1e-12)
    assert np.allclose(np.abs(rect_corners[:, 2] - 0.5).max(), 1.0) and np.allclose(np.abs(rect_corners[:, 1] - 1.0).max(), 0.5)
    np.testing.assert_allclose(disc_corners[:, 1], 0.5, rtol=0, atol=1e-12)
    assert np.hypot(disc_corners[:, 0] - 6.0, disc_corners[:, 2] + 1.0).max() <= 0.75 + 1e-12
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])  # counter-clockwise about each normal
    assert np.all(normals[:2] @ [-1.0, 0.0, 0.0] > 0) and np.all(normals[2:] @ [0.0, 1.0, 0.0] > 0)


def test_a_post_is_drawn_as_its_side_and_caps(tmp_path):
    """A post (kind = "cylinder") in `plates`: DISC_SIDES quads of side and two fans of DISC_SIDES,
    on its cylinder and caps, wound counter-clockwise seen from outside."""
    from warp_ricochet.io.xdmf import DISC_SIDES

    raw = paper_raw()
    raw["shot"]["count"] = 64
    post = {"kind": "cylinder", "point": [5.0, 0.0, 0.5], "normal": [0.0, 1.0, 0.0], "radius": 0.2, "length": 1.5}
    post.update(restitution=0.3, mu_s=0.2)
    raw["surfaces"] = [raw["surfaces"][0], post]
    raw["physics"]["until"] = "landing"
    raw["output"] = {"fields": ["landing"]}
    api.run(make_scene(raw, precision="float64"), tmp_path / "post.h5", device="cpu")
    blocks, _steps = _read(tmp_path / "post.xmf")
    plates = blocks["plates"]
    assert plates.GetNumberOfCells() == 4 * DISC_SIDES
    np.testing.assert_array_equal(_arrays(plates, cells=True)["surface"], [1] * (4 * DISC_SIDES))
    corners = vtk_to_numpy(plates.GetPoints().GetData()).reshape(-1, 3, 3)
    points = corners.reshape(-1, 3)
    radial = np.hypot(points[:, 0] - 5.0, points[:, 2] - 0.5)
    assert radial.max() <= 0.2 + 1e-12 and points[:, 1].min() >= -1e-12 and points[:, 1].max() <= 1.5 + 1e-12
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    outward = corners.mean(axis=1) - [5.0, 0.75, 0.5]
    assert np.all(np.einsum("ij,ij->i", normals, outward) > 0)


def test_boxes_meshes_and_terrain_are_drawn_from_the_file(tmp_path):
    """Issue 27, part 5: a box, a small mesh and the shipped terrain (warp_ricochet/examples/terrain/
    trap_field.asc): each surface's triangles are stored once in /geometry/surface_I (float64 m,
    int32) as the run used them, and vtkXdmfReader's `geometry_I` block has their count, corners
    and bounds; the sidecar references them (it stays small)."""
    from importlib.resources import files

    trimesh = pytest.importorskip("trimesh")
    from warp_ricochet.model import terrain_triangles
    from warp_ricochet.scene.triangles import box_triangles, load_mesh

    tetra = np.array([[30.0, 0.0, -2.0], [32.0, 0.0, -2.0], [31.0, 0.0, 0.0], [31.0, 2.0, -1.0]])
    faces = [[0, 1, 2], [0, 3, 1], [1, 3, 2], [0, 2, 3]]  # wound outwards (wound inwards its solid holds the gun)
    mesh_path = tmp_path / "tetra.ply"
    trimesh.Trimesh(vertices=tetra, faces=faces, process=False).export(mesh_path)
    raster = str(files("warp_ricochet") / "examples" / "terrain" / "trap_field.asc")
    raw = paper_raw(until="landing")
    raw["shot"]["count"] = 16
    box = {"kind": "box", "point": [20.0, 1.0, 0.0], "normal": [0.0, 1.0, 0.0], "axis_u": [1.0, 0.0, 0.0], "size": [1, 2, 3]}
    terrain = {"kind": "terrain", "file": raster, "origin": [500_010.0, 4_200_050.0], "elevation": 119.8}
    surfaces = [box, {"kind": "mesh", "file": str(mesh_path), "point": [0.0, 0.5, 0.0]}, terrain]
    raw["surfaces"] = [{**s, "name": f"s{i}", "restitution": 0.5, "mu_s": 0.2} for i, s in enumerate(surfaces)] + raw["surfaces"]
    raw["output"] = {"fields": ["landing"]}
    scene = make_scene(raw, precision="float64")
    api.run(scene, tmp_path / "geo.h5", device="cpu")
    used = [
        box_triangles(box["point"], box["normal"], box["axis_u"], box["size"]),
        load_mesh(str(mesh_path), "file", (0.0, 0.5, 0.0)),
        terrain_triangles(scene, 2),
    ]
    assert len(used[2].triangles) == 2 * 60 * 20  # (61 x 21 samples)
    blocks, _steps = _read(tmp_path / "geo.xmf")
    assert "geometry_3" not in blocks and blocks["surfaces"].GetNumberOfCells() == 1  # the plane: a quad
    with h5py.File(tmp_path / "geo.h5") as f:
        for i, mesh in enumerate(used):
            g = f[f"geometry/surface_{i}"]
            assert g.attrs["name"] == f"s{i}" and g["vertices"].attrs["units"] == "m"
            assert g["vertices"].dtype == np.float64 and g["triangles"].dtype == np.int32
            np.testing.assert_array_equal(g["vertices"][()], mesh.vertices)
            np.testing.assert_array_equal(g["triangles"][()], mesh.triangles)
            ds = blocks[f"geometry_{i}"]
            assert ds.GetNumberOfCells() == len(mesh.triangles)
            np.testing.assert_allclose(np.reshape(ds.GetBounds(), (3, 2)).T, [mesh.vertices.min(0), mesh.vertices.max(0)])
            points = vtk_to_numpy(ds.GetPoints().GetData())
            cells = vtk_to_numpy(ds.GetCells().GetConnectivityArray())
            np.testing.assert_array_equal(points[cells.reshape(-1, 3)], mesh.vertices[mesh.triangles])
    assert (tmp_path / "geo.xmf").stat().st_size < 20_000
