"""The per-station table of a run with [[stations]]: a row a station, then the combined (the run's
own statistics), in `warp-ricochet run`'s summary and `warp-ricochet report` (docs/scenes.md)."""

from __future__ import annotations

import math

from .. import display

COLUMNS = (  # (header, statistic, decimals); headers in SI, printed in the chosen units (`display`)
    ("pellets", "pellets", 0),
    ("hits", "hits", 0),
    ("landed", "landed", 0),
    ("mean range <L> (m)", "range_mean", 3),
    ("L+ (m)", "range_max", 3),
    ("mean W_T at landing (J)", "landing_mean_WT", 6),
    ("distance P99 (m)", "distance_p99", 1),  # from the landing tallies: the bin's upper edge
)
UNITS = {"range_mean": "m", "range_max": "m", "distance_p99": "m"}
P99 = 3  # LEVELS.index(0.99) (tallies.quantiles)


def _with_p99(stats) -> dict:
    """The statistics with `distance_p99` from their landing counts (NaN without)."""
    out = dict(stats)
    tally = getattr(stats, "tally", None)
    if tally is not None:
        from ..tallies.quantiles import summarize

        out["distance_p99"] = float(summarize(tally, int(stats["landed"]))["quantiles"]["distance"][0][P99])
    return out


def rows_of_run(stats) -> list[tuple[str, dict]]:
    """[(name, statistics)] of each station of a run's statistics (`pipeline.RunStats.stations`), then the combined."""
    stations = getattr(stats, "stations", None) or {}
    return [(name, _with_p99(part)) for name, part in [*stations.items(), ("combined", stats)]] if stations else []


def rows_of_file(f) -> list[tuple[str, dict]]:
    """The same from an open run file's /stations groups and /stats (empty without stations)."""
    top = f.get("stations")
    if top is None or "stats" not in f:
        return []

    def read(group):
        out = {name: float(group[f"stats/{name}"][()]) for _h, name, _d in COLUMNS if f"stats/{name}" in group}
        if "stats/quantiles/distance" in group:
            out["distance_p99"] = float(group["stats/quantiles/distance"][P99])
        return out

    return [*((str(name), read(top[str(name)])) for name in top.attrs["order"]), ("combined", read(f))]


def station_block(rows, fmt: str = "text") -> str:
    """The table (tabulate: "simple" text or a Markdown "pipe" table); "" without stations."""
    if not rows:
        return ""
    from tabulate import tabulate

    def cell(value, decimals):
        value = float(value) if value is not None else math.nan
        return "n/a" if not math.isfinite(value) else f"{value:,.{decimals}f}"

    body = [
        [name, *(cell(display.value(stats.get(key), UNITS.get(key, "")), d) for _h, key, d in COLUMNS)] for name, stats in rows
    ]
    headers = ["station", *(display.header(h) for h, _k, _d in COLUMNS)]
    table = tabulate(body, headers, tablefmt="pipe" if fmt == "markdown" else "simple", disable_numparse=True)
    title = "Stations (each alone, then combined: the run's statistics above)"
    return f"**{title}**\n\n{table}" if fmt == "markdown" else f"{title}\n{table}"
