"""`warp-ricochet report RUN.h5 --html` (issue 26, part 3; docs/hazard.md, "The report"): the scene key
`[[hazard.references]]` and its datasets, the page's text against the run file's numbers (always),
the page opened in headless Chromium (a screenshot that is not blank, the numbers in its DOM text;
skipped only without `chromium`), the named places and outlines when the file has them, and bad
input refused in one line before anything is written."""

import html.parser
import math
import re
import shutil
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

import warp_ricochet as wr
from tests.helpers import cli
from warp_ricochet.errors import SceneError
from warp_ricochet.report import html as report_html
from warp_ricochet.report.html_data import fmt, journee_distance
from warp_ricochet.scene import load_scene, scene_from_dict

ROOT = Path(__file__).resolve().parents[1]
SHORT = 50.0  # m: a reference every bounded danger distance of the run lies beyond


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    """A real run of examples/hazard.toml (14 shots: 3,920 pellets, enough to bound p = 1e-3 of the
    corneal threshold; to rest, on the CPU) with two references."""
    refs = "[{name = 'CPSA shot fall', distance = 275.0, source = 'CPSA'}, {name = 'short', distance = 50.0}]"
    scene = load_scene(
        ROOT / "examples" / "hazard.toml",
        ["shot.shots=14", 'output.fields=["landing", "hazard", "rest"]', f"hazard.references={refs}"],
    )
    path = tmp_path_factory.mktemp("html") / "run.h5"
    wr.run(scene, path, device="cpu")
    return path


class _Text(html.parser.HTMLParser):
    """The text of a page (scripts and styles left out) and its tables' rows as lists of cell texts."""

    def __init__(self):
        super().__init__()
        self.parts, self.rows, self._skip, self._cell = [], [], 0, None

    def handle_starttag(self, tag, attrs):
        if tag in ("style", "script"):
            self._skip += 1
        elif tag == "tr":
            self.rows.append([])
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("style", "script"):
            self._skip -= 1
        elif tag in ("td", "th") and self._cell is not None:
            self.rows[-1].append(" ".join("".join(self._cell).split()))
            self._cell = None

    def handle_data(self, data):
        if not self._skip:
            self.parts.append(data)
            if self._cell is not None:
                self._cell.append(data + " ")

    @property
    def text(self):
        return " ".join(" ".join(self.parts).split())


def _parse(text):
    p = _Text()
    p.feed(text)
    return p


def _numbers(path):
    """The run's danger distances, intervals, quantiles and tail fractions as the page formats them."""
    with h5py.File(path, "r") as f:
        d = {k: f[f"hazard/danger_distance/{k}"][()] for k in ("distance", "ci_low", "ci_high")}
        out = [fmt(x) for x in d["distance"].ravel()]
        out += [f"[{fmt(lo)}, {fmt(hi)}]" for lo, hi in zip(d["ci_low"].ravel(), d["ci_high"].ravel())]
        out += [fmt(x) for x in f["stats/quantiles/distance"][()]] + [fmt(x) for x in f["stats/quantiles/rest_distance"][()]]
        out += [fmt(x) for x in f["stats/tail/fraction"][()]]
        out.append(f"{int(f['stats/pellets'][()]):,}")
    return out


# ---------------------------------------------------------------------------------------------- the key


def test_references_key_round_trips_and_bad_values_are_one_line():
    refs = "[{name = 'CPSA', distance = 275.0, source = 'CPSA guidance'}, {name = 'BSA', distance = 274.32}]"
    scene = load_scene(ROOT / "examples" / "hazard.toml", [f"hazard.references={refs}"])
    assert [(r.name, r.distance, r.source) for r in scene.hazard.references] == [
        ("CPSA", 275.0, "CPSA guidance"),
        ("BSA", 274.32, ""),
    ]
    import tomllib

    assert scene_from_dict(tomllib.loads(scene.to_toml())) == scene
    assert "references" not in load_scene(ROOT / "examples" / "hazard.toml", ["hazard.references=[]"]).to_toml()
    for bad, key in (
        ("[{name = 'a'}]", "hazard.references.0.distance"),
        ("[{name = 'a', distance = -1.0}]", "hazard.references.0.distance"),
        ("[{name = 'a', distance = 1.0, src = 'x'}]", "hazard.references.0.src"),
        ("[{name = 'a', distance = 1.0}, {name = 'a', distance = 2.0}]", "hazard.references.1.name"),
        ("[{name = '', distance = 1.0}]", "hazard.references.0.name"),
        ("[1]", "hazard.references.0"),
        ("3", "hazard.references"),
    ):
        with pytest.raises(SceneError) as exc:
            load_scene(ROOT / "examples" / "hazard.toml", [f"hazard.references={bad}"])
        message = str(exc.value)
        assert message.startswith(key + " =") and "\n" not in message, message


def test_references_are_written_into_the_run_file(run_file):
    with h5py.File(run_file, "r") as f:
        g = f["hazard/references"]
        assert [n.decode() for n in g["name"][()]] == ["CPSA shot fall", "short"]
        assert g["distance"][()].tolist() == [275.0, 50.0]
        assert [s.decode() for s in g["source"][()]] == ["CPSA", ""]
        for name in ("name", "distance", "source"):
            assert "units" in g[name].attrs and g[name].attrs["description"]
        assert g["distance"].attrs["units"] == "m"


def test_journees_rule_is_2200_yards_per_inch():
    assert journee_distance(0.0254) == pytest.approx(2200 * 0.9144)  # 1 inch shot: 2,200 yd
    assert journee_distance(0.1 * 0.0254) == pytest.approx(201.168)  # 0.1 in: 220 yd


# ------------------------------------------------------------------------------------------ the page


def test_the_page_holds_the_runs_numbers_and_the_comparisons(run_file, tmp_path):
    out = tmp_path / "report.html"
    rc, stdout, err = cli(["report", run_file, "--html", out])
    assert (rc, err) == (0, "") and stdout == f"wrote {out}\n"
    page = _parse(out.read_text())
    for number in _numbers(run_file):
        assert number in page.text, number
    with h5py.File(run_file, "r") as f:
        diameter = 2 * f["constants/radius"][()]
        d = {k: f[f"hazard/danger_distance/{k}"][()] for k in ("distance", "ci_low", "ci_high")}
        names = [n.decode() for n in f["hazard/thresholds/name"][()]]
        landings = f["hazard/thresholds/landings"][()]
    journee = journee_distance(diameter)
    assert f"{fmt(journee)} m" in page.text and "2200 x shot diameter in inches" in page.text
    header = next(r for r in page.rows if r[:2] == ["threshold", "p"])
    columns = {
        name: header.index(next(h for h in header if h.startswith(name))) for name in ("CPSA shot fall", "short", "Journee")
    }
    rows = [r for r in page.rows if len(r) == len(header) and r[0] in names]
    assert len(rows) == d["distance"].size
    for row in rows:
        i, j = names.index(row[0]), [f"{p:g}" for p in (1e-3, 1e-5)].index(row[1])
        x, lo, hi = d["distance"][i, j], d["ci_low"][i, j], d["ci_high"][i, j]
        assert landings[i] > 0 and row[2] == fmt(x)
        for name, reference in (("CPSA shot fall", 275.0), ("short", SHORT), ("Journee", journee)):
            cell = row[columns[name]]
            expected = "inside" if hi < reference else "OUTSIDE" if lo > reference else "undecided"
            side = "beyond" if x > reference else "short of"
            assert cell == f"{expected} {fmt(abs(x - reference))} m ({fmt(abs(100 * (x - reference) / reference))}%) {side} it", (
                cell
            )
    assert any(r[columns["short"]].startswith("OUTSIDE") for r in rows)  # (the test sees each verdict)
    assert any(r[columns["CPSA shot fall"]].startswith("inside") for r in rows)
    assert "Pellets do not collide" in page.text and "float32" in page.text  # the limits that apply
    assert page.text.count("data:image/png") == 0 and out.read_text().count('src="data:image/png;base64,') == 3


def test_units_imperial_gives_the_pages_lengths_in_yards_and_speeds_in_feet_per_second(run_file, tmp_path):
    out = tmp_path / "imperial.html"
    rc, _stdout, err = cli(["report", run_file, "--html", out, "--units", "imperial"])
    assert (rc, err) == (0, "")
    page = _parse(out.read_text())
    with h5py.File(run_file, "r") as f:
        d = f["hazard/danger_distance/distance"][()]
        diameter = 2 * f["constants/radius"][()]
        speed = f["hazard/thresholds/speed"][()]
    header = next(r for r in page.rows if r[:2] == ["threshold", "value"])
    assert header[2] == "as a speed (ft/s)" and header[5:7] == ["danger distance (yd)", "95% interval (yd)"]
    rows = [r for r in page.rows if len(r) == len(header) and r[4] in ("0.001", "1e-05")]
    assert rows and {r[5] for r in rows} <= {fmt(x / 0.9144) for x in d.ravel()} | {"none above"}
    assert {r[2] for r in rows} <= {fmt(v / 0.3048) for v in speed}
    assert f"{journee_distance(diameter) / 0.9144:.4g} yd" in page.text and "--units imperial" in page.text
    assert " m/s" not in page.text.split("TOML")[0] and "launched at " in page.text and " ft above " in page.text


def _texts(fig) -> list[str]:
    """Every text a figure shows: titles, axis and colour-bar labels, legends, annotations."""
    out = [fig.get_suptitle()] + [t.get_text() for legend in fig.legends for t in legend.get_texts()]
    for ax in fig.axes:
        out += [ax.get_title(), ax.get_xlabel(), ax.get_ylabel(), *(t.get_text() for t in ax.texts)]
        out += [t.get_text() for t in ax.get_legend().get_texts()] if ax.get_legend() else []
    return [t for t in out if t]


def test_units_imperial_draws_every_figure_in_yards_with_the_tables_numbers(run_file):
    """--units imperial (issue 28): each figure of the page is the metric one with every length in
    yards (the axes, every line: the danger circles, outlines, curves and danger lines, the named
    places; the map's densities per ft^2), labelled so, with no metre left; the danger distances
    the map's legend names are the table's cells, its circles are drawn at them, and the survival
    figure's lines are at the file's landing danger distances."""
    from warp_ricochet import display
    from warp_ricochet.report import html_data

    with h5py.File(run_file, "r") as f:
        metric = report_html.drawn(f)
        with display.using("imperial"):
            imperial = report_html.drawn(f)
            table = html_data.danger_rows(f, float(f["stats/pellets"][()]))
        landing_danger = f["hazard/landing_danger_distance/distance"][()]
    assert [t for t, _, _ in imperial] == ["The map", "Landings beyond a distance", "Where the pellets end"]
    yard, foot = 0.9144, 0.3048
    for (title, fig_m, _), (_, fig_i, caption) in zip(metric, imperial, strict=True):
        texts = _texts(fig_i)
        assert "metre" not in caption, caption
        assert not [t for t in texts if re.search(r"\(m\)| m\b|m\$\^2", t)], (title, texts)
        assert len(fig_m.axes) == len(fig_i.axes)
        for ax_m, ax_i in zip(fig_m.axes, fig_i.axes):
            scale = []
            for label_m, label_i in ((ax_m.get_xlabel(), ax_i.get_xlabel()), (ax_m.get_ylabel(), ax_i.get_ylabel())):
                assert label_i == label_m.replace("(m)", "(yd)").replace("per m$^2$", "per ft$^2$"), (label_m, label_i)
                scale.append(1 / yard if "(m)" in label_m else 1.0)
            assert len(ax_m.lines) == len(ax_i.lines)
            for line_m, line_i in zip(ax_m.lines, ax_i.lines):
                xy_m, xy_i = np.asarray(line_m.get_xydata(), float), np.asarray(line_i.get_xydata(), float)
                np.testing.assert_allclose(xy_i, xy_m * scale, rtol=1e-12, err_msg=title)
            for mesh_m, mesh_i in zip(ax_m.collections, ax_i.collections):  # the map's densities: per ft^2
                if "QuadMesh" in type(mesh_m).__name__:
                    np.testing.assert_allclose(mesh_i.get_array(), mesh_m.get_array() * foot**2, rtol=1e-12)
    _, fig, caption = imperial[0]
    assert "per square foot" in caption and any("(yd)" in t for t in _texts(fig))
    cells = {(row["name"], c["p"]): c["distance"] for row in table["rows"] for c in row["cells"]}
    named = [re.fullmatch(r"(.+): where above; dashed: danger distance (\S+) yd \(p = (\S+)\)", t) for t in _texts(fig)]
    named = [m for m in named if m]
    radii = sorted(
        round(float(np.hypot(*line.get_xydata().T).max()), 6) for line in fig.axes[0].lines if line.get_linestyle() == "--"
    )
    assert named and len(named) == len(radii)
    for m in named:
        for name in m.group(1).split(", "):
            assert cells[(name, m.group(3))] == m.group(2), (name, m.group(0))
        assert any(abs(r - float(m.group(2))) <= 5e-4 * r for r in radii), (m.group(0), radii)
    vertical = [line.get_xdata() for line in imperial[1][1].axes[0].lines if len(line.get_xdata()) == 2]  # (axvline)
    drawn_lines = {round(float(x[0]), 6) for x in vertical if x[0] == x[1]}
    want = {round(x / yard, 6) for x in landing_danger.ravel() if np.isfinite(x)}
    assert drawn_lines == want and want


def test_the_named_places_and_the_outlines_when_the_file_has_them(run_file, tmp_path, monkeypatch):
    run = tmp_path / "run.h5"
    shutil.copy(run_file, run)
    with h5py.File(run, "a") as f:  # /hazard/points as issue 26's contract lays it out (values made up here)
        if "hazard/points" in f:  # (the example's own places: replaced)
            del f["hazard/points"]
        g, k = f.create_group("hazard/points"), len(f["hazard/thresholds/name"])
        g["name"] = np.asarray([b"footpath", b"car park"])
        g["position"] = np.asarray([[60.0, 0.0, 2.0], [75.0, 0.0, -3.0]])
        g["area"] = np.full(2, 0.7)
        g["radius"] = np.full(2, 0.7 / 3.6)
        g["pellets"] = np.arange(2 * k, dtype=np.int64).reshape(2, k)
        g["probability"] = np.linspace(0.01, 0.3, 2 * k).reshape(2, k)
        g["ci_low"], g["ci_high"] = g["probability"][()] / 2, g["probability"][()] * 2
        g["expected_per_shot"] = g["probability"][()] * 1.5
        g["expected_ci_low"], g["expected_ci_high"] = g["expected_per_shot"][()] / 2, g["expected_per_shot"][()] * 2
        g.attrs["pellets_per_shot"] = 280

    class Square:
        exterior = type("Ring", (), {"coords": [(50.0, -2.0), (70.0, -2.0), (70.0, 2.0), (50.0, 2.0), (50.0, -2.0)]})()

    drawn = []
    monkeypatch.setattr(
        report_html, "outline_polygons", lambda group: drawn.append(group.name) or [("corneal_abrasion", 1e-3, Square())]
    )
    out = tmp_path / "places.html"
    report_html.write_html(run, out)
    page = _parse(out.read_text())
    assert drawn == ["/"] and "the danger-area outlines" in page.text
    with h5py.File(run, "r") as f:
        for k, name in enumerate(["footpath", "car park"]):
            row = next(r for r in page.rows if r and r[0] == name)
            for i in range(len(f["hazard/thresholds/name"])):
                p, lo, hi = (f[f"hazard/points/{n}"][k, i] for n in ("probability", "ci_low", "ci_high"))
                assert row[3 + i].startswith(f"{fmt(p)} [{fmt(lo)}, {fmt(hi)}]"), row


# ------------------------------------------------------------------------------------------ bad input


def test_bad_html_paths_and_runs_are_refused_in_one_line(run_file, tmp_path):
    existing = tmp_path / "old.html"
    existing.write_text("keep me")
    unfinished = tmp_path / "unfinished.h5"
    shutil.copy(run_file, unfinished)
    with h5py.File(unfinished, "a") as f:
        f["stats/pellets"][()] = math.nan  # as a run that has not finished leaves it
        f.attrs["status"] = "running"
    cases = [
        (["report", run_file, "--html", tmp_path], "is a folder"),
        (["report", run_file, "--html", existing], "exists; give --overwrite"),
        (["report", run_file, "--html", tmp_path / "no" / "r.html"], "does not exist"),
        (["report", unfinished, "--html", tmp_path / "u.html"], "holds no results"),
        (["report", tmp_path / "missing.h5", "--html", tmp_path / "m.html"], "missing.h5"),
        (["report", run_file, run_file, "--html", tmp_path / "two.html"], "of one run file"),
    ]
    for argv, said in cases:
        rc, out, err = cli(argv)
        assert rc == 2 and out == "" and err.count("\n") == 1 and err.startswith("warp-ricochet: error: "), (argv, err)
        assert said in err, (argv, err)
    assert existing.read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.html", "unfinished.h5"]  # nothing else written
    rc, _, err = cli(["report", run_file, "--html", existing, "--overwrite"])
    assert rc == 0 and existing.read_text().startswith("<!DOCTYPE html>")


# ------------------------------------------------------------------------------------------ the browser


def _chromium():
    return shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(_chromium() is None, reason="Debian's chromium is not installed (apt-get install chromium)")
def test_the_page_in_headless_chromium(run_file, tmp_path):
    from matplotlib.image import imread

    out = tmp_path / "report.html"
    report_html.write_html(run_file, out)
    browser = [_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"]
    png = tmp_path / "shot.png"
    subprocess.run(
        [*browser, f"--screenshot={png}", "--window-size=1200,3000", out.as_uri()], check=True, capture_output=True, timeout=120
    )
    pixels = imread(png)[..., :3]
    assert pixels.shape[:2] == (3000, 1200)
    assert pixels.std() > 0.05  # not blank: text, tables and figures
    assert pixels[:1500].std() > 0.05 and pixels[1500:].std() > 0.05  # the whole height drawn
    dom = subprocess.run([*browser, "--dump-dom", out.as_uri()], check=True, capture_output=True, text=True, timeout=120).stdout
    text = _parse(dom).text
    for number in _numbers(run_file):
        assert number in text, number
    assert "How far pellets stay dangerous" in text and "CPSA shot fall" in text


def _berm_page(tmp_path, until: str, *more) -> str:
    """The HTML report of 64 pellets of the paper's scene with surfaces `more` and a box (the
    berm) behind them, followed to `until`."""
    raw = load_scene(ROOT / "examples" / "paper.toml", ["shot.count=64"]).to_dict()
    box = {"kind": "box", "point": [9.0, 1.0, 0.0], "normal": [0.0, 1.0, 0.0], "axis_u": [1.0, 0.0, 0.0]}
    for surface in (*more, {**box, "name": "berm", "size": [4.0, 30.0, 2.0]}):
        raw["surfaces"].append({**surface, "restitution": 0.3, "mu_s": 0.2})
    raw["physics"]["until"] = until
    if until == "rest":  # (the figure of where the pellets end)
        raw["output"]["fields"] = [*raw["output"]["fields"], "rest"]
    path, out = tmp_path / "berm.h5", tmp_path / "berm.html"
    wr.run(scene_from_dict(raw), path, device="cpu")
    rc, _stdout, err = cli(["report", path, "--html", out])
    assert (rc, err) == (0, "")
    return out.read_text()


def test_a_plate_is_named_by_its_shape_and_the_limits_say_so(tmp_path):
    """The scene's surfaces table names each surface's shape (docs/geometry.md) and the limits
    section says plates are met inside their outline only, and a box's convex edges and corners are
    contacts of their own (docs/geometry.md, "Edges and corners"), not stopped only when the centre
    reaches a triangle (a terrain's ridges are the ones that are no contacts)."""
    plate = {"kind": "rectangle", "point": [4.0, 1.0, 0.0], "normal": [-1.0, 0.0, 0.0], "axis_u": [0.0, 0.0, 1.0]}
    page = _parse(_berm_page(tmp_path, "landing", {**plate, "name": "plate", "size": [2.0, 1.0]}))
    shapes = {r[1]: r[2] for r in page.rows if len(r) > 2 and r[0] in ("0", "1", "2")}
    assert shapes["plate"] == "rectangle 2 m x 1 m, met from its normal's side"
    assert shapes["berm"] == "box 4 m x 30 m x 2 m (12 triangles)"
    assert list(shapes.values())[0] == "infinite plane"
    assert "finite flat plates" in page.text and "surfaces of triangles" in page.text
    assert "grazing a convex edge stopped when its centre reaches the triangle" not in page.text
    assert "convex edges and corners are contacts of their own" in page.text and "terrain's ridges" not in page.text


def test_the_limits_name_the_surfaces_section_and_follow_triangles_to_rest(tmp_path):
    """The limits point to the section whose table lists the surfaces, and do not say a box is
    followed to the landing only in a run that follows it to rest (docs/geometry.md, "Rest on
    triangles")."""
    page = _berm_page(tmp_path, "rest")
    section = re.search(r"not listed in section (\d+)", page).group(1)
    heading = re.search(rf"<h2>{section}\. ([^<]*)</h2>(.*?)<h2>", page, re.S)
    assert "berm" in heading.group(2) and "box 4 m x 30 m x 2 m" in heading.group(2)  # the surfaces' table
    text = _parse(page).text
    assert "surfaces of triangles" in text and "terrain: followed to the landing only" not in text
    # the figures' captions: no thresholds or danger-distance lines in a scene without [hazard], and
    # the landing is the contact after physics.bounces ricochets, not a pellet's first one
    assert "Landings beyond a distance" in text and "above each threshold" not in text and "vertical lines" not in text
    assert "Where the pellets end" in text and "first landed" not in text and "after its physics.bounces" in text


def test_a_mesh_first_is_not_given_a_normal_it_does_not_have():
    """A mesh takes no `normal` (its triangles carry theirs; the scene keeps a default +z): the
    launch height above a mesh ground is along up (-gravity), and its table row shows no normal."""
    from warp_ricochet.report.html_data import _height, _surfaces

    ground = {"name": "mound", "kind": "mesh", "file": "mound.stl", "point": [0.0, 0.5, 0.0], "normal": [0.0, 0.0, 1.0]}
    scene = {"surfaces": [ground], "physics": {"gravity": [0.0, -9.81, 0.0]}}
    assert _height(scene, np.array([0.0, 2.0, 3.0])) == "1.5 m above mound"  # (before: along +z, 3 m)
    (row,) = _surfaces({}, scene)
    assert row["normal"] == "its triangles'" and row["shape"] == "triangle mesh from mound.stl"
