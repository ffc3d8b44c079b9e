"""Table 3 of several output files side by side (`warp-ricochet report A.h5 B.h5`): the same sweep
points in, say, vacuum and air, one group of columns per file, each named by what sets it apart
(vacuum, air, or the file's name). Needs h5py and numpy only (never warp)."""

from __future__ import annotations

import math
import os
import tomllib

from .. import display
from .tables import NA, ReportError, Results, _num, _param_formatter, _point_cells, _render, header_line, param_header, shown_rows

COLUMNS = (("<L> (m)", "range_mean"), ("L+ (m)", "range_max"), ("L- (m)", "range_min"), ("landing <W_T> (J)", "landing_mean_WT"))


def file_label(results: Results) -> str:
    """ "air" for a scene with an [air] table of non-zero density, else "vacuum"."""
    try:
        scene = tomllib.loads(str(results.meta.get("scene_toml", "")))
    except ValueError:
        return os.path.basename(str(results.meta.get("file", "?")))
    air = scene.get("air")
    return "air" if isinstance(air, dict) and air.get("density", 1.0) != 0.0 else "vacuum"


def _labels(all_results) -> list[str]:
    labels = [file_label(r) for r in all_results]
    if len(set(labels)) < len(labels):  # the same kind twice: name them by file
        labels = [os.path.basename(str(r.meta.get("file", label))) for r, label in zip(all_results, labels)]
    return labels


def _key(row, params):
    """A point's swept values, rounded (a vector key's as a tuple of its components)."""
    return tuple(_rounded(row.get(p, math.nan)) for p in params)


def _rounded(value):
    if hasattr(value, "__len__"):  # a tuple, or a row of a (points, 3) array
        return tuple(round(float(x), 12) for x in value)
    return round(float(value), 12)


DISTANCE_LEVELS = (("distance P50 (m)", 0.5), ("distance P99.9 (m)", 0.999))  # from the shooter: landing tallies


def _distances(results: Results) -> dict:
    """Point key -> {column: distance quantile} of each run in the file (its landing tallies,
    `/stats/quantiles/distance` of the run or of each `/runs/NNNN`); empty where the file has none."""
    import h5py
    import numpy as np

    from ..io.h5open import open_for_reading

    params, out = list(results.params), {}
    try:
        with open_for_reading(results.meta["file"]) as f:
            if results.kind == "run":
                groups = [((), f)]
            else:
                values = [np.asarray(f["sweep"][p][()], dtype=np.float64) for p in params]  # (points,) or (points, 3)
                groups = [(_key(dict(zip(params, v)), params), f.get(f"runs/{i:04d}")) for i, v in enumerate(zip(*values))]
            for key, group in groups:
                q = group.get("stats/quantiles/distance") if isinstance(group, h5py.Group) else None
                if isinstance(q, h5py.Dataset):
                    levels = list(np.asarray(group["stats/quantiles"].attrs["levels"], dtype=np.float64))
                    out[key] = {c: float(q[levels.index(lv)]) for c, lv in DISTANCE_LEVELS if lv in levels}
    except (OSError, KeyError, ValueError):  # statistics of a file written without tallies: no columns
        return {}
    return out


def format_side_by_side(all_results: list[Results], fmt: str = "text") -> str:
    """Table 3, the mean translational energy at landing and the distance from the shooter (median
    and P99.9 of the landing tallies) of each file, matched by sweep point."""
    first = all_results[0]
    params = list(first.params)
    for results in all_results[1:]:
        if list(results.params) != params:
            raise ReportError(
                results.meta.get("file", "?"),
                f"sweeps {results.params or 'nothing'}, not {params or 'nothing'} "
                "as the first file: side by side needs the same sweep",
            )
    labels = _labels(all_results)
    shown = [shown_rows(res.rows, params) for res in all_results]  # (the printed units: `display`)
    formatters = {p: _param_formatter([r.get(p) for rows in shown for r in rows]) for p in params}
    by_point = [{_key(r, params): s for r, s in zip(res.rows, rows)} for res, rows in zip(all_results, shown)]
    keys = list(dict.fromkeys(_key(r, params) for res in all_results for r in res.rows))
    headers = [param_header(p, params) for p in params] or ["run"]
    n = len(headers)
    distances = [_distances(res) for res in all_results]
    columns = [c for c, _ in DISTANCE_LEVELS if any(c in d for dist in distances for d in dist.values())]
    headers += [f"{h} {label}" for label in labels for h in [h for h, _ in COLUMNS] + columns]
    body = []
    for key in keys:
        sample = next(rows[key] for rows in by_point if key in rows)
        cells = _point_cells(sample, params, formatters)
        for rows, dist in zip(by_point, distances):
            row = rows.get(key)
            cells += [_num(row.get(stat)) if row is not None else NA for _, stat in COLUMNS]
            cells += [_num(display.value(dist.get(key, {}).get(c), "m")) for c in columns]
        body.append(cells)
    title = "Table 3. Post-impact ricochet ranges, side by side: " + ", ".join(labels)
    if columns:
        title += (
            "; range: eq. (42), from the last ricochet; distance: horizontal, from the shooter to the landing "
            "point (landing quantiles, bin upper edges, <= 0.1% above)"
        )
    blocks = [header_line(r) for r in all_results]
    blocks = ["\n".join(blocks), _render(title, headers, body, fmt, set(range(n)) if not params else set())]
    return "\n\n".join(blocks) + "\n"
