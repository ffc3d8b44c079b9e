"""`warp-ricochet report RUN.h5 --html OUT.html`: one self-contained HTML page a range-safety
reviewer reads (docs/hazard.md, "The report"): the scene, the answers with their 95% intervals, the
map (with the danger-area outlines when `outline_polygons` gives them) and the plots as embedded
PNGs, the probabilities at named places, the numerical settings, the model's limits, and the
danger distances against reference distances. Rendered by the jinja2 template
`templates/report.html.j2` (package data) from `html_data`'s dicts. Needs jinja2 and matplotlib
(`pip install 'warp-ricochet[report]'`), h5py and numpy; never warp.
"""

from __future__ import annotations

import base64
import datetime
import io
import os

import numpy as np

from .. import display
from ..bound import BoundResult
from ..errors import RicochetError
from ..io.atomic import replaced
from ..io.h5open import open_for_reading
from . import hazard_plots, html_data, rest
from .plotdata import scene_dict
from .tables import read_results

EXTRA = "pip install 'warp-ricochet[report]'"
DPI = 110


class HtmlError(RicochetError):
    """The HTML report cannot be written where asked (one line)."""

    def __init__(self, path, problem: str):
        super().__init__(f"--html = {str(path)!r}: {problem}")


def outline_polygons(group):
    """The danger-area outlines (docs/hazard.md section 10, `gis.outline`): [(threshold name, p,
    polygon)] in the map's (u, v) metres, from the exposure layers (a run's passes; an older run's
    landings above each threshold), the outlines the map holds at each of its p; None without the
    `gis` extra, a map or any contained outline."""
    try:
        from ..gis.outline import outline
    except ImportError:
        return None
    if "hazard/map" not in group or "hazard/thresholds" not in group:
        return None
    m, th = group["hazard/map"], group["hazard/thresholds"]
    names = [n.decode() if isinstance(n, bytes) else str(n) for n in th["name"][()]]
    if "exposure" in m:
        counts, off_grid = m["exposure"][()], m["exposure_outside"][()][1:]
    else:
        counts = m["above"][()]
        off_grid = th["landings"][()] - counts.sum(axis=(1, 2))
    u_edges, v_edges = m["u_edges"][()], m["v_edges"][()]
    cell = float(u_edges[1] - u_edges[0])
    out = []
    for i, name in enumerate(names):
        for p in group["hazard/danger_distance/fraction"][()]:
            o = outline(counts[i], int(off_grid[i]), float(p), float(u_edges[0]), float(v_edges[0]), cell)
            if o.geometry is not None:
                out.append((name, float(p), o.geometry))
    return out or None


def _rings(polygon):
    """The exterior rings (k, 2) of a Polygon or MultiPolygon."""
    parts = getattr(polygon, "geoms", None) or [polygon]
    return [np.asarray(p.exterior.coords, dtype=np.float64)[:, :2] for p in parts]


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _map_extras(fig, f, outlines):
    """The outlines and the named places on the hazard map (`draw_map`'s figure, drawn in the
    printed length unit: `display`)."""
    ax = fig.axes[0]
    scale = display.factor("m")
    for k, (name, p, polygon) in enumerate(outlines or []):
        for j, ring in enumerate(_rings(polygon)):
            ring = ring * scale
            ax.plot(
                ring[:, 0], ring[:, 1], color=f"C{(k + 1) % 10}", lw=1.6, label=f"outline {name}, p = {p:g}" if j == 0 else None
            )
    if "hazard/points" in f and "hazard/map/origin" in f:
        m = f["hazard/map"]
        offset = np.asarray(f["hazard/points/position"][()], dtype=np.float64) - m["origin"][()]
        u, v = offset @ m["u_axis"][()] * scale, offset @ m["v_axis"][()] * scale
        ax.plot(u, v, ls="", marker="^", color="C3", markersize=7)
        for x, y, name in zip(u, v, html_data._names(f["hazard/points/name"])):
            ax.annotate(name, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8, color="C3")
    if outlines:  # draw_map's legend again, with the outlines' entries
        for legend in list(fig.legends):
            legend.remove()
        fig.legend(fontsize=7, loc="outside lower center", frameon=False, ncol=2)


def figures(f) -> list[dict]:
    """The report's figures as base64 PNGs: [{title, png, caption}], those the run can draw."""
    return [{"title": title, "png": _png(fig), "caption": caption} for title, fig, caption in drawn(f)]


def drawn(f) -> list[tuple]:
    """The report's figures, [(title, matplotlib Figure, caption)], those the run can draw; lengths
    in the printed unit (`display`: m, or yd with --units imperial, densities per ft^2)."""
    from .plots import require_matplotlib

    figure_class = require_matplotlib()
    out = []
    outlines = outline_polygons(f)
    fig = figure_class(figsize=(8.0, 6.0), layout="constrained")
    if hazard_plots.draw_map(fig, f, "Landings on the map"):
        _map_extras(fig, f, outlines)
        what = "passes within body height" if "hazard/map/passes" in f else "landings"
        caption = (
            f"Grey: {what} per square {'foot' if display.imperial() else 'metre'} (log scale). Coloured contours: where "
            f"{what} above each threshold occur; dashed circles: each threshold's danger distance at the smallest p the run bounds."
        )
        if outlines:
            caption += " Solid coloured lines: the danger-area outlines."
        if "hazard/points" in f:
            caption += " Red triangles: the named places."
        out.append(("The map", fig, caption))
    fig = figure_class(figsize=(7.5, 4.6), layout="constrained")
    if hazard_plots.draw_survival(fig, f):
        caption = "The share of landed pellets at or beyond each distance from the shooter (log scale)."
        if "hazard/thresholds/name" in f:
            caption = (
                "The share of landed pellets at or beyond each distance from the shooter, all of them and those above "
                "each threshold (log scale); vertical lines: the danger distances of the landings (along the path, "
                "the danger distances above are the reach's)."
            )
        out.append(("Landings beyond a distance", fig, caption))
    fig = figure_class(figsize=(12.0, 5.0), layout="constrained")
    if rest.draw_rest_distance(fig, f):
        caption = (
            "Left: where each pellet ends against where it landed (its contact after its physics.bounces ricochets); "
            "right: the share of pellets at least this far."
        )
        out.append(("Where the pellets end", fig, caption))
    return out


def _environment():
    try:
        import jinja2
    except ImportError:
        raise HtmlError("", f"the HTML report needs jinja2, which is not installed: {EXTRA}") from None
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("warp_ricochet.report", "templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.globals.update(unit=display.unit, length=lambda x: display.value(x, "m"))  # (--units: `display`)
    return env


def check_output(path, overwrite: bool) -> str:
    """The HTML path, or a one-line HtmlError: a folder, a missing folder, an existing file without
    `overwrite`."""
    path = os.fspath(path)
    if os.path.isdir(path):
        raise HtmlError(path, "is a folder; give the HTML file's name (e.g. report.html)")
    folder = os.path.dirname(path) or "."
    if not os.path.isdir(folder):
        raise HtmlError(path, f"its folder {folder!r} does not exist")
    if os.path.lexists(path) and not overwrite:
        raise HtmlError(path, "exists; give --overwrite to replace it")
    return path


def context(path, f, results) -> dict:
    """Everything the template shows, from the run file `f` (open) and its `read_results`."""
    scene = scene_dict(f)
    stats = results.rows[0]
    tally = results.meta.get("tally")
    danger = html_data.danger_rows(f, stats.get("pellets", 0.0))
    refs = html_data.references(f)
    return {
        "file": os.path.basename(os.fspath(path)),
        "path": os.path.abspath(os.fspath(path)),
        "created": str(results.meta.get("created", "n/a")),
        "made": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "status": str(results.meta.get("status", "n/a")),
        "version": str(results.meta.get("package_version", "n/a")),
        "warp": str(results.meta.get("warp_version", "n/a")),
        "scene": html_data.scene_words(f, scene, stats),
        "danger": danger,
        "levels": list(html_data.SHOWN_LEVELS),
        "quantiles": html_data.quantile_rows(tally),
        "landed": f"{int(stats.get('landed', 0)):,}",
        "tail": html_data.tail_rows(tally),
        "points": html_data.point_rows(f),
        "references": refs,
        "comparison": html_data.comparison(f, refs),
        "settings": html_data.settings(f, scene, stats),
        "warning": rest.not_finished_line(stats),
        "bound": None if results.meta.get("bound") is None else BoundResult.of(results.meta["bound"]),
        "limits": html_data.limit_flags(scene, bool(danger and danger["reach"])),
        "figures": figures(f),
        "scene_toml": html_data._text(f.attrs.get("scene_toml", "")),
        "imperial": display.imperial(),
    }


def write_html(run, out, overwrite: bool = False) -> str:
    """Write the report of run file `run` to `out`; returns `out`. Every input is checked, and the
    page rendered in memory, before `out` is written (whole, through a temporary file beside it)."""
    out = check_output(out, overwrite)
    env = _environment()
    results = read_results(run)  # one line for a missing, damaged or foreign file
    if results.kind != "run":
        raise HtmlError(out, f"{os.fspath(run)!r} is a {results.kind} file; the HTML report is of one run file")
    if not results.rows:
        raise HtmlError(
            out, f"{os.fspath(run)!r} holds no results (status {results.meta.get('status')!r}): the run did not finish"
        )
    with open_for_reading(run) as f:
        page = env.get_template("report.html.j2").render(**context(run, f, results))
    with replaced(out) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(page)
    return out
