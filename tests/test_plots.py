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
REST = ["--set", 'physics.until="rest"', "--set", 'output.fields=["initial", "impact", "landing", "rest"]']  # rest-distance
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
    assert quiet(["run", SCENE, *SMALL, *HAZARD_MAP, *REST, "-o", str(out["run"])]) == 0
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
        if name.endswith("hazard-map.png"):  # sized to the grid's shape (hazard_plots._map_size)
            assert png_size(outdir / name)[0] == size[0], name
        else:
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
    for argv in (
        ["plot", str(tmp_path / "missing.h5")],
        ["plot", str(text)],
        ["plot", str(files["run"]), "-o", str(text)],
        ["plot", str(files["run"]), str(files["run"])],
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(PREFIX), argv


def test_every_plot_error_names_plots_own_argument(files, tmp_path, capsys):
    """Each one-line error of `plot` names what the user typed (an input file as `plot = PATH`, the
    folder as `-o = DIR`), never `report`'s key or an internal `output`; nothing is written."""
    run, text, missing = str(files["run"]), tmp_path / "x.h5", str(tmp_path / "missing.h5")
    text.write_text("not hdf5")
    other = tmp_path / "other"
    other.mkdir()
    (other / "run.h5").write_bytes(files["run"].read_bytes())
    beside = tmp_path / "beside"
    beside.mkdir()
    (beside / "run.h5").write_bytes(files["run"].read_bytes())
    (beside / "run-range.png").write_bytes(b"old")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "run-range.png").write_bytes(b"old")
    cases = [
        (["plot", missing], f"plot = {missing!r}: does not exist"),
        (["plot", str(text)], f"plot = {str(text)!r}: is not an HDF5 file"),
        (["plot", str(tmp_path / "a" / "b.h5")], f"plot = {str(tmp_path / 'a' / 'b.h5')!r}: does not exist"),
        (["plot", run, "-o", str(text)], f"-o = {str(text)!r}: is not a folder"),
        (["plot", run, "--output", str(tmp_path / "no" / "pngs")], f"-o = {str(tmp_path / 'no' / 'pngs')!r}: its parent folder"),
        (["plot", run, run], f"plot = {run!r}: is given twice"),
        (["plot", run, str(other / "run.h5")], f"plot = {str(other / 'run.h5')!r}: has the file name of {run!r}"),
        (
            ["plot", run, "-o", str(tmp_path / "full")],
            f"-o = {str(tmp_path / 'full')!r}: run-range.png exists in it; give --overwrite",
        ),
        (
            ["plot", str(beside / "run.h5")],
            f"plot = {str(beside / 'run.h5')!r}: run-range.png exists beside it; give --overwrite",
        ),
    ]
    for argv, want in cases:
        before = sorted(str(p) for p in tmp_path.rglob("*"))
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(PREFIX + want), (argv, err)
        assert sorted(str(p) for p in tmp_path.rglob("*")) == before, argv


def test_plot_of_a_statistics_only_run_skips_with_a_reason(files, tmp_path, capsys):
    outdir = tmp_path / "png"
    assert main(["plot", str(files["stats"]), "-o", str(outdir)]) == 0
    lines = capsys.readouterr().out.splitlines()
    skipped = [line for line in lines if line.startswith("skipped ")]
    assert len(skipped) == 5 and sum("no per-pellet" in line for line in skipped) == 4
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
    landings = plotdata.Landings(
        position=position,
        distance=None,
        range=None,
        energy=rng.uniform(1, 2, n),
        slipped=None,
        shooter=np.zeros(3),
        up=np.array([0.0, 1.0, 0.0]),
        planes=[],
        rows=n,
        total=n,
    )
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


# ---------------------------------------------------------------------------------------------- figure objects


def _drawn(ax, handle, label) -> bool:
    """A legend entry stands for something drawn: its own artist with data, or (a proxy, e.g. for a
    contour or a danger-distance line) a drawn line or contour of its colour and line style."""
    from matplotlib.colors import same_color
    from matplotlib.lines import Line2D

    if not isinstance(handle, Line2D):
        return True  # patches, collections and error bars are the artists themselves
    if len(handle.get_xdata()) and handle in ax.lines:
        return True
    if handle.get_linestyle() in ("None", " ", "") and handle.get_marker() in (None, "None", "", " "):
        return True  # a note without a symbol (the landing map's horizontal planes) promises no artist
    style, colour = handle.get_linestyle(), handle.get_color()
    any_colour = label.startswith("danger distance")  # one entry a style, its lines in the thresholds' colours
    for line in ax.lines:
        if (
            line is not handle
            and len(line.get_xdata())
            and line.get_linestyle() == style
            and (any_colour or same_color(line.get_color(), colour))
        ):
            return True
    return style == "-" and any(
        hasattr(c, "levels") and any(same_color(e, colour) for e in c.get_edgecolor()) for c in ax.collections
    )  # a contour drawn in that colour


def legend_entries(fig):
    """(axes, handle, label) of every legend of `fig`, and the legends' titles."""
    out, titles = [], []
    for legend in [ax.get_legend() for ax in fig.axes if ax.get_legend()] + list(fig.legends):
        ax = legend.axes if legend.axes is not None and legend.axes in fig.axes else fig.axes[0]
        titles.append(legend.get_title().get_text())
        out += [(ax, h, t.get_text()) for h, t in zip(legend.legend_handles, legend.get_texts())]
    return out, titles


def _hazard_dict(names=("a", "b", "c", "eye"), extent=(40.0, 80.0, -5.0, 5.0), same=3):
    """A map of 40 m x 10 m whose first `same` thresholds have every landing above them (one layer)."""
    rng = np.random.default_rng(3)
    u, v = np.linspace(extent[0], extent[1], 81), np.linspace(extent[2], extent[3], 21)
    count = np.zeros((20, 80), np.int64)
    count[8:12, 10:60] = rng.integers(1, 50, (4, 50))
    above = np.stack([count if i < same else np.where(np.arange(80) < 30, count, 0) for i in range(len(names))])
    r = np.array([[59.0, 59.5] if i < same else [44.0, np.inf] for i in range(len(names))])
    edges = np.geomspace(1.0, 100.0, 401)
    distance_counts = np.zeros((len(names) + 1, 400), np.int64)
    distance_counts[-1, 300:350] = 10  # every landing above every threshold: identical curves
    return {
        "edges": edges,
        "distance_counts": distance_counts,
        "names": list(names),
        "threshold_speed": np.zeros(len(names), bool),
        "fractions": np.array([1e-3, 1e-6]),
        "danger_distance": r,
        "ci_low": r - 0.5,
        "ci_high": r + 0.5,
        "map_count": count,
        "map_above": above,
        "map_energy": np.zeros(len(names)),
        "map_u_edges": u,
        "map_v_edges": v,
        "map_outside": 0,
    }


@pytest.mark.parametrize("plot", [p for p in PLOTS if p.kind == "run"], ids=lambda p: p.name)
def test_every_legend_entry_of_a_run_plot_has_a_drawn_artist(files, plot):
    from matplotlib.figure import Figure

    for name in ("run", "stats"):
        with h5py.File(files[name]) as f:
            fig = Figure(figsize=plot.size, layout="constrained")
            if not plot.draw(fig, f):
                continue
        entries, titles = legend_entries(fig)
        for ax, handle, label in entries:
            assert _drawn(ax, handle, label), (plot.name, name, label)
        for title in titles:  # a title may not promise what no entry shows (the danger distances were one)
            assert "danger" not in title, (plot.name, name, title)


def test_the_hazard_plots_merge_thresholds_that_coincide_and_fit_the_map():
    from matplotlib.figure import Figure

    from warp_ricochet.report import hazard_plots

    d = _hazard_dict()
    fig = Figure(figsize=(8, 6), layout="constrained")  # the registry's size: resized to the grid
    assert hazard_plots.draw_map(fig, d)
    entries, _ = legend_entries(fig)
    labels = [label for _, _, label in entries]
    assert labels == [
        "a, b, c: where above; dashed: danger distance 59.5 m (p = 1e-06)",
        "eye: where above; dashed: danger distance 44 m (p = 0.001)",
    ]  # no shooter: it is at u = 0
    assert all(_drawn(ax, h, label) for ax, h, label in entries)
    fig.draw_without_rendering()  # the constrained layout, as saved
    ax = fig.axes[0]
    box = ax.get_position(original=False)  # the drawn box (equal scales), in figure fractions
    assert box.height > 0.45 and box.width > 0.6, (box, fig.get_size_inches())  # not mostly blank
    assert (ax.get_xlim(), ax.get_ylim()) == ((40.0, 80.0), (-5.0, 5.0))

    d = _hazard_dict(extent=(-10.0, 30.0, -5.0, 5.0))
    fig = Figure(layout="constrained")
    hazard_plots.draw_map(fig, d)
    assert "shooter" in [label for _, _, label in legend_entries(fig)[0]]

    fig = Figure(layout="constrained")
    assert hazard_plots.draw_survival(fig, _hazard_dict(same=4))
    entries, titles = legend_entries(fig)
    assert [label for _, _, label in entries] == [
        "all landings",
        "above a, b, c, eye (every landing)",
        "danger distance, p = 0.001",
        "danger distance, p = 1e-06",
    ]
    assert all(_drawn(ax, h, label) for ax, h, label in entries) and titles == [""]
    ax = fig.axes[0]
    assert ax.get_lines()[1].get_linestyle() != "-"  # dashed over the black curve it would hide


def _sweeps(files):
    from warp_ricochet.report.plots import Sweep
    from warp_ricochet.report.tables import read_results

    return [Sweep(read_results(files[k]), h5py.File(files[k]), k) for k in ("vacuum", "air")]


def test_compared_sweep_panels_have_one_scale_and_the_paper_is_explained(files):
    from matplotlib.figure import Figure

    from warp_ricochet.report.plots import draw_sweep_ranges, draw_sweep_survival

    sweeps = _sweeps(files)
    try:
        fig = Figure(figsize=(13, 5), layout="constrained")
        assert draw_sweep_ranges(fig, sweeps)
        vacuum, air = fig.axes[:2]
        assert vacuum.get_yscale() == air.get_yscale() == "log" and vacuum.get_ylim() == air.get_ylim()
        drawn = [r[k] for s in sweeps for r in s.results.rows for k in ("range_min", "range_max")]
        assert vacuum.get_ylim()[0] <= min(drawn) and max(drawn) <= vacuum.get_ylim()[1]
        paper = [label for _, _, label in legend_entries(fig)[0] if "Zohdi" in label]
        assert len(paper) == 1 and "(27)-(29)" in paper[0]  # why its markers sit far below ours
        errorbar = vacuum.containers[0]
        low = min(float(np.min(seg[:, 1])) for seg in errorbar.lines[2][0].get_segments())
        assert vacuum.get_ylim()[0] <= low  # the paper's L- (17 m) is inside the axes

        fig = Figure(figsize=(13, 5), layout="constrained")
        assert draw_sweep_survival(fig, sweeps)
        panels = [ax for ax in fig.axes if ax.get_lines()]
        assert len(panels) == 2 and {ax.get_xscale() for ax in panels} == {"log"}
        for ax in panels:
            x = np.concatenate([line.get_xdata() for line in ax.get_lines()])
            assert ax.get_xlim()[0] <= x.min() and x.max() <= ax.get_xlim()[1]
            assert any(t.get_text() for t in ax.get_xticklabels())  # a narrow log axis still has numbers
    finally:
        for s in sweeps:
            s.file.close()


def test_the_landing_map_draws_only_planes_as_lines_and_names_other_kinds():
    """A vertical plane is drawn as its line on the ground; a vertical plate or a terrain is not drawn
    as an infinite plane (the legend names it by its kind)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from warp_ricochet.report.figures import _planes

    up, shooter = np.array([0.0, 1.0, 0.0]), np.zeros(3)
    e1, e2 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, -1.0])
    wall, plate, field = (np.array([50.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])), np.array([20.0, 1.0, 0.0]), np.zeros(3)
    planes = [("wall", *wall, "plane"), ("gong", plate, np.array([-1.0, 0.0, 0.0]), "rectangle"), ("field", field, up, "terrain")]
    fig, ax = plt.subplots()
    _planes(ax, planes, shooter, up, e1, e2)
    labels = [line.get_label() for line in ax.get_lines()]
    assert labels == ["wall (plane 0)", "gong: rectangle (surface 1, not drawn)", "field: terrain (surface 2, not drawn)"]
    assert [line.get_label() for line in ax.get_lines() if line.get_xydata().size] == ["wall (plane 0)"]
    plt.close(fig)


def test_plot_of_an_unfinished_run_skips_the_plots_of_its_counts(tmp_path, capsys):
    """An interrupted run's file holds its first chunk's pellets but no landing counts yet (written
    when the run completes): the survival curve and the map are skipped with that reason, not drawn
    empty ("none landed"); the plots of its pellets are drawn."""
    scene = wr.load_scene(SCENE, ["shot.count=140000", "numerics.chunk_size=65536", *HAZARD_MAP[1::2]])

    def stop(done, total):
        if done > 0:  # (Ctrl-C after the first chunk)
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        wr.run(scene, tmp_path / "run.h5", device="cpu", progress=stop)
    outdir = tmp_path / "png"
    assert main(["plot", str(tmp_path / "run.h5.partial"), "-o", str(outdir)]) == 0
    lines = capsys.readouterr().out.splitlines()
    unfinished = "nothing to draw (status 'interrupted': the run's counts are written when it completes)"
    assert [line for line in lines if "survival" in line or "hazard-map" in line] == [
        f"skipped {outdir / f'run.h5-{name}.png'}: {unfinished}" for name in ("distance-survival", "hazard-map")
    ]
    assert sorted(p.name for p in outdir.iterdir()) == [f"run.h5-{n}.png" for n in ("energy-distance", "landing-map", "range")]
