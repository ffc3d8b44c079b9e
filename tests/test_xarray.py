"""Run files in xarray and pandas, with the real clients: xarray + h5netcdf see named, unit-carrying
dimensions (HDF5 dimension scales) in run, collision and sweep files; `warp_ricochet.open_run` reads
a run of several chunks lazily (dask) with values equal to h5py's, a killed run's .partial only up to
/progress/rows, and a resumed run as an uninterrupted one; `Run.dataframe` gives pandas one row per
pellet."""

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import h5py
import numpy as np
import pytest

import warp_ricochet as wr
from warp_ricochet.fields import FIELDS
from warp_ricochet.io.dimensions import field_dimensions
from warp_ricochet.scene import load_scene
from warp_ricochet.tallies.reduce import SEGMENT

xr = pytest.importorskip("xarray")
da = pytest.importorskip("dask.array")
pytest.importorskip("h5netcdf")
pd = pytest.importorskip("pandas")

ROOT = Path(__file__).resolve().parents[1]
PAPER = str(ROOT / "examples" / "paper.toml")
PELLETS = 2 * SEGMENT + 5000  # three chunks of the smallest size
SETS = [
    f"shot.count={PELLETS}",
    "numerics.chunk_size=65536",
    "numerics.precision='float64'",
    'output.fields=["landing", "impact.velocity", "initial.position"]',
]
ALL_SETS = ["shot.count=300", "physics.bounces=2", 'output.fields=["initial", "impact", "landing"]']


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """An uninterrupted run of three chunks."""
    path = tmp_path_factory.mktemp("xarray") / "ref.h5"
    wr.run(load_scene(PAPER, SETS), path, device="cpu")
    return path


def walk(tree):
    """(path, DataArray) of every variable of every node of a DataTree."""
    for node in tree.subtree:
        for name, var in node.to_dataset(inherit=False).variables.items():
            yield f"{node.path.rstrip('/')}/{name}".lstrip("/"), var


def assert_named_like_the_layout(path, group=""):
    """xarray + h5netcdf: no anonymous dimension anywhere; every per-pellet dataset of `group` has the
    layout's dimensions, its units and h5py's values."""
    with xr.open_datatree(path, engine="h5netcdf") as tree, h5py.File(path, "r") as f:
        variables = dict(walk(tree))
        phony = [(p, v.dims) for p, v in variables.items() if any(d.startswith("phony") for d in v.dims)]
        assert not phony, phony
        fields = [p for p in variables if p.startswith(group + "pellets/")]
        assert fields
        for p in fields:
            name = p[len(group + "pellets/") :].replace("/", ".")
            assert variables[p].dims == field_dimensions(name), p
            assert variables[p].attrs["units"] == FIELDS[name].unit, p
            np.testing.assert_array_equal(variables[p].values, f[p][:], err_msg=p)
        return variables


def test_xarray_with_h5netcdf_sees_named_dimensions_and_units(tmp_path):
    path = tmp_path / "all.h5"
    wr.run(load_scene(PAPER, ALL_SETS), path, device="cpu")
    variables = assert_named_like_the_layout(path)
    assert variables["pellets/impact/velocity"].dims == ("pellet", "bounce", "xyz")
    assert variables["pellets/impact/velocity"].shape == (300, 2, 3)
    assert variables["constants/surfaces/normal"].dims == ("surface", "xyz")
    assert variables["progress/segment_results"].dims[0] == "segment"
    assert list(variables["xyz"].values) == ["x", "y", "z"]
    assert variables["stats/range_mean"].attrs["units"] == "m"
    with xr.open_dataset(path, engine="h5netcdf", group="pellets/landing") as ds:
        assert dict(ds.sizes) == {"pellet": 300, "xyz": 3}
        assert ds["range"].attrs["units"] == "m" and ds["velocity"].dims == ("pellet", "xyz")


def test_collision_runs_with_frames_and_sweeps_have_no_anonymous_dimension(tmp_path):
    collide = tmp_path / "collide.h5"
    wr.run(
        load_scene(
            PAPER,
            [
                "shot.count=40",
                "shot.shots=2",
                "collisions.enabled=true",
                "collisions.frame_every=200",
                'output.fields=["landing", "collisions", "release"]',
            ],
        ),
        collide,
        device="cpu",
    )
    variables = assert_named_like_the_layout(collide)
    assert variables["progress/shot_totals"].dims[0] == "shot"
    assert variables["particles/pellets/position/value"].dims == ("frame", "pellet", "xyz")
    sweep = tmp_path / "sweep.h5"
    wr.sweep(
        load_scene(PAPER, ["shot.count=50", 'output.fields=["landing"]']),
        {"surfaces.0.mu_s": [0.0, 0.5]},
        ties=[("surfaces.0.mu_d", 0.9, None)],
        output=sweep,
        device="cpu",
    )
    variables = assert_named_like_the_layout(sweep, group="runs/0001/")
    assert variables["stats/range_mean"].dims == ("point",)
    assert variables["sweep/surfaces.0.mu_s"].dims == ("point",)
    with wr.open_run(sweep) as run:  # the sweep's statistics per point, the swept values as coordinates
        table = run.stats[["range_mean"]].to_dataframe()
        assert list(table["surfaces.0.mu_s"]) == [0.0, 0.5] and table["range_mean"].notna().all()
    with wr.open_run(sweep, point=1) as run, h5py.File(sweep) as f:
        np.testing.assert_array_equal(run.landing.range.values, f["runs/0001/pellets/landing/range"][:])
        assert run.stats.range_mean.item() == f["stats/range_mean"][1]


def test_every_group_of_a_hazard_run_opens_and_open_run_reads_its_hazard_group(tmp_path):
    """/hazard/map/surface (a scalar) once met a dimension `surface` in the file's root: h5netcdf took
    it for a coordinate variable and sliced it ("Illegal slicing argument for scalar dataspace").
    Dimension scales now live in the groups of their datasets, none in a run file's root."""
    path = tmp_path / "hazard.h5"
    wr.run(load_scene(str(ROOT / "examples" / "hazard.toml"), ["shot.count=30", "shot.shots=2"]), path, device="cpu")
    variables = assert_named_like_the_layout(path)
    assert variables["hazard/map/surface"].dims == () and variables["hazard/map/above"].dims[0] == "threshold"
    assert variables["hazard/danger_distance/distance"].dims == ("threshold", "fraction")
    with h5py.File(path) as f:
        assert sorted(f) == ["constants", "hazard", "pellet", "pellets", "progress", "stats", "xyz"]
        assert f["hazard/map/above"].dims[0][0].name == "/hazard/threshold"
        assert f.attrs["format_version"] == 2
        with wr.open_run(path) as run:
            h = run.hazard_results
            assert list(h.thresholds_name.values) == [n.decode() for n in f["hazard/thresholds/name"][()]]
            np.testing.assert_array_equal(h.map_above.values, f["hazard/map/above"][()])
            assert h.map_count.dims == ("map_v", "map_u") and h.map_origin.dims == ("xyz",)
            assert h.danger_distance_distance.attrs["units"] == "m"
            assert "hazard" in run.to_datatree().children
            assert run.hazard.energy_density.shape == (60,)


def test_open_run_reads_several_chunks_lazily_as_h5py_does(reference):
    with wr.open_run(reference, chunk_rows=SEGMENT) as run, h5py.File(reference) as f:
        assert (run.status, run.rows, run.pellets) == ("complete", PELLETS, PELLETS)
        assert set(run.groups) == {"landing", "impact", "initial"}
        velocity = run.impact.velocity
        assert isinstance(velocity.data, da.Array) and velocity.data.numblocks[0] == 3
        assert velocity.dims == ("pellet", "bounce", "xyz") and velocity.attrs["units"] == "m/s"
        for group, name in (
            ("landing", "range"),
            ("landing", "position"),
            ("impact", "velocity"),
            ("initial", "position"),
        ):
            np.testing.assert_array_equal(run[group][name].values, f[f"pellets/{group}/{name}"][:])
        mean = run.landing.range.where(run.landing.surface >= 0).mean()
        assert isinstance(mean.data, da.Array)
        assert float(mean) == pytest.approx(f["stats/range_mean"][()], rel=1e-12)
        assert run.stats.range_mean.item() == f["stats/range_mean"][()]
        table = run.dataframe("landing")
        assert len(table) == PELLETS and table.index.name == "pellet"
        assert list(table.columns) == [
            "position_x",
            "position_y",
            "position_z",
            "range",
            "surface",
            "time",
            "velocity_x",
            "velocity_y",
            "velocity_z",
        ]
        assert table.attrs["units"]["velocity_z"] == "m/s"
        np.testing.assert_array_equal(table["position_z"].to_numpy(), f["pellets/landing/position"][:, 2])
        long = run.landing[["range"]].isel(pellet=slice(0, 10)).to_dataframe()
        assert len(long) == 10
        impact = run.dataframe("impact", pellets=slice(100, 200))
        assert impact.index.names == ["pellet", "bounce"] and len(impact) == 100
        tree = run.to_datatree()
        assert isinstance(tree["pellets/landing/range"].data, da.Array)
        assert list(tree["pellets/impact"].ds.xyz.values) == ["x", "y", "z"]  # inherited from the root
        with pytest.raises(AttributeError, match="no per-pellet collisions"):
            _ = run.collisions


KILLED = textwrap.dedent("""
    import os, signal, sys
    import warp_ricochet as wr
    from warp_ricochet.io.writer import RunWriter
    from warp_ricochet.scene import load_scene

    append, calls = RunWriter.append, []

    class Die:  # the second chunk's rows are written and flushed, then the process dies before counting them
        def __setitem__(self, key, value):
            os.kill(os.getpid(), signal.SIGKILL)

    def dying(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            self.progress_rows = Die()
        return append(self, *args, **kwargs)

    RunWriter.append = dying
    wr.run(load_scene(sys.argv[1], sys.argv[3:]), sys.argv[2], device="cpu")
""")


def test_a_killed_run_reads_up_to_its_progress_and_its_resume_is_named_too(tmp_path, reference):
    out = tmp_path / "killed.h5"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(
        [sys.executable, "-c", KILLED, PAPER, str(out), *SETS], env=env, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    partial = Path(str(out) + ".partial")
    with h5py.File(partial, "r", swmr=True) as f:
        assert f.attrs["status"] == "running" and f["progress/rows"][()] == SEGMENT
        assert len(f["pellets/landing/range"]) == 2 * SEGMENT  # a chunk beyond the count
    with wr.open_run(partial) as run, h5py.File(reference) as ref:
        assert (run.status, run.rows, run.pellets) == ("running", SEGMENT, PELLETS)
        assert run.landing.sizes["pellet"] == SEGMENT and len(run.dataframe("landing")) == SEGMENT
        for group, name in (("landing", "range"), ("impact", "velocity"), ("initial", "position")):
            np.testing.assert_array_equal(run[group][name].values, ref[f"pellets/{group}/{name}"][:SEGMENT])
        assert np.isnan(run.stats.range_mean.item())
    wr.run(load_scene(PAPER, SETS), out, device="cpu", resume=True)
    assert_named_like_the_layout(out)
    with wr.open_run(out) as run, h5py.File(reference) as ref:
        assert run.rows == PELLETS
        np.testing.assert_array_equal(run.landing.range.values, ref["pellets/landing/range"][:])


def test_open_run_refuses_what_is_not_a_run_file_in_one_line(tmp_path):
    with pytest.raises(wr.OutputError, match="does not exist"):
        wr.open_run(tmp_path / "none.h5")
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = [1.0]
    with pytest.raises(wr.OutputError, match="is not a warp-ricochet output file") as info:
        wr.open_run(other)
    assert "\n" not in str(info.value)


def test_the_documented_examples_run(tmp_path, monkeypatch):
    """Every Python example of docs/output.md's "xarray and pandas" section, on a run file shot.h5."""
    text = (ROOT / "docs" / "output.md").read_text()
    section = text.split("\n## xarray and pandas\n", 1)[1].split("\n## ", 1)[0]
    blocks = [b.split("```", 1)[0] for b in section.split("```python\n")[1:]]
    assert len(blocks) >= 3
    monkeypatch.chdir(tmp_path)
    wr.run(
        load_scene(PAPER, ["shot.count=200", "physics.bounces=2", 'output.fields=["impact", "landing"]']),
        "shot.h5",
        device="cpu",
    )
    for block in blocks:
        exec(compile(block, "docs/output.md", "exec"), {})  # raises if an example is wrong


def test_datasets_the_layout_does_not_know_get_dimensions_of_their_own(tmp_path):
    """A dataset added to a run group later (say by a new writer) is named, not left anonymous:
    `xyz` for a last axis of 3, `<path>_<axis>` otherwise, never sharing a dimension of another length."""
    from warp_ricochet.io.dimensions import name_run_dimensions

    path = tmp_path / "extra.h5"
    with h5py.File(path, "w") as f:
        f["pellets/landing/range"] = np.arange(4.0)
        f["particles/pellets/box/edges"] = np.ones(3)
        f["particles/pellets/id/value"] = np.zeros((2, 5))
        f["other/value"] = np.zeros(7)
        name_run_dimensions(f)
    with xr.open_datatree(path, engine="h5netcdf") as tree:
        dims = {p: v.dims for p, v in walk(tree)}
    assert dims["pellets/landing/range"] == ("pellet",)
    assert dims["particles/pellets/box/edges"] == ("xyz",)
    assert dims["particles/pellets/id/value"] == ("particles_pellets_id_value_0", "particles_pellets_id_value_1")
    assert dims["other/value"] == ("other_value_0",)


@pytest.mark.parametrize("compression", ["gzip-4", "lzf"])
def test_compressed_runs_resume_bitwise_and_read_the_same(tmp_path, reference, compression):
    """output.compression filters the per-pellet datasets (chunked, SWMR): a run interrupted after two
    of its three chunks and resumed equals the uncompressed uninterrupted run bitwise, in less space."""
    from helpers import assert_same_run, interrupt_after

    out = tmp_path / "packed.h5"
    scene = load_scene(PAPER, SETS + [f"output.compression={compression!r}"])
    interrupt_after(2, scene, str(out))
    wr.run(scene, out, device="cpu", resume=True)
    fields = ["landing/range", "landing/position", "impact/velocity", "initial/position", "landing/surface"]
    assert_same_run(out, reference, fields)
    with h5py.File(out) as f, h5py.File(reference) as ref:
        assert f["pellets/landing/range"].compression == compression.split("-")[0]
        assert f["pellets/landing/range"].shuffle and ref["pellets/landing/range"].compression is None
        packed = sum(f[f"pellets/{n}"].id.get_storage_size() for n in fields)
        assert packed < sum(ref[f"pellets/{n}"].id.get_storage_size() for n in fields)
    with wr.open_run(out) as run, h5py.File(reference) as ref:
        np.testing.assert_array_equal(run.impact.velocity.values, ref["pellets/impact/velocity"][()])


def test_plate_shapes_have_named_dimensions(tmp_path):
    """/constants/surfaces/{kind, axis_u, size, two_sided} of a run with a finite plate open in
    xarray + h5netcdf on the `surface`, `xyz` and `side` dimensions, with their units."""
    from helpers import make_scene, paper_raw

    raw = paper_raw()
    raw["shot"]["count"] = 32
    plate = {"kind": "rectangle", "point": [4.0, 1.0, 0.0], "normal": [-1.0, 0.0, 0.0], "axis_u": [0.0, 0.0, 1.0]}
    raw["surfaces"] = [raw["surfaces"][0], {**plate, "size": [2.0, 1.0], "restitution": 0.3, "mu_s": 0.2}]
    raw["output"] = {"fields": ["landing"]}
    path = tmp_path / "plate.h5"
    wr.run(make_scene(raw, precision="float64"), path, device="cpu")
    variables = assert_named_like_the_layout(path)
    assert variables["constants/surfaces/size"].dims == ("surface", "side")
    assert variables["constants/surfaces/size"].attrs["units"] == "m"
    assert variables["constants/surfaces/axis_u"].dims == ("surface", "xyz")
    assert list(variables["constants/surfaces/kind"].values) == [0, 1]
