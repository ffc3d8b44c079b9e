"""Plots of run and sweep files as PNGs (`warp-ricochet plot OUT.h5 [-o DIR]`).

`PLOTS` is the registry the command walks: each `Plot` names its file suffix, what it draws from
("run": called once per run file with its root group; "sweep": called once with every sweep file
given, one panel each), its size, and `draw(fig, source) -> bool` (False: nothing to draw, no file).
Adding a plot is one `Plot(...)` line in `PLOTS` (or `register(...)` from another module). The
arrays come from `plotdata` and the drawing from `figures`. Needs matplotlib (the `plot` extra:
`pip install 'warp-ricochet[plot]'`), h5py and numpy; never warp.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import RicochetError
from ..io.atomic import replaced
from ..io.h5open import open_for_reading
from . import figures, hazard_plots, plotdata, rest
from .compare import file_label
from .paper import paper_row
from .papercheck import is_papers
from .tables import ReportError, Results, read_results

__all__ = ["Plot", "PLOTS", "DPI", "PlotError", "register", "require_matplotlib", "planned", "write_plots"]

DPI = 120
EXTRA = "pip install 'warp-ricochet[plot]'"


class PlotError(RicochetError):
    """A plot cannot be made or written (one line)."""


@dataclass(frozen=True)
class Sweep:
    """A sweep file given to the sweep plots: its statistics, open file and column label."""

    results: Results
    file: object
    label: str


@dataclass(frozen=True)
class Plot:
    """One PNG: `name` (file suffix), `kind` ("run" or "sweep"), `size` (inches; a sweep plot's width
    is per file), `draw(fig, source) -> bool`, and what a file it draws nothing of lacks (`missing`)."""

    name: str
    kind: str
    size: tuple[float, float]
    draw: Callable
    missing: str = "no per-pellet landing data in the file"
    counts: bool = False  # drawn from the run's counts, written when it completes (not an unfinished run's)


def require_matplotlib():
    """matplotlib's Figure class, or a one-line PlotError naming the extra that installs it."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise PlotError(f"plot needs matplotlib, which is not installed: {EXTRA}") from None
    return Figure


# ---------------------------------------------------------------------------------------------- run plots


_LANDINGS: dict = {}  # (file name, group name) -> Landings, for the plots of one write_plots call


def _landings(group):
    """`plotdata.read_landings(group)`, read once for all the run plots of one call."""
    key = (str(group.file.filename), group.name)
    if key not in _LANDINGS:
        _LANDINGS[key] = plotdata.read_landings(group)
    return _LANDINGS[key]


def _title(fig, group, what: str):
    name = os.path.basename(str(group.file.filename))
    where = "" if group.name == "/" else f" {group.name}"
    fig.suptitle(f"{what}: {name}{where}")


def draw_landing_map(fig, group) -> bool:
    landings = _landings(group)
    if landings is None:
        return False
    e1, e2 = plotdata.top_view(landings)
    ax1, ax2 = fig.subplots(2, 1)
    figures.landing_map(ax1, ax2, landings, e1, e2, (plotdata.axis_name(e1), plotdata.axis_name(e2)))
    _title(fig, group, "Landing map seen from above" + _read_note(landings))
    return True


def draw_range(fig, group) -> bool:
    landings = _landings(group)
    if landings is None or landings.range is None:
        return False
    ax1, ax2 = fig.subplots(1, 2)
    figures.range_histogram(ax1, landings.range, "range from the last ricochet L, eq. (42) (m)")
    figures.survival_curve(ax2, landings.range)
    ax2.set_xlabel("range from the last ricochet L, eq. (42) (m)")
    ax1.set_title("Distribution")
    ax2.set_title("Survival: share of pellets at least this far")
    _title(fig, group, f"Ricochet range of {landings.range.size:,} landed pellets" + _read_note(landings))
    return True


def draw_energy_distance(fig, group) -> bool:
    landings = _landings(group)
    if landings is None or landings.energy is None:
        return False
    ax = fig.subplots()
    figures.energy_distance(ax, landings.distance, landings.energy, landings.slipped)
    _title(fig, group, "Energy at landing against distance" + _read_note(landings))
    return True


def _read_note(landings) -> str:
    return "" if landings.rows >= landings.total else f" (first {landings.rows:,} of {landings.total:,} pellets)"


# ---------------------------------------------------------------------------------------------- sweep plots


def _x_param(results: Results) -> str | None:
    """The swept key to plot against: mu_s, else the first number swept; None when only vectors
    (shot.envelope_center) are swept."""
    scalars = [p for p in results.params if not any(isinstance(r.get(p), (tuple, list)) for r in results.rows)]
    keys = [p for p in scalars if p.rsplit(".", 1)[-1] == "mu_s"]
    return (keys or scalars or [None])[0]


def _shown(value) -> str:
    return f"({', '.join(f'{x:g}' for x in value)})" if isinstance(value, (tuple, list)) else f"{value:g}"


def _groups(rows, x, params):
    """Rows grouped by the swept values other than x: [(label, rows)]."""
    others = [p for p in params if p != x]
    out: dict = {}
    for row in rows:
        key = tuple(row.get(p) for p in others)
        out.setdefault(key, []).append(row)
    return [(", ".join(f"{p.rsplit('.', 1)[-1]} = {_shown(v)}" for p, v in zip(others, key)), rs) for key, rs in out.items()]


def _paper_points(sweep: Sweep, x: str):
    if x.rsplit(".", 1)[-1] != "mu_s":
        return None
    res, keys, pts = sweep.results, sweep.results.params + sweep.results.tied, []
    for row in res.rows:
        pr = paper_row(row[x])
        if pr is not None and is_papers(res.meta.get("scene_toml", ""), row, keys):
            pts.append((row[x], pr["range_mean"], pr["range_min"], pr["range_max"]))
    return tuple(zip(*pts)) if pts else None


def _log_if_wide(ax, axis: str, values) -> None:
    """A logarithmic `axis` when the positive `values` span more than a factor 10."""
    values = values[np.isfinite(values)]
    if values.size and values.min() > 0 and values.max() > 10 * values.min():
        figures.plain_log(ax, axis)


def _axis_label(key: str) -> str:
    """A swept key with its meaning and unit where known (friction coefficients are dimensionless)."""
    last = key.rsplit(".", 1)[-1]
    names = {
        "mu_s": "static friction coefficient mu_s",
        "mu_d": "dynamic friction coefficient mu_d",
        "restitution": "restitution E",
    }
    return f"{names[last]} ({key})" if last in names else key


def draw_sweep_ranges(fig, sweeps) -> bool:
    """The paper's study as one figure: <L> against the swept key, the L- to L+ band; one panel a
    file, all on one y axis (logarithmic when the ranges drawn span more than a factor 10)."""
    if any(_x_param(sweep.results) is None for sweep in sweeps):
        return False
    axes = np.atleast_1d(fig.subplots(1, len(sweeps), sharey=True))
    drawn = []
    for ax, sweep in zip(axes, sweeps):
        x = _x_param(sweep.results)
        paper = _paper_points(sweep, x)
        for i, (label, rows) in enumerate(_groups(sweep.results.rows, x, sweep.results.params)):
            series = [[r.get(k, math.nan) for r in rows] for k in (x, "range_mean", "range_min", "range_max")]
            figures.sweep_band(ax, *series, label=label or None, color=f"C{i % 10}", paper=paper if i == 0 else None)
        drawn += [r.get(k, math.nan) for r in sweep.results.rows for k in ("range_min", "range_max")]
        drawn += [] if paper is None else [v for column in paper[1:] for v in column]
        ax.set_xlabel(_axis_label(x))
        ax.set_title(f"{sweep.label}: {os.path.basename(str(sweep.results.meta.get('file', '')))}")
        ax.legend(loc="best", fontsize="small")
    axes[0].set_ylabel("ricochet range, eq. (42) (m)")
    for ax in axes:
        _log_if_wide(ax, "y", np.array(drawn, dtype=np.float64))
    fig.suptitle(
        "Mean ricochet range <L> with the L- to L+ band, over the sweep" + (" (panels on one scale)" if len(axes) > 1 else "")
    )
    return True


def draw_sweep_survival(fig, sweeps) -> bool:
    """Each point's range survival curve, coloured by the swept value; one panel a file."""
    import h5py
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    if any(_x_param(sweep.results) is None for sweep in sweeps):
        return False
    drawn, spans = False, []
    axes = np.atleast_1d(fig.subplots(1, len(sweeps)))
    for ax, sweep in zip(axes, sweeps):
        f, x = sweep.file, _x_param(sweep.results)
        values = np.asarray(f["sweep"][x][()], dtype=np.float64)
        norm = Normalize(float(np.nanmin(values)), float(np.nanmax(values)) + (np.nanmax(values) == np.nanmin(values)))
        runs = f.get("runs")
        for i, value in enumerate(values):
            group = runs.get(f"{i:04d}") if isinstance(runs, h5py.Group) else None
            ds = None if group is None else group.get("pellets/landing/range")
            if ds is None:
                continue
            rows = min(plotdata.rows_final(group), plotdata.MAX_ROWS, len(ds))
            ranges = np.asarray(ds[:rows], dtype=np.float64)
            figures.survival_curve(ax, ranges, color=colormaps["viridis"](norm(value)))
            spans.append(ranges[np.isfinite(ranges)])
            drawn = True
        fig.colorbar(ScalarMappable(norm=norm, cmap="viridis"), ax=ax, label=_axis_label(x))
        ax.set_xlabel("range from the last ricochet L, eq. (42) (m)")
        ax.set_title(f"{sweep.label}: {os.path.basename(str(sweep.results.meta.get('file', '')))}")
    for ax in axes:  # one scale type on every panel: logarithmic when any panel's ranges span a factor 10
        _log_if_wide(ax, "x", np.concatenate(spans) if spans else np.zeros(0))
    fig.suptitle("Range survival at each sweep point (log scale: the tail)")
    return drawn


# ---------------------------------------------------------------------------------------------- registry

NO_X = "no swept number to plot against: a file sweeps vector keys (shot.envelope_center) only"

PLOTS: list[Plot] = [
    Plot("landing-map", "run", (10.0, 9.0), draw_landing_map),
    Plot("range", "run", (12.0, 4.8), draw_range),
    Plot("energy-distance", "run", (8.0, 5.5), draw_energy_distance),
    Plot(
        "distance-survival",
        "run",
        (7.0, 4.5),
        hazard_plots.draw_survival,  # docs/hazard.md
        "no landing histograms: output.quantiles = false",
        counts=True,
    ),
    Plot("hazard-map", "run", (8.0, 6.0), hazard_plots.draw_map, "no hazard map: [hazard] map_cell and map_extent", True),
    Plot(
        "rest-distance",
        "run",
        (12.0, 5.0),
        rest.draw_rest_distance,  # docs/ground.md
        'no per-pellet rest and landing positions: physics.until = "rest", output.fields with "rest" and "landing"',
    ),
    Plot("sweep-ranges", "sweep", (6.5, 5.0), draw_sweep_ranges, NO_X),
    Plot("sweep-survival", "sweep", (6.5, 5.0), draw_sweep_survival, NO_X),
]


def register(plot: Plot) -> None:
    """Add a plot to the registry (replacing one of the same name)."""
    PLOTS[:] = [p for p in PLOTS if p.name != plot.name] + [plot]


# ---------------------------------------------------------------------------------------------- command


def _stem(path) -> str:
    name = os.path.basename(os.fspath(path))
    return name[:-3] if name.endswith(".h5") else os.path.splitext(name)[0]


def _read(path) -> Results:
    """`read_results(path)`, its one-line error naming plot's input (`plot = PATH`), not `report`'s."""
    try:
        return read_results(path)
    except ReportError as exc:
        raise PlotError(f"plot = {exc.path!r}: {exc.problem}") from None


def planned(paths, outdir, results=None) -> list[tuple[str, Plot, list]]:
    """[(png path, plot, the input files it draws from)] for input `paths` (their `Results` when read)."""
    results = results or [_read(p) for p in paths]
    runs = [p for p, r in zip(paths, results) if r.kind == "run"]
    sweeps = [p for p, r in zip(paths, results) if r.kind == "sweep"]
    out = []
    for plot in PLOTS:
        if plot.kind == "run":
            out += [(os.path.join(outdir, f"{_stem(p)}-{plot.name}.png"), plot, [p]) for p in runs]
        elif sweeps:
            stem = "+".join(_stem(p) for p in sweeps)
            out.append((os.path.join(outdir, f"{stem}-{plot.name}.png"), plot, sweeps))
    return out


def _check_outdir(outdir, shown: str) -> None:
    """Refuse a PNG folder that is a file or whose parent is missing; `shown`: the key and value named."""
    if os.path.exists(outdir) and not os.path.isdir(outdir):
        raise PlotError(f"{shown}: is not a folder; give a folder for the PNGs (made if missing)")
    parent = os.path.dirname(os.path.abspath(outdir))
    if not os.path.exists(outdir) and not os.path.isdir(parent):
        raise PlotError(f"{shown}: its parent folder does not exist; give a folder in an existing one")


def _check_plan(plan, given: bool, overwrite: bool) -> None:
    """Refuse two inputs whose PNGs would have the same names, and (without `overwrite`) a PNG
    that exists, naming what the user gave: -o DIR (`given`), else the input beside which it goes."""
    first: dict = {}
    for png, _, inputs in plan:
        if png in first:
            a, b = first[png][0], inputs[0]
            if os.path.abspath(a) == os.path.abspath(b):
                raise PlotError(f"plot = {b!r}: is given twice; give each file once")
            raise PlotError(
                f"plot = {b!r}: has the file name of {a!r}, so their PNGs would have the same names; "
                "plot them one at a time into different folders (-o)"
            )
        first[png] = inputs
    if overwrite:
        return
    for png, _, inputs in plan:
        if os.path.lexists(png):
            name = os.path.basename(png)
            if given:
                raise PlotError(f"-o = {os.path.dirname(png)!r}: {name} exists in it; give --overwrite to replace it")
            raise PlotError(f"plot = {inputs[0]!r}: {name} exists beside it; give --overwrite to replace it, or -o DIR")


def write_plots(paths, outdir=None, overwrite=False) -> list[tuple[str, str | None]]:
    """Draw every registered plot of the input files into `outdir` (default: the first file's folder).
    Returns [(png path, None if written else why not)]. Refuses in one line, before drawing anything,
    a missing matplotlib, an unreadable or damaged input (`read_results` checks each file whole:
    io.inputcheck) and an existing PNG unless `overwrite`; every PNG is drawn in memory before the
    folder and the first PNG are written, so a file that fails while drawn leaves nothing behind."""
    figure_class = require_matplotlib()
    paths = [os.fspath(p) for p in paths]
    results = {p: _read(p) for p in paths}  # (first: the default folder is the first input's)
    given = outdir is not None
    outdir = os.fspath(outdir) if given else (os.path.dirname(paths[0]) or ".")
    _check_outdir(outdir, f"-o = {outdir!r}" if given else f"plot = {paths[0]!r}")
    plan = planned(paths, outdir, [results[p] for p in paths])
    _check_plan(plan, given, overwrite)
    done, drawn = [], []
    files = {}
    inputs = []  # (the input(s) being opened or drawn, named if one is damaged)
    try:
        for p in paths:
            inputs = [p]
            files[p] = open_for_reading(p)  # (a killed run's partial: as a SWMR reader)
        for png, plot, inputs in plan:
            fig = figure_class(
                figsize=(plot.size[0] * (len(inputs) if plot.kind == "sweep" else 1), plot.size[1]), dpi=DPI, layout="constrained"
            )
            source = (
                files[inputs[0]]
                if plot.kind == "run"
                else [Sweep(results[p], files[p], label) for p, label in _labels(inputs, results).items()]
            )
            status = results[inputs[0]].meta.get("status", "complete")
            if plot.counts and status != "complete":  # (zeros until then: not "none landed")
                done.append((png, f"nothing to draw (status {status!r}: the run's counts are written when it completes)"))
                continue
            if not plot.draw(fig, source):
                done.append((png, f"nothing to draw ({plot.missing})"))
                continue
            drawn.append((png, _render(fig)))
            done.append((png, None))
    except (KeyError, ValueError, TypeError, OSError, RuntimeError) as exc:  # a damaged file (nothing written yet)
        if isinstance(exc, RicochetError):
            raise
        from ..errors import hdf5_reason

        shown = ", ".join(map(repr, inputs))
        raise PlotError(
            f"plot = {shown}: {'is' if len(inputs) == 1 else 'one is'} damaged; the plot failed ({hdf5_reason(exc)})"
        ) from None
    finally:
        _LANDINGS.clear()
        for f in files.values():
            f.close()
    os.makedirs(outdir, exist_ok=True)
    for png, data in drawn:
        _save(data, png)
    return done


def _render(fig) -> bytes:
    """The figure as PNG bytes (a few hundred kB)."""
    import io

    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=DPI, format="png")
    return buffer.getvalue()


def _save(data: bytes, png) -> None:
    """Write the PNG beside its place, then move it there: a failed write leaves no partial PNG."""
    with replaced(png) as tmp, open(tmp, "wb") as out:
        out.write(data)


def _labels(paths, results) -> dict:
    labels = {p: file_label(results[p]) for p in paths}
    if len(set(labels.values())) < len(labels):
        labels = {p: _stem(p) for p in paths}
    return labels
