"""Reports: the paper's Tables 1-3 (Zohdi 2021) from an output file or a sweep in memory, as text or Markdown.

`read_results(path)` reads a run or sweep HDF5 file (layout in `io.writer`, docs/output.md) into `Results`: one row
per run / sweep point, a flat dict of the statistics (`tallies.sums.STAT_UNITS`) and the point's swept
and tied values, sorted like the paper (first swept parameter descending). `format_tables` prints
Tables 1-3 in the paper's layout, optionally followed by the paper's own values (`paper`).
`format_run_summary` is the short summary of one run's statistics printed by `warp-ricochet run`.

This module needs h5py and numpy only (never warp), so reports work without a device.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

from .. import display
from ..bound import BoundResult
from ..errors import RicochetError, hdf5_reason
from ..io import bound_out
from ..io.inputcheck import open_valid
from ..io.locks import in_use, writer_gone
from ..scene.units import unit_of
from ..tallies.ensemble import STAT_KIND
from ..tallies.sums import STAT_UNITS
from .hazard_tables import from_file, from_run, tally_lines
from .paper import paper_row
from .papercheck import differences, row_scene
from .rest import not_finished_line, rest_block, rest_rows
from .stations import rows_of_file as station_rows_of_file
from .stations import rows_of_run as station_rows_of_run
from .stations import station_block

__all__ = ["ReportError", "Results", "read_results", "results_from_sweep", "format_tables", "format_run_summary"]

NA = "n/a"


class ReportError(RicochetError):
    """A report input cannot be used (missing, unreadable, not HDF5, not a warp-ricochet file)."""

    def __init__(self, path, problem: str):
        self.path, self.problem = str(path), problem  # (`plot` names its own input: report.plots)
        super().__init__(f"report = {str(path)!r}: {problem}")


@dataclass
class Results:
    """The rows of a report. `params`: swept keys (first one sorts the rows); `tied`: keys following them."""

    rows: list[dict]
    meta: dict = field(default_factory=dict)
    params: list[str] = field(default_factory=list)
    tied: list[str] = field(default_factory=list)

    @property
    def kind(self) -> str:
        return str(self.meta.get("kind", "sweep" if self.params else "run"))


# ---------------------------------------------------------------------------------------------- reading


def _text(value):
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if hasattr(value, "item") and getattr(value, "shape", None) == ():
        return value.item()
    return value


def _key_list(value) -> list[str]:
    if value is None:
        return []
    if isinstance(value, (str, bytes)):
        return [str(_text(value))]
    return [str(_text(v)) for v in value]


def _sort_rows(rows: list[dict], params: list[str]) -> list[dict]:
    """Paper order: by the swept parameters, descending (the paper lists mu_s = 0.5 first); NaN last."""

    def key(row):
        out = []
        for p in params:
            v = row.get(p, math.nan)
            v = float(v) if isinstance(v, (int, float)) else math.nan
            out.append((math.isnan(v), -v if not math.isnan(v) else 0.0))
        return out

    return sorted(rows, key=key) if params else list(rows)


def read_results(path) -> Results:
    """Read a warp-ricochet run or sweep file; raise `ReportError` (one line) for any unusable input."""
    import numpy as np

    path = os.fspath(path)
    if os.path.isdir(path):
        from ..io.sweepdir import folder_progress

        found = folder_progress(path)
        if found is not None:
            raise ReportError(
                path,
                f"is an unfinished sweep: {found[0]} of {found[1]} points complete (its tables are "
                "written when every point is); warp-ricochet sweep ... --resume continues it",
            )
        raise ReportError(path, "is a directory, not an HDF5 file")
    try:
        with open_valid(path, "", lambda problem: ReportError(path, problem)) as f:  # also a killed run's partial
            results = _read_open_file(f, path, np)
    except RicochetError:
        raise
    except (OSError, KeyError, ValueError, TypeError) as exc:  # truncated or otherwise damaged files
        raise ReportError(path, f"cannot be read as a warp-ricochet file: {hdf5_reason(exc)}") from None
    # only a file marked "running" is tested for its writer's lock (after our read: a complete file
    # is never locked here, so a reader opening it meanwhile is not refused)
    if results.meta.get("status") == "running" and writer_gone(results.meta, in_use(path)):
        results.meta["status"] = WRITER_GONE
    return results


WRITER_GONE = "not finished (the writer is gone: killed or crashed; --resume continues it)"


def _read_open_file(f, path, np) -> Results:
    import h5py

    attrs = {k: _text(v) for k, v in f.attrs.items()}  # (format and kind: checked by io.inputcheck)
    kind = attrs["kind"]
    status = attrs.get("status", "unknown")
    stats_group = f.get("stats")
    if not isinstance(stats_group, h5py.Group) or not len(stats_group):
        raise ReportError(path, f"holds no statistics (status = {status!r}): the run did not finish")
    stats = {name: ds[()] for name, ds in stats_group.items() if isinstance(ds, h5py.Dataset)}
    meta = dict(attrs, file=path)
    if kind == "run":
        row = {name: float(np.asarray(v).reshape(-1)[0]) for name, v in stats.items()}
        meta["points"] = meta["points_done"] = 1
        if status != "complete" and "progress/rows" in f and "constants/pellets" in f:  # how far it got
            meta["rows_done"], meta["rows_total"] = int(f["progress/rows"][()]), int(f["constants/pellets"][()])
        if math.isnan(row.get("pellets", math.nan)):  # statistics (and tallies) are written when the run completes
            meta["points_done"] = 0
            return Results(rows=[], meta=meta)
        meta["intervals"] = {
            name: (float(ds.attrs["ci_low"]), float(ds.attrs["ci_high"]))
            for name, ds in stats_group.items()
            if isinstance(ds, h5py.Dataset) and "ci_low" in ds.attrs
        }
        shots_group = stats_group.get("shots")
        meta["shots"] = int(shots_group.attrs.get("shots", 0)) if isinstance(shots_group, h5py.Group) else 0
        meta["tally"] = from_file(f)
        meta["bound"] = bound_out.read(f)  # [hazard.bound]: its outcome (None without)
        meta["stations"] = station_rows_of_file(f)
        return Results(rows=[row], meta=meta)
    sweep = f["sweep"]  # (a group: io.inputcheck)
    params = _key_list(sweep.attrs.get("parameters"))
    tied = _key_list(sweep.attrs.get("tied"))
    values = {key: np.asarray(ds[()], dtype=np.float64) for key, ds in sweep.items() if isinstance(ds, h5py.Dataset)}
    if not params:
        params = [k for k in values if k not in tied]
    missing = [p for p in params if p not in values]
    if missing:
        raise ReportError(path, f"has no /sweep/{missing[0]} dataset for swept parameter {missing[0]!r}")
    points = len(values[params[0]])
    rows = []
    for i in range(points):
        row = {}
        for name, arr in stats.items():
            arr = np.asarray(arr, dtype=np.float64).reshape(-1)
            row[name] = float(arr[i]) if i < arr.size else math.nan
        if math.isnan(row.get("pellets", math.nan)):
            continue  # a point the (interrupted) sweep never ran
        for key, arr in values.items():  # (points,), or (points, 3) for a vector key: a tuple
            row[key] = math.nan if i >= len(arr) else float(arr[i]) if arr.ndim == 1 else tuple(arr[i].tolist())
        rows.append(row)
    meta["points"], meta["points_done"] = points, len(rows)
    return Results(rows=_sort_rows(rows, params), meta=meta, params=params, tied=tied)


def results_from_sweep(results, params, ties=(), meta=None) -> Results:
    """`Results` from the list `api.sweep` returns ([(point, stats)]) when no file was written."""
    rows = [dict(stats, **point) for point, stats in results]
    params = list(params)
    meta = dict(meta or {})
    meta.setdefault("kind", "sweep")
    meta.setdefault("status", "complete")
    meta["points"] = meta["points_done"] = len(rows)
    tied = [t[0] if isinstance(t, (tuple, list)) else str(t) for t in ties]
    return Results(rows=_sort_rows(rows, params), meta=meta, params=params, tied=tied)


# ---------------------------------------------------------------------------------------------- numbers


def _num(x, decimals: int = 3) -> str:
    """Like the paper: fixed decimals with thousands separators; n/a for NaN or missing."""
    if x is None:
        return NA
    try:
        x = float(x)
    except (TypeError, ValueError):
        return str(x)
    if math.isnan(x):
        return NA
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    text = f"{x:,.{decimals}f}"
    return text[1:] if text.startswith("-") and not text.strip("-0.,") else text  # no "-0.000"


def _count(x) -> str:
    try:
        x = float(x)
    except (TypeError, ValueError):
        return NA
    return NA if math.isnan(x) else f"{int(round(x)):,}"


def _param_formatter(values):
    """3 decimals like the paper when that is exact for every value, else the shortest exact form;
    a vector's (a swept shot.envelope_center) as "(x, y, z)", its components so."""
    if any(isinstance(v, (tuple, list)) for v in values):
        one = _param_formatter([x for v in values if isinstance(v, (tuple, list)) for x in v])
        return lambda v: "(" + ", ".join(map(one, v)) + ")" if isinstance(v, (tuple, list)) else one(v)
    finite = [float(v) for v in values if isinstance(v, (int, float)) and math.isfinite(v)]
    if all(abs(v - round(v, 3)) <= 1e-12 * max(1.0, abs(v)) for v in finite):
        return lambda v: _num(v, 3)
    return lambda v: NA if not isinstance(v, (int, float)) or math.isnan(v) else f"{float(v):.6g}"


def _rel(ours, theirs) -> str:
    """Relative difference (ours - paper) / paper as a signed percentage."""
    try:
        ours, theirs = float(ours), float(theirs)
    except (TypeError, ValueError):
        return NA
    if math.isnan(ours) or math.isnan(theirs) or theirs == 0:
        return NA
    return f"{100 * (ours - theirs) / abs(theirs):+,.1f}%"


def frictional_case(row: dict) -> str:
    """All-stick, All-slip, or Mixed: stick+slip (S stick / P slip), from the first-impact counts."""
    stick, slip = row.get("stick", math.nan), row.get("slip", math.nan)
    if any(not isinstance(v, (int, float)) or math.isnan(v) for v in (stick, slip)):
        return NA
    if stick + slip == 0:
        return "No impacts"
    if slip == 0:
        return "All-stick"
    if stick == 0:
        return "All-slip"
    return f"Mixed: stick+slip ({_count(stick)} stick / {_count(slip)} slip)"


# ---------------------------------------------------------------------------------------------- tables


def _label(key: str, params: list[str]) -> str:
    """Column header for a swept key: its last part (mu_s), or the whole key where that is ambiguous."""
    last = key.rsplit(".", 1)[-1]
    return last if sum(p.rsplit(".", 1)[-1] == last for p in params) == 1 else key


def _markdown(text: str) -> str:
    """A cell as Markdown text: `|`, `<`, `>` and `*` backslash-escaped (CommonMark), so `<v_t>`
    reads as itself in the source and on GitHub (HTML entities such as `&lt;` read badly in a terminal)."""
    for c in "\\|<>*":
        text = text.replace(c, "\\" + c)
    return text


def _render(title: str, headers: list[str], rows: list[list[str]], fmt: str, left: set[int] = frozenset()) -> str:
    """A titled table of preformatted cells (tabulate: "simple" text or a Markdown "pipe" table)."""
    from tabulate import tabulate

    align = ["left" if i in left else "right" for i in range(len(headers))]
    headers = [display.header(h) for h in headers]  # (a unit in parentheses: as printed, `display`)
    if fmt == "markdown":
        table = tabulate(
            [[_markdown(c) for c in r] for r in rows],
            [_markdown(h) for h in headers],
            tablefmt="pipe",
            disable_numparse=True,
            colalign=align,
        )
        return f"**{_markdown(title)}**\n\n{table}"
    table = tabulate(rows, headers, tablefmt="simple", disable_numparse=True, colalign=align)
    return "\n".join([title, *(line.rstrip() for line in table.splitlines())])


STAT_SI_UNITS = {name: unit for name, (unit, _doc) in STAT_UNITS.items()}


def shown_rows(rows, params) -> list[dict]:
    """The rows in the printed units (`display`): statistics and swept keys."""
    units = {**STAT_SI_UNITS, **{p: unit_of(p) or "" for p in params}}
    return [display.row(r, units) for r in rows]


def param_header(key: str, params: list[str]) -> str:
    """A swept key's column header (`_label`), with its unit where it is printed in another than SI."""
    si = unit_of(key) or ""
    return _label(key, params) + (f" ({display.unit(si)})" if display.unit(si) != si else "")


def _point_cells(row, params, formatters) -> list[str]:
    return [formatters[p](row.get(p, math.nan)) for p in params] if params else ["run"]


TABLE_TITLES = (
    "Table 1. Pre- and post-impact velocities.",
    "Table 2. Spin and translational and rotational kinetic energies.",
    "Table 3. Post-impact ricochet ranges.",
)
T1 = (("<v_t> (m/s)", "mean_vt"), ("<v_n> (m/s)", "mean_vn"), ("||<omega>|| (rad/s)", "norm_mean_omega"))
T2 = (("<W_T> (J)", "mean_WT"), ("<W_R> (J)", "mean_WR"), ("<W_T>/<W(t=0)>", "ratio_WT"), ("<W_R>/<W(t=0)>", "ratio_WR"))
T3 = (("<L> (m)", "range_mean"), ("L+ (m)", "range_max"), ("L- (m)", "range_min"))


def _tables(rows, point_headers, point_cells, fmt, *, paper_rows=None) -> list[str]:
    """Tables 1-3 of our `rows`; with `paper_rows` ([(our row, the paper's row)]), the paper's values
    beside ours in each table and the relative differences of the ranges."""
    n = len(point_headers)
    left = set(range(n)) if point_headers == ["run"] else set()
    source = [(r, None) for r in rows] if paper_rows is None else paper_rows
    suffix = "" if paper_rows is None else ", ours beside the paper's [paper: Zohdi 2021]"
    paper = paper_rows is not None
    out = []
    # Table 1 and 2: a pre and a post row per point; one pre row when it is the same at every point
    for title, columns in ((TABLE_TITLES[0], T1), (TABLE_TITLES[1], T2)):
        headers = point_headers + ["Time"] + [c for h, _ in columns for c in ((h, "paper") if paper else (h,))]

        def values(mine, theirs, phase, columns=columns):
            cells = []
            for _, stat in columns:
                cells.append(_num(mine.get(f"{phase}_{stat}")))
                if paper:
                    cells.append(_num(theirs.get(f"{phase}_{stat}")))
            return cells

        pre = [values(mine, theirs, "pre") for mine, theirs in source]
        once = len(pre) > 1 and all(cells == pre[0] for cells in pre)
        body = [["all"] * n + ["pre"] + pre[0]] if once else []
        for (mine, theirs), pre_cells in zip(source, pre):
            if not once:
                body.append(point_cells(mine, mine) + ["pre"] + pre_cells)
            body.append(point_cells(mine, mine) + ["post"] + values(mine, theirs, "post"))
        note = " The pre-impact row is the same at every point: shown once." if once else ""
        out.append(_render(title.rstrip(".") + suffix + "." + note, headers, body, fmt, left | {n}))
    # Table 3
    body = []
    if not paper:
        headers = point_headers + [h for h, _ in T3] + ["Frictional case", "L+ slip (m)", "L+ stick (m)"]
        for row, _ in source:
            body.append(
                point_cells(row, row)
                + [_num(row.get(stat)) for _, stat in T3]
                + [frictional_case(row), _num(row.get("range_slip_max")), _num(row.get("range_stick_max"))]
            )
        out.append(_render(TABLE_TITLES[2], headers, body, fmt, left | {n + 3}))
    else:
        headers = (
            point_headers
            + [c for h, _ in T3 for c in (h, "paper")]
            + ["Frictional case", "paper"]
            + ["ours vs paper " + h.split(" (")[0] for h, _ in T3]
        )
        for mine, theirs in source:
            body.append(
                point_cells(mine, mine)
                + [c for _, stat in T3 for c in (_num(mine.get(stat)), _num(theirs.get(stat)))]
                + [frictional_case(mine), theirs.get("case", NA)]
                + [_rel(mine.get(stat), theirs.get(stat)) for _, stat in T3]
            )
        out.append(_render(TABLE_TITLES[2].rstrip(".") + suffix + ".", headers, body, fmt, left | {n + 6, n + 7}))
    return out


def _paper_matches(results: Results):
    """Rows of `results` split by the paper's scene (`papercheck`): ([(row, the paper's row)], rows of
    another scene with their first difference, mu_s values of the paper's scene the paper has no row for)."""
    keys = results.params + results.tied
    matched, other, missing = [], [], []
    for row in results.rows:
        scene = row_scene(results.meta.get("scene_toml", ""), row, keys)
        diffs = differences(scene)
        if diffs:
            other.append((row, diffs))
            continue
        mu_s = float(scene["surfaces"][0]["mu_s"])
        theirs = paper_row(mu_s)
        if theirs is None:
            missing.append(mu_s)
        else:
            matched.append((row, theirs))
    return matched, other, missing


def _given(value) -> str:
    return "absent" if value is None else repr(value)


def _paper_blocks(results: Results, point_headers, point_cells, fmt) -> list[str]:
    """`report --paper`: Tables 1-3 with the paper's values beside ours for the rows whose scene is
    the paper's (apart from friction), and a one-line note for the rows it does not apply to."""
    matched, other, missing = _paper_matches(results)
    blocks = []
    if other:
        row, diffs = other[0]
        key, ours, theirs = diffs[0]
        more = f" and {len(diffs) - 1} more key{'s' if len(diffs) > 2 else ''}" if len(diffs) > 1 else ""
        which = (
            "this run"
            if results.kind == "run"
            else ("any point" if len(other) == len(results.rows) else f"{len(other)} of {len(results.rows)} points")
        )
        blocks.append(
            f"paper: the comparison with Zohdi (2021) does not apply to {which}: the scene differs from "
            f"the paper's (examples/paper.toml) in {key} = {_given(ours)} (paper: {_given(theirs)}){more}"
        )
    if missing:
        values = ", ".join(f"{m:g}" for m in sorted(set(missing)))
        blocks.append(f"paper: Zohdi (2021) has no row for mu_s = {values} (it lists mu_s = 0, 0.05, ..., 0.5)")
    if matched:
        blocks.append(
            "The paper's values (Zohdi 2021, Tables 1-3) beside ours for the same mu_s; its Time "
            "0.000/0.010 is shown as pre/post. The paper's stick rows do not follow its eqs. (27)-(29); "
            "see warp_ricochet.report.paper. Last columns: relative difference (ours - paper) / paper."
        )
        blocks += _tables(None, point_headers, point_cells, fmt, paper_rows=matched)
    return blocks


COLLISION_COLUMNS = (
    ("collided", "collided_fraction", 4),
    ("pair collisions", "pair_collisions", 0),
    ("energy lost (J)", "pair_energy_lost", 4),
    ("lost per pellet (J)", "pair_energy_lost_mean", 6),
    ("dense steps mean", "dense_steps_mean", 1),
    ("dense steps max", "dense_steps_max", 0),
    ("dense time mean (s)", "dense_time_mean", 6),
    ("dense time max (s)", "dense_time_max", 6),
    ("skin overrun max", "skin_overrun_max", 2),
)


def _collision_tables(rows, point_headers, point_cells, fmt) -> list[str]:
    """The collision statistics of rows with pellet-pellet collisions (none for other runs)."""
    rows = [r for r in rows if math.isfinite(r.get("collided_fraction", math.nan))]
    if not rows:
        return []
    left = set(range(len(point_headers))) if point_headers == ["run"] else set()
    body = [point_cells(r, r) + [_num(r.get(stat), d) for _, stat, d in COLLISION_COLUMNS] for r in rows]
    return [
        _render(
            "Pellet-pellet collisions (fraction of pellets that collided, pair collisions, the energy they "
            "lost; the dense phase's steps and duration per shot; skin overrun in half skins).",
            point_headers + [h for h, _, _ in COLLISION_COLUMNS],
            body,
            fmt,
            left,
        )
    ]


def header_line(results: Results) -> str:
    """One line: file, kind, device, status and pellets."""
    meta = results.meta
    parts = []
    if meta.get("file"):
        parts.append(f"file: {meta['file']}")
    if results.kind == "sweep":
        done, total = meta.get("points_done", len(results.rows)), meta.get("points", len(results.rows))
        parts.append(f"sweep: {done} of {total} points" if done != total else f"sweep: {total} points")
        if results.params:
            parts[-1] += " over " + ", ".join(results.params)
        if results.tied:
            parts[-1] += " (tied: " + ", ".join(results.tied) + ")"
    else:
        parts.append("run")
    parts.append(f"device: {meta.get('device', NA)}")
    parts.append(f"status: {meta.get('status', NA)}")
    pellets = sorted(
        {
            int(round(r["pellets"]))
            for r in results.rows
            if isinstance(r.get("pellets"), (int, float)) and math.isfinite(r["pellets"])
        }
    )
    text = ", ".join(f"{p:,}" for p in pellets) or NA
    parts.append(f"pellets: {text}" + (" per point" if results.kind == "sweep" and len(pellets) == 1 else ""))
    return " | ".join(parts)


def format_tables(results: Results, fmt: str = "text", paper: bool = False) -> str:
    """Tables 1-3 in the paper's layout ("text" or "markdown"); with `paper`, the paper's values too."""
    if fmt not in ("text", "markdown"):
        raise ValueError(f"fmt must be 'text' or 'markdown', not {fmt!r}")
    params = list(results.params)
    rows = shown_rows(results.rows, params)  # (SI: results.rows, for the paper's and the per-file blocks)
    formatters = {p: _param_formatter([r.get(p) for r in rows]) for p in params}
    point_headers = [param_header(p, params) for p in params] or ["run"]

    def point_cells(row, _values):
        return _point_cells(row, params, formatters)

    blocks = [header_line(results)]  # followed by a blank line: never a Markdown table
    if "rows_done" in results.meta:  # an unfinished run file (NAME.h5.partial)
        done, total = results.meta["rows_done"], results.meta["rows_total"]
        status = results.meta.get("status")
        said = "the run's writer is gone (killed or crashed)" if status == WRITER_GONE else f"status is {status!r}"
        blocks.append(
            f"note: {said}: {done:,} of {total:,} pellets complete "
            f"({100 * done / max(total, 1):.1f}%); the statistics are written when the run completes "
            "(warp-ricochet run ... --resume continues it)"
        )
    elif results.meta.get("status", "complete") != "complete":
        blocks.append(f"note: status is {results.meta.get('status')!r}; the tables show the points that finished")
    blocks += _tables(rows, point_headers, point_cells, fmt)
    blocks += _collision_tables(rows, point_headers, point_cells, fmt)
    if results.meta.get("intervals") and len(results.rows) == 1:
        blocks.append(format_intervals(results.rows[0], results.meta["intervals"], results.meta.get("shots", 0), fmt))
    if paper:
        blocks += _paper_blocks(results, point_headers, point_cells, fmt)
    if results.kind == "run" and results.rows and rest_block(results.rows[0]):
        blocks.append(rest_block(results.rows[0]))
    if results.meta.get("tally") is not None:
        blocks.append("\n".join(tally_lines(results.meta["tally"], results.rows[0].get("pellets", 0.0))))
    if results.meta.get("bound") is not None:
        blocks.append(BoundResult.of(results.meta["bound"]).summary())
    if results.meta.get("stations"):
        blocks.append(station_block(results.meta["stations"], fmt))
    return "\n\n".join(blocks) + "\n"


def format_run_summary(stats: dict, output=None, device=None, scene=None) -> str:
    """A short summary of one run's statistics, with units (`scene`: its named places' names)."""

    def unit(name):
        u = display.unit(STAT_UNITS.get(name, ("", ""))[0])
        return "" if u == "1" else f" {u}"

    def val(name, decimals=3):
        return _num(display.value(stats.get(name), STAT_SI_UNITS.get(name, "")), decimals) + unit(name)

    lines = []
    if output is not None:
        lines.append(f"wrote {output}" + (f" (device {device})" if device else ""))
    elif device:
        lines.append(f"device {device} (no output file)")
    rows = [
        ("pellets", _count(stats.get("pellets"))),
        ("hits", f"{_count(stats.get('hits'))} ({frictional_case(stats)})"),
        ("stick", _count(stats.get("stick"))),
        ("slip", _count(stats.get("slip"))),
        ("landed", _count(stats.get("landed"))),
        ("hit, never landed", _count(stats.get("escaped"))),  # (the end state "escaped" is another count: rest_rows)
        ("missed", _count(stats.get("missed"))),
        *([("entered at the first impact", _count(stats.get("entered")))] if stats.get("entered", 0) > 0 else []),
        ("mean v_t pre/post", f"{val('pre_mean_vt')} / {val('post_mean_vt')}"),
        ("mean v_n pre/post", f"{val('pre_mean_vn')} / {val('post_mean_vn')}"),
        ("mean range <L>", val("range_mean")),
        ("L+ (longest)", val("range_max")),
        ("L- (shortest)", val("range_min")),
        ("mean W_T at landing", val("landing_mean_WT", 6)),
        *rest_rows(stats),
    ]
    if math.isfinite(stats.get("collided_fraction", math.nan)):
        rows += [
            ("collided (fraction)", _num(stats.get("collided_fraction"), 4)),
            ("pair collisions", _count(stats.get("pair_collisions"))),
            ("energy lost in them", f"{val('pair_energy_lost', 4)} ({val('pair_energy_lost_mean', 6)} per pellet)"),
            ("dense steps mean/max", f"{_num(stats.get('dense_steps_mean'), 1)} / {_count(stats.get('dense_steps_max'))}"),
            ("dense time mean/max", f"{val('dense_time_mean', 6)} / {val('dense_time_max', 6)}"),
        ]
    width = max(len(k) for k, _ in rows)
    lines += [f"{k.ljust(width)}  {v}" for k, v in rows]
    lines += [line for line in (not_finished_line(stats),) if line]
    lines += tally_lines(from_run(stats, scene), stats.get("pellets", 0.0))
    if getattr(stats, "bound", None) is not None:  # [hazard.bound]: the pellets it took, the final interval
        lines += ["", stats.bound.summary()]
    if getattr(stats, "stations", None):
        lines += ["", station_block(station_rows_of_run(stats))]
    ensemble = getattr(stats, "ensemble", None)
    if ensemble is not None:
        intervals = {name: (ensemble.low[name], ensemble.high[name]) for name in ensemble.low}
        lines += ["", format_intervals(stats, intervals, ensemble.shots, "text", SUMMARY_INTERVALS)]
    return "\n".join(lines) + "\n"


SUMMARY_INTERVALS = (
    "landed",
    "post_mean_vt",
    "range_mean",
    "range_std",
    "range_max",
    "range_min",
    "landing_mean_WT",
    "collided_fraction",
    "pair_energy_lost_mean",
    "rest_distance_mean",
    "rest_distance_max",
    "rest_not_finished",
)


def _interval_decimals(value, low, high) -> int:
    """Decimals that show an interval's width to two significant digits, at most 7 significant
    digits of the value (4 for an interval of zero width)."""
    width = abs(float(high) - float(low))
    if not math.isfinite(width) or width == 0:
        return 4
    d = 1 - math.floor(math.log10(width))
    value = abs(float(value))
    if math.isfinite(value) and value > 0:
        d = min(d, 6 - math.floor(math.log10(value)))
    return int(min(10, max(0, d)))


def format_intervals(row: dict, intervals: dict, shots: int, fmt: str, names=None) -> str:
    """The 95% intervals over shots of a run of several shots (`tallies.ensemble`), apart from the
    value over all shots: each statistic over every pellet of the run ("all shots"; for L+ and L-
    the extreme of all shots), the mean of its per-shot values (the centre of the Student t
    interval) and the interval, which is of a shot's mean, of one shot's extreme, or of the total
    of all shots. Counts are whole numbers."""
    body = []
    for name in names or STAT_UNITS:
        if name not in intervals or name not in row:
            continue
        si = STAT_UNITS[name][0]
        unit = display.unit(si)
        low, high = (display.value(x, si) for x in intervals[name])
        x = display.value(row[name], si)
        kind = STAT_KIND.get(name)
        over = {"extreme": "one shot's extreme", "total": "total of all shots"}.get(kind, "per shot")
        centre = 0.5 * (float(low) + float(high))  # Student t: symmetric about the mean over shots
        if kind == "total" and unit == "1":  # counts
            cells = [_count(x), _count(centre), _count(low), _count(high)]
        else:
            d = _interval_decimals(x, low, high)
            cells = [_num(x, d), _num(centre, d), _num(low, d), _num(high, d)]
        body.append([name, *cells, "" if unit == "1" else unit, over])
    title = (
        f"95% confidence intervals over {shots:,} shots (Student t over the per-shot values in /stats/shots; "
        'docs/output.md). "all shots": the statistic over every pellet of the run, for L+ and L- the '
        "extreme of all shots, which lies outside the interval of one shot's extreme by design, and for "
        'range_std the spread with the shots\' differences; "mean over shots": the mean of the per-shot '
        "values, the interval's centre."
    )
    return _render(
        title, ["statistic", "all shots", "mean over shots", "95% low", "95% high", "unit", "interval of"], body, fmt, {0, 5, 6}
    )
