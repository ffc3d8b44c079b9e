"""A station run's per-station results in its run file (docs/output.md, "Stations").

/stations/<name> holds the station's description (attributes, SI: position m, azimuth and elevation
deg as the scene gives them, aim, aim_sigma deg, weight, first_shot, shots, pellets, pieces: the
[first, end) shots of each of its pieces, `bound.station_pieces`) and its own
/stats (the scalars of the run's /stats, of its pellets alone, with their intervals over the
station's shots and /stats/shots when it fires more than one) and, with landing tallies, the run's
tally layout (histograms, quantiles, tails, hazard and map) of its pellets alone. The
combined results stay where a plain run has them. For --resume, /progress/station_tally keeps the
run's cumulative landing counts at each piece's end (row p, once piece p is complete;
/progress/station_tally_rows: the rows it is complete for, -1 before; /stations attribute
piece_ends: the pieces' ends in pellets).
"""

from __future__ import annotations

import numpy as np

from ..bound import station_pieces
from ..scene.stations import station_shots
from ..tallies.counts import TallySetup, TallyTotals
from ..tallies.ensemble import has_ensemble
from ..tallies.sums import STAT_UNITS
from . import tally_out
from .ensemble import create_ensemble_datasets, write_ensemble


def create(group, scene, model, stats) -> None:
    """The /stations groups (values NaN or 0 until the end) and the progress rows for --resume."""
    top = group.create_group("stations")
    top.attrs["description"] = (
        "each station's results alone, in scene order (docs/output.md, Stations); the run's are the combined"
    )
    top.attrs["order"] = [s.name for s in scene.stations]
    pieces = station_pieces(scene)
    ends = [end * scene.shot.count for _first, end, _k in pieces]
    top.attrs["piece_ends"] = np.asarray(ends, dtype=np.int64)
    for k, station in enumerate(scene.stations):
        shots = len(station_shots(pieces, k))
        g = top.create_group(station.name)
        g.attrs.update(
            position=np.asarray(station.position),
            azimuth=np.asarray(station.azimuth),
            elevation=np.asarray(station.elevation),
            aim=station.aim,
            aim_sigma=np.nan if station.aim_sigma is None else station.aim_sigma,
            weight=station.weight,
            first_shot=next(a for a, _b, owner in pieces if owner == k),
            shots=shots,
            pellets=shots * scene.shot.count,
            pieces=np.asarray([(a, b) for a, b, owner in pieces if owner == k], dtype=np.int64),
            units="position m; azimuth, elevation, aim_sigma deg",
        )
        for name in stats:
            ds = g.create_dataset(f"stats/{name}", data=np.nan)
            ds.attrs["units"], ds.attrs["description"] = STAT_UNITS[name]
        if scene.output.quantiles:
            tally_out.create(g, scene, model, progress=False)
        if has_ensemble(scene) and shots > 1:
            create_ensemble_datasets(g, stats, shots)
    if scene.output.quantiles:
        width = TallyTotals(TallySetup.of(scene, model.mass, model.radius, 1.0)).flat().size
        p = group["progress"]
        ds = p.create_dataset(
            "station_tally",
            shape=(len(ends), width),
            dtype=np.int64,
            fillvalue=0,
            chunks=(1, max(1, min(width, 1 << 20))),
            compression="gzip",
            compression_opts=1,
        )
        ds.attrs["units"] = "1"
        ds.attrs["description"] = "the run's cumulative landing counts at each piece's end (TallyTotals.flat)"
        p.create_dataset("station_tally_rows", data=np.full(len(ends), -1, dtype=np.int64)).attrs["units"] = "1"


def store_progress(group, tally, stop: int, ends) -> None:
    """Keep the counts of a chunk that ends a piece (before its rows are committed)."""
    if tally is not None and stop in ends and "station_tally" in group["progress"]:
        k = list(ends).index(stop)
        group["progress/station_tally"][k] = tally.flat()
        group["progress/station_tally_rows"][k] = stop


def read_progress(progress, rows: int) -> dict:
    """piece -> the run's counts at its end as (index, value) of their nonzero elements, for the
    pieces complete by `rows` (read a row at a time: a dense row can be hundreds of MB)."""
    if "station_tally_rows" not in progress:
        return {}
    held, out = progress["station_tally_rows"][()], {}
    for k in np.flatnonzero((held >= 0) & (held <= rows)):
        row = progress["station_tally"][int(k)]
        index = np.flatnonzero(row)
        out[int(k)] = (index, row[index])
    return out


def write(group, stats) -> None:
    """Fill each station's /stats and tallies (`pipeline.RunStats.stations`)."""
    for name, values in (stats.stations or {}).items():
        g = group[f"stations/{name}"]
        for key, value in values.items():
            if f"stats/{key}" in g:
                g[f"stats/{key}"][()] = float(value)
        if values.tally is not None:
            tally_out.write_results(g, values.tally, int(values["landed"]), int(values["pellets"]))
        if values.ensemble is not None:
            write_ensemble(g, values.ensemble)
