"""The per-station table of a run with [[stations]]: a row a station, then the combined (the run's
own statistics), in `warp-ricochet run`'s summary and `warp-ricochet report` (docs/scenes.md)."""

from __future__ import annotations

import math

COLUMNS = (  # (header, statistic, decimals)
    ("pellets", "pellets", 0),
    ("hits", "hits", 0),
    ("landed", "landed", 0),
    ("mean range <L> (m)", "range_mean", 3),
    ("L+ (m)", "range_max", 3),
    ("mean W_T at landing (J)", "landing_mean_WT", 6),
)


def rows_of_run(stats) -> list[tuple[str, dict]]:
    """[(name, statistics)] of each station of a run's statistics (`pipeline.RunStats.stations`), then the combined."""
    stations = getattr(stats, "stations", None) or {}
    return [*stations.items(), ("combined", stats)] if stations else []


def rows_of_file(f) -> list[tuple[str, dict]]:
    """The same from an open run file's /stations groups and /stats (empty without stations)."""
    top = f.get("stations")
    if top is None or "stats" not in f:
        return []

    def read(group):
        return {name: float(group[f"stats/{name}"][()]) for _h, name, _d in COLUMNS if f"stats/{name}" in group}

    return [*((str(name), read(top[str(name)])) for name in top.attrs["order"]), ("combined", read(f))]


def station_block(rows, fmt: str = "text") -> str:
    """The table (tabulate: "simple" text or a Markdown "pipe" table); "" without stations."""
    if not rows:
        return ""
    from tabulate import tabulate

    def cell(value, decimals):
        value = float(value) if value is not None else math.nan
        return "n/a" if not math.isfinite(value) else f"{value:,.{decimals}f}"

    body = [[name, *(cell(stats.get(key), d) for _h, key, d in COLUMNS)] for name, stats in rows]
    headers = ["station", *(h for h, _k, _d in COLUMNS)]
    table = tabulate(body, headers, tablefmt="pipe" if fmt == "markdown" else "simple", disable_numparse=True)
    title = "Stations (each alone, then combined: the run's statistics above)"
    return f"**{title}**\n\n{table}" if fmt == "markdown" else f"{title}\n{table}"
