"""`warp-ricochet plot` (report/plots.py, figures.py, plotdata.py): the PNGs a small run and small
sweeps give (names, sizes, PNG signatures), refusal to overwrite, a one-line error without
matplotlib, and the drawn data against independent NumPy computations. CPU, 200 pellets a point."""

import io
import struct
import sys
from contextlib import redirect_stdout
from pathlib import Path

import h5py
import numpy as np
import pytest

pytest.importorskip("matplotlib")

import warp_ricochet as wr  # noqa: E402
from warp_ricochet.cli import main  # noqa: E402
from warp_ricochet.report import figures, plotdata  # noqa: E402
from warp_ricochet.report.plots import DPI, PLOTS  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "examples" / "paper.toml")
SMALL = ["--set", "shot.count=200", "--device", "cpu"]
SWEEP = ["--param", "surfaces.0.mu_s=0:0.1:0.05", "--tie", "surfaces.0.mu_d=0.9*"]
HAZARD_MAP = ["--set", "hazard.map_cell=1.0", "--set", "hazard.map_extent=[100.0, 140.0, -20.0, 20.0]"]  # docs/hazard.md
PREFIX = "warp-ricochet: error: "


def quiet(argv) -> int:
    with redirect_stdout(io.StringIO()):
        return main(argv)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A run file, a sweep in vacuum and the same sweep in air, and a statistics-only run."""
    d = tmp_path_factory.mktemp("plots")
    out = {"run": d / "run.h5", "vacuum": d / "sweep.h5", "air": d / "sweep-air.h5", "stats": d / "stats.h5"}
    assert quiet(["run", SCENE, *SMALL, *HAZARD_MAP, "-o", str(out["run"])]) == 0
    assert quiet(["sweep", SCENE, *SMALL, *SWEEP, "-o", str(out["vacuum"])]) == 0
    assert quiet(["sweep", SCENE, *SMALL, *SWEEP, "--set", "air.density=1.225", "-o", str(out["air"])]) == 0
    assert quiet(["run", SCENE, *SMALL, "--set", "output.fields=[]", "-o", str(out["stats"])]) == 0
    return out


def png_size(path) -> tuple[int, int]:
    data = Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def expected_size(name: str, panels: int = 1) -> tuple[int, int]:
    plot = next(p for p in PLOTS if p.name == name)
    return round(plot.size[0] * panels * DPI), round(plot.size[1] * DPI)


def test_plot_writes_every_plot_of_a_run_and_of_sweeps_side_by_side(files, tmp_path, capsys):
    outdir = tmp_path / "png"
    assert main(["plot", str(files["run"]), str(files["vacuum"]), str(files["air"]), "-o", str(outdir)]) == 0
    printed = capsys.readouterr().out.splitlines()
    want = {f"run-{p.name}.png": expected_size(p.name) for p in PLOTS if p.kind == "run"}
    want |= {f"sweep+sweep-air-{p.name}.png": expected_size(p.name, 2) for p in PLOTS if p.kind == "sweep"}
    assert sorted(p.name for p in outdir.iterdir()) == sorted(want)  # no temporary files left
    assert sorted(printed) == sorted(f"wrote {outdir / name}" for name in want)
    for name, size in want.items():
        assert png_size(outdir / name) == size, name
        assert (outdir / name).stat().st_size > 20_000, name  # drawn, not blank


def test_plot_of_one_sweep_defaults_to_its_folder(files, tmp_path):
    sweep = tmp_path / "one.h5"
    sweep.write_bytes(files["vacuum"].read_bytes())
    assert quiet(["plot", str(sweep)]) == 0
    assert png_size(tmp_path / "one-sweep-ranges.png") == expected_size("sweep-ranges")
    assert png_size(tmp_path / "one-sweep-survival.png") == expected_size("sweep-survival")


def test_plot_refuses_to_overwrite(files, tmp_path, capsys):
    outdir = tmp_path / "png"
    assert quiet(["plot", str(files["run"]), "-o", str(outdir)]) == 0
    before = {p.name: p.stat().st_mtime_ns for p in outdir.iterdir()}
    capsys.readouterr()
    assert main(["plot", str(files["run"]), "-o", str(outdir)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(PREFIX) and "exists" in err[0] and "--overwrite" in err[0]
    assert {p.name: p.stat().st_mtime_ns for p in outdir.iterdir()} == before
    assert quiet(["plot", str(files["run"]), "-o", str(outdir), "--overwrite"]) == 0


def test_plot_without_matplotlib_is_one_line(files, tmp_path, monkeypatch, capsys):
    for name in [m for m in sys.modules if m == "matplotlib" or m.startswith("matplotlib.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib raises ImportError
    assert main(["plot", str(files["run"]), "-o", str(tmp_path / "png")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(PREFIX) and "warp-ricochet[plot]" in err[0]
    assert not (tmp_path / "png").exists()


def test_plot_bad_inputs_are_one_line(files, tmp_path, capsys):
    text = tmp_path / "x.h5"
    text.write_text("not hdf5")
    for argv in (["plot", str(tmp_path / "missing.h5")], ["plot", str(text)],
                 ["plot", str(files["run"]), "-o", str(text)], ["plot", str(files["run"]), str(files["run"])]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(PREFIX), argv


def test_plot_of_a_statistics_only_run_skips_with_a_reason(files, tmp_path, capsys):
    outdir = tmp_path / "png"
    assert main(["plot", str(files["stats"]), "-o", str(outdir)]) == 0
    lines = capsys.readouterr().out.splitlines()
    skipped = [line for line in lines if line.startswith("skipped ")]
    assert len(skipped) == 4 and sum("no per-pellet" in line for line in skipped) == 3
    assert any("no hazard map" in line for line in skipped)
    # the distance survival curve comes from the on-device histograms (docs/hazard.md): drawn all the same
    assert [p.name for p in outdir.iterdir()] == ["stats-distance-survival.png"]


def test_landing_data_against_numpy(files):
    """Energies, distances and the top view from the stored per-pellet datasets, independently;
    distances from the shooter the tallies use (the envelope centre here: the paper's, (0, 1, 0))."""
    with h5py.File(files["run"]) as f:
        landings = plotdata.read_landings(f)
        mass = f["constants/mass"][()]
        v = f["pellets/landing/velocity"][:].astype(np.float64)
        p = f["pellets/landing/position"][:].astype(np.float64)
        start = np.array([0.0, 1.0, 0.0])
    np.testing.assert_allclose(landings.energy, 0.5 * mass * (v**2).sum(axis=1), rtol=1e-12)
    np.testing.assert_allclose(landings.distance, np.hypot(p[:, 0] - start[0], p[:, 2] - start[2]), rtol=1e-12)
    e1, e2 = plotdata.top_view(landings)
    np.testing.assert_array_equal(e1, [1.0, 0.0, 0.0])  # the paper's shot flies along +x: an axis
    np.testing.assert_allclose(e2, [0.0, 0.0, -1.0])  # seen from +y with x to the right, -z is up the page
    assert landings.rows == landings.total == 200 and landings.slipped.shape == (200,)


def test_drawn_survival_curve_and_density_are_the_data():
    from matplotlib.figure import Figure

    rng = np.random.default_rng(7)
    values = rng.lognormal(3.0, 0.5, 50_000)
    ax = Figure().subplots()
    figures.survival_curve(ax, values)
    x, y = ax.lines[0].get_data()
    ref = np.sort(values)
    for xi, yi in zip(x, y):  # P(X >= x) at every drawn step
        assert yi == np.count_nonzero(values >= xi) / values.size
    assert x[-1] == ref[-1] and y[-1] == 1 / values.size  # the farthest pellet is drawn

    n = 30_000
    position = np.c_[rng.normal(100, 5, n), np.zeros(n), rng.normal(0, 10, n)]
    landings = plotdata.Landings(position=position, distance=None, range=None, energy=rng.uniform(1, 2, n),
                                 slipped=None, shooter=np.zeros(3), up=np.array([0.0, 1.0, 0.0]), planes=[],
                                 rows=n, total=n)
    fig = Figure()
    a1, a2 = fig.subplots(2, 1)
    figures.landing_map(a1, a2, landings, np.array([1.0, 0, 0]), np.array([0, 0, -1.0]))
    mesh = a2.collections[0]
    xb, yb = mesh.get_coordinates()[0, :, 0], mesh.get_coordinates()[:, 0, 1]
    cell = (xb[1] - xb[0]) * (yb[1] - yb[0])
    assert np.isclose(mesh.get_array().sum() * cell, n)  # landings per m^2 integrate to the landings


def test_plot_distances_are_the_tallies_distances(tmp_path):
    """With `[hazard] shooter` set, the plots measure distances from it, as the landing tallies
    do: the largest plotted distance lies in the bin of /stats/quantiles/distance's top level."""
    from warp_ricochet.scene import load_scene

    scene = load_scene(SCENE, ["shot.count=500", 'output.fields=["landing"]', "hazard.shooter=[5.0, 0.0, 3.0]"])
    out = tmp_path / "shooter.h5"
    wr.run(scene, out, device="cpu")
    with h5py.File(out) as f:
        landings = plotdata.read_landings(f)
        p = f["pellets/landing/position"][:].astype(np.float64)
        top, bottom = f["stats/quantiles/distance"][-1], f["stats/quantiles/lower/distance"][-1]
    np.testing.assert_allclose(landings.distance, np.hypot(p[:, 0] - 5.0, p[:, 2] - 3.0), rtol=1e-12)
    assert bottom <= landings.distance.max() <= top
