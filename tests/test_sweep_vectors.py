"""A sweep over a vector key (shot.envelope_center, a point): /sweep/<key> is (points, 3) with its
unit and the dimensions (point, xyz), and every reader takes it: the file check, the XDMF sidecar,
open_run (xarray), report (tables, side by side) and plot. A scalar key's stays (points,)."""

import shutil
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest

import warp_ricochet as wr
from tests.helpers import cli
from warp_ricochet.io.inputcheck import BadFile, check_file
from warp_ricochet.report import format_tables, read_results
from warp_ricochet.report.compare import format_side_by_side
from warp_ricochet.scene import load_scene
from warp_ricochet.scene.sweep import SweepPoints

SCENE = str(Path(__file__).resolve().parents[1] / "examples" / "paper.toml")
CENTRES = [[0.0, 1.0, 0.0], [0.0, 2.0, 0.5]]
RESTITUTION = [0.01, 0.05]


def _sweep(path, params):
    scene = load_scene(SCENE, ["shot.count=16", "numerics.precision='float64'", 'output.fields=["landing.range"]'])
    with warnings.catch_warnings(record=True) as caught:  # e.g. "the XDMF sidecar ... was not written"
        warnings.simplefilter("always")
        wr.sweep(scene, params, output=path, device="cpu")
    assert [str(w.message) for w in caught] == []
    return path


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    """The centre (slowest) and the restitution swept: 4 points."""
    path = tmp_path_factory.mktemp("vec") / "mixed.h5"
    return _sweep(path, {"shot.envelope_center": CENTRES, "surfaces.0.restitution": RESTITUTION})


@pytest.fixture(scope="module")
def centres(tmp_path_factory):
    """The centre swept alone: 2 points."""
    given = [["0 yd", "100 cm", 0], CENTRES[1]]  # with units, as a scene may give it (docs/scenes.md)
    return _sweep(tmp_path_factory.mktemp("vec") / "centres.h5", {"shot.envelope_center": given})


def _dims(ds) -> list[str]:
    return [dim[0].name.rsplit("/", 1)[-1] for dim in ds.dims]


def test_a_vector_key_is_written_points_by_3_and_a_scalar_key_points(mixed):
    with h5py.File(mixed) as f:
        centre, e = f["sweep/shot.envelope_center"], f["sweep/surfaces.0.restitution"]
        assert centre.shape == (4, 3) and centre.dtype == np.float64 and centre.attrs["units"] == "m"
        assert centre[()].tolist() == [CENTRES[0], CENTRES[0], CENTRES[1], CENTRES[1]]
        assert _dims(centre) == ["point", "xyz"]
        assert e.shape == (4,) and e[()].tolist() == RESTITUTION * 2 and _dims(e) == ["point"]
        check_file(f)  # the file check passes (the sweep raised no warning: above)
    assert mixed.with_suffix(".xmf").is_file()  # the sidecar is written


def test_a_vector_given_with_units_is_written_as_numbers_in_the_key_s_unit(centres):
    with h5py.File(centres) as f:
        assert f["sweep/shot.envelope_center"][()].tolist() == CENTRES
    assert SweepPoints({"shot.speed": ["1350 ft/s", 400]})[0] == {"shot.speed": 1350 * 0.3048}


def test_the_file_check_still_refuses_other_shapes(mixed, tmp_path):
    for shape in [(4, 2), (3, 3), (4, 3, 1)]:
        bad = tmp_path / "bad.h5"
        shutil.copy(mixed, bad)
        with h5py.File(bad, "r+") as f:
            del f["sweep/shot.envelope_center"]
            f["sweep"].create_dataset("shot.envelope_center", data=np.zeros(shape))
        with h5py.File(bad) as f, pytest.raises(BadFile, match="/sweep"):
            check_file(f)


def test_open_run_gives_the_vector_a_dimension_for_its_components(mixed):
    with wr.open_run(mixed) as run:
        centre = run.stats["shot.envelope_center"]
        assert centre.dims == ("point", "xyz") and centre.attrs["units"] == "m"
        assert run.stats["xyz"].values.tolist() == ["x", "y", "z"]
        assert centre.sel(xyz="y").values.tolist() == [1.0, 1.0, 2.0, 2.0]
        assert run.stats["surfaces.0.restitution"].dims == ("point",)
        assert run.stats["landed"].sizes == {"point": 4}
        assert run.to_datatree()["stats"]["shot.envelope_center"].dims == ("point", "xyz")


def test_netcdf_readers_see_the_dimensions(mixed):
    xr = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    with xr.open_dataset(mixed, engine="h5netcdf", group="sweep") as ds:
        assert ds["shot.envelope_center"].dims == ("point", "xyz") and ds.sizes == {"point": 4, "xyz": 3}


def test_report_shows_each_point_s_vector(mixed, centres):
    results = read_results(mixed)
    assert results.meta["points"] == results.meta["points_done"] == 4
    assert sorted({row["shot.envelope_center"] for row in results.rows}) == [tuple(c) for c in CENTRES]
    text = format_tables(results, "text")
    assert text.count("(0.000, 2.000, 0.500)") == 8  # its 2 points: Table 1 (pre, post), 2 (post), 3
    assert "2 points over shot.envelope_center" in format_tables(read_results(centres), "markdown")
    side = format_side_by_side([read_results(centres), read_results(centres)])
    assert "(0.000, 1.000, 0.000)" in side and "(0.000, 2.000, 0.500)" in side


def test_plots_draw_against_the_swept_number_and_skip_a_vector_only_sweep(mixed, centres, tmp_path):
    pytest.importorskip("matplotlib")
    from warp_ricochet.report.plots import write_plots

    done = dict(write_plots([mixed], tmp_path / "mixed"))
    assert done and all(why is None for why in done.values()), done
    done = dict(write_plots([centres], tmp_path / "centres"))
    assert done and all("no swept number" in why for why in done.values()), done


def test_a_tie_to_a_vector_key_is_refused_in_one_line():
    with pytest.raises(wr.SceneError, match=r"^--tie = .*shot.envelope_center is swept over vectors; a tie follows a number$"):
        SweepPoints({"shot.envelope_center": CENTRES}, [("shot.envelope_radius", 0.5, None)])


def test_the_cli_sweeps_a_vector_given_as_a_toml_array(tmp_path):
    out = tmp_path / "cli.h5"
    spec = 'shot.envelope_center=[[0, 1, 0], [0, "200 cm", 0.5]]'
    rc, text, err = cli(["sweep", SCENE, "--device", "cpu", "--set", "shot.count=8", "--param", spec, "-o", out, "-q"])
    assert (rc, err) == (0, "")
    assert "2 points over shot.envelope_center" in text and "(0.000, 2.000, 0.500)" in text
    with h5py.File(out) as f:
        assert f["sweep/shot.envelope_center"][()].tolist() == CENTRES
    assert out.with_suffix(".xmf").is_file()


@pytest.mark.parametrize(
    "spec, problem",
    [
        ("shot.envelope_center=[", "must be KEY=[v1, v2, ...], a TOML array"),
        ("shot.envelope_center=[]", "must be KEY=[v1, v2, ...], a TOML array"),
        ("shot.envelope_center=[[0, 1, 0]]\ny = 2", "must be KEY=[v1, v2, ...], a TOML array"),
        ("shot.envelope_center=[[0, 1]]", "must be a list of 3 numbers (m)"),
        ('physics.until=["landing", "rest"]', "a sweep written to a file takes numbers or vectors of 3 numbers"),
    ],
)
def test_bad_arrays_and_values_no_number_are_refused_before_any_work(tmp_path, spec, problem):
    out = tmp_path / "bad.h5"
    rc, text, err = cli(["sweep", SCENE, "--device", "cpu", "--set", "shot.count=8", "--param", spec, "-o", out, "-q"])
    assert rc == 2 and text == "" and err.count("\n") == 1 and problem in err, err
    assert list(tmp_path.iterdir()) == []
