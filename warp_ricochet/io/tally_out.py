"""The landing tallies in a run file (docs/output.md, docs/hazard.md): created with the run (SWMR: no
objects later), their counts kept for --resume after every chunk, their results written at the end.

/progress/tally holds the run's cumulative counts (`TallyTotals.flat`) in two slots used in turn,
/progress/tally_rows the rows each slot is complete for: a chunk writes the slot not holding the
rows committed so far, before it commits its own rows, so one slot always matches /progress/rows.
"""

from __future__ import annotations

import numpy as np

from ..tallies.bins import BINS, RESOLUTION, edges
from ..tallies.counts import TallySetup, TallyTotals
from ..tallies.points import CONFIDENCE, place_statistics
from ..tallies.quantiles import LEVELS, QUANTITIES, REST_QUANTITIES, summarize

HIST_ROWS = "range, speed, then distance of the landings exceeding 0, 1, ... thresholds (hazard levels)"
REACH_ROWS = ", then each threshold's reach along the path (thresholds in scene order; pellets with one)"


def _ds(g, name, data=None, *, unit, doc, **kw):
    ds = g.create_dataset(name, data=data, **kw)
    ds.attrs["units"], ds.attrs["description"] = unit, doc
    return ds


def create(group, scene, model, progress: bool = True):
    """Every tally object of a run of `scene` (its shapes; values NaN or 0 until the end); without
    `progress`, not the counts kept for --resume (a station's group: `io.station_out`)."""
    setup = TallySetup.of(scene, model.mass, model.radius, 1.0)
    if progress:
        _create_progress(group["progress"], TallyTotals(setup).flat().size)
    _create_results(group, scene, setup)


def _create_progress(p, width: int):
    _ds(
        p,
        "tally",
        shape=(2, width),
        dtype=np.int64,
        fillvalue=0,
        unit="1",
        chunks=(1, min(width, 1 << 20)),
        compression="gzip",
        compression_opts=1,
        doc="cumulative landing counts (warp_ricochet.tallies.counts.TallyTotals.flat) in two slots used in turn",
    )
    _ds(p, "tally_rows", np.full(2, -1, dtype=np.int64), unit="1", doc="rows each tally slot is complete for")


def _create_results(group, scene, setup):
    n_levels, quant = len(LEVELS), group.create_group("stats/quantiles")
    quant.attrs["levels"] = np.asarray(LEVELS)
    quant.attrs["resolution"] = RESOLUTION
    rest = {name: (unit, doc, "") for name, (unit, doc) in REST_QUANTITIES.items()} if setup.rest else {}
    for name, (unit, doc, whose) in {**{k: (*v, ", landed pellets") for k, v in QUANTITIES.items()}, **rest}.items():
        for path, what in (
            (name, "upper edge of the bin holding the sample quantile X_(ceil(q n)) of the"),
            (f"lower/{name}", "lower edge of the bin holding the sample quantile of the"),
        ):
            ds = _ds(quant, path, np.full(n_levels, np.nan), unit=unit, doc=f"{what} {doc}{whose}")
            ds.attrs["levels"] = np.asarray(LEVELS)
            ds.attrs["resolution"] = RESOLUTION
    hist = group.create_group("stats/histograms")
    _ds(
        hist,
        "counts",
        np.zeros((setup.hist_rows, BINS), dtype=np.int64),
        unit="1",
        compression="gzip",
        compression_opts=1,
        doc="landings per bin; rows: " + HIST_ROWS + (REACH_ROWS if setup.path else ""),
    ).attrs["resolution"] = RESOLUTION
    if setup.rest:
        _ds(
            hist,
            "rest_counts",
            np.zeros(BINS, dtype=np.int64),
            unit="1",
            compression="gzip",
            compression_opts=1,
            doc="pellets at rest or embedded per bin of their rest distance from the shooter (m)",
        ).attrs["resolution"] = RESOLUTION
    _ds(hist, "edges", edges(), unit="m, m/s (by row)", doc="bin edges (BINS + 1): 0, the log-spaced span, inf")
    distances = scene.output.tail_distances
    tails = group.create_group("stats/tail")
    _ds(
        tails,
        "distance",
        np.full(len(distances), np.nan),
        unit="m",
        doc="output.tail_distances, each moved up to the nearest bin edge (at most 0.098% more)",
    )
    _ds(
        tails,
        "count",
        np.zeros(len(distances), dtype=np.int64),
        unit="1",
        doc="landings at or beyond the distance from the shooter",
    )
    _ds(
        tails,
        "fraction",
        np.full(len(distances), np.nan),
        unit="1",
        doc="share of the landed pellets at or beyond the distance from the shooter",
    )
    if scene.hazard is not None:
        _create_hazard(group.create_group("hazard"), setup)
        _create_places(group["hazard"], scene, len(setup.names))
        if scene.hazard.references:
            _create_references(group["hazard"].create_group("references"), scene.hazard.references)
        if scene.hazard.site is not None:
            _create_site(group["hazard"].create_group("site"), scene.hazard.site, setup)


def _create_hazard(g, setup):
    t = len(setup.names)
    th = g.create_group("thresholds")
    _ds(
        th, "name", np.asarray(setup.names, dtype="S"), unit="", doc="threshold names, in the order of the bits of hazard.exceeds"
    )
    _ds(th, "kind", np.asarray(setup.kinds, dtype="S"), unit="", doc="energy_density (J/m^2) or speed (m/s)")
    _ds(th, "value", np.asarray(setup.values, dtype=np.float64), unit="J/m^2 or m/s (by kind)", doc="threshold values")
    _ds(
        th,
        "speed",
        np.sqrt(np.asarray(setup.thresholds2, dtype=np.float64)),
        unit="m/s",
        doc="the same thresholds as landing speeds (E/A = m v^2 / (2 pi R^2))",
    )
    _ds(th, "landings", np.zeros(t, dtype=np.int64), unit="1", doc="landings at or above each threshold")
    if setup.path:
        _ds(
            th,
            "reaching",
            np.zeros(t, dtype=np.int64),
            unit="1",
            doc="pellets within body height at or above each threshold somewhere on their path",
        )
        _create_danger(
            g.create_group("danger_distance"),
            setup,
            "reach distances (farthest within body height above the threshold, along the path)",
            "pellets reaching above the threshold",
        )
        _create_danger(g.create_group("landing_danger_distance"), setup, "landing distances", "landings above the threshold")
    else:
        _create_danger(g.create_group("danger_distance"), setup, "landing distances", "landings above the threshold")
    if setup.has_map:
        m = g.create_group("map")
        shape = (setup.map_nv, setup.map_nu)
        _ds(m, "count", **_map_layer(shape, np.int64), unit="1", doc="landings per cell (rows v, columns u)")
        _ds(m, "outside", np.int64(0), unit="1", doc="landings on the map's surface outside the grid")
        _ds(m, "elsewhere", np.int64(0), unit="1", doc="landings on other surfaces")
        _ds(
            m,
            "energy",
            **_map_layer(shape, np.float64),
            unit="J",
            doc="kinetic energy at landing per cell, summed (fixed point: `quantum`)",
        )
        _ds(m, "quantum", np.nan, unit="J", doc="the energy sums' unit: each landing's energy rounded to a multiple of it")
        _ds(m, "above", **_map_layer((t,) + shape, np.int64), unit="1", doc="landings above each threshold per cell")
        _ds(m, "u_edges", setup.map_u0 + setup.map_cell * np.arange(setup.map_nu + 1), unit="m", doc="cell edges along u")
        _ds(m, "v_edges", setup.map_v0 + setup.map_cell * np.arange(setup.map_nv + 1), unit="m", doc="cell edges along v")
        _ds(m, "origin", np.asarray(setup.map_origin), unit="m", doc="(u, v) = (0, 0): the shooter projected on the surface")
        _ds(m, "u_axis", np.asarray(setup.map_u), unit="1", doc="unit vector of u (downrange)")
        _ds(m, "v_axis", np.asarray(setup.map_v), unit="1", doc="unit vector of v = normal x u")
        _ds(m, "surface", np.int64(setup.map_surface), unit="1", doc="index of the surface the map lies on")
        if setup.path:
            _ds(m, "passes", **_map_layer(shape, np.int64), unit="1", doc="passes through each cell's column within body height")
            _ds(
                m,
                "exposure",
                **_map_layer((t,) + shape, np.int64),
                unit="1",
                doc="passes through each cell's column within body height at or above each threshold (speed at entry)",
            )
            _ds(
                m,
                "exposure_outside",
                np.zeros(t + 1, dtype=np.int64),
                unit="1",
                doc="passes within body height off the grid: all, then at or above each threshold",
            )


def _create_danger(d, setup, of: str, whose: str):
    """The danger distances' datasets (thresholds x fractions) of the distances `of`."""
    t, f = len(setup.names), len(setup.fractions)
    _ds(
        d,
        "fraction",
        np.asarray(setup.fractions, dtype=np.float64),
        unit="1",
        doc=f"p: the share of the {whose} left beyond",
    )
    for name, doc in (
        (
            "distance",
            f"distance from the shooter containing all but p of the {whose} ({of}; upper edge of its bin)",
        ),
        ("ci_low", "lower end of its 95% confidence interval (order statistics)"),
        ("ci_high", "upper end of its 95% confidence interval (inf: the run is too small for p)"),
    ):
        _ds(d, name, np.full((t, f), np.nan), unit="m", doc=doc + "; rows: thresholds, columns: fractions")
    _ds(
        d,
        "needed_landings",
        np.zeros((t, f), dtype=np.int64),
        unit="1",
        doc=f"{whose} a bounded 95% interval needs at that p",
    )


def _create_references(g, references):
    """`[[hazard.references]]`: the distances `report --html` compares the danger distances with."""
    _ds(g, "name", np.asarray([r.name.encode() for r in references], dtype="S"), unit="", doc="reference names, as in the scene")
    _ds(
        g,
        "distance",
        np.asarray([r.distance for r in references], dtype=np.float64),
        unit="m",
        doc="reference distances from the shooter (horizontal), as in the scene",
    )
    _ds(
        g, "source", np.asarray([r.source.encode() for r in references], dtype="S"), unit="", doc="where each distance comes from"
    )


def _create_site(g, site, setup):
    """[hazard.site] and the map's horizontal frame: all `warp-ricochet export` needs to place the map."""
    from ..gis.site import local_matrix, parse_crs  # (pyproj: the gis extra, which a site needs)

    _ds(g, "crs", site.crs, unit="", doc="the site's CRS as given (hazard.site.crs)")
    _ds(g, "crs_wkt", parse_crs(site.crs)[0].to_wkt(), unit="", doc="the same CRS as WKT2 (pyproj)")
    _ds(g, "shooter", np.asarray(site.shooter), unit="CRS units", doc="the shooter in the CRS: [easting, northing] or [lon, lat]")
    _ds(
        g,
        "azimuth",
        site.azimuth,
        unit="deg",
        doc="the map's u axis, clockwise from grid north (projected CRS) or true north (geographic CRS)",
    )
    _ds(
        g,
        "local",
        local_matrix(setup),
        unit="1, m (last column)",
        doc="(d, l) = local @ (u, v, 1): horizontal metres from the shooter, d along u, l to its left",
    )


def _map_layer(shape, dtype) -> dict:
    """A map layer's dataset: zeros until written, gzip-compressed (most cells of a map are empty:
    1e6 cells x 31 thresholds took 248 MB dense)."""
    return dict(shape=shape, dtype=dtype, fillvalue=0, compression="gzip", compression_opts=1)


def store_progress(group, tally: TallyTotals, rows: int):
    """Keep the cumulative counts for `rows` rows in the slot not holding the committed rows."""
    p = group["progress"]
    committed = int(p["rows"][()])
    slot = 1 if committed > 0 and int(p["tally_rows"][0]) == committed else 0
    p["tally"][slot] = tally.flat()
    p["tally_rows"][slot] = rows


def read_progress(progress, rows: int):
    """The counts of the slot complete for `rows` rows, or None (no tally, or none matches)."""
    if "tally_rows" not in progress:
        return None
    held = progress["tally_rows"][()]
    if rows == 0:
        return None
    slots = np.flatnonzero(held == rows)
    return progress["tally"][int(slots[0])] if len(slots) else None


DANGER = ("distance", "ci_low", "ci_high", "needed_landings")


def write_results(group, tally: TallyTotals, landed: int, pellets: int | None = None):
    """Fill the tally objects from the run's final counts (`tallies.quantiles.summarize`);
    `pellets`: the run's (n of the named places' statistics; None: /stats/pellets)."""
    results = summarize(tally, landed)
    group["stats/histograms/counts"][...] = tally.hist
    if tally.setup.rest:
        group["stats/histograms/rest_counts"][...] = tally.rest
    for name, (value, lower) in results["quantiles"].items():
        group[f"stats/quantiles/{name}"][...] = value
        group[f"stats/quantiles/lower/{name}"][...] = lower
    for name, values in results["tail"].items():
        group[f"stats/tail/{name}"][...] = values
    if "hazard" in results:
        landing = results.get("landing_hazard")
        if landing is not None:  # along the path: the reach's distances, beside the landings'
            group["hazard/thresholds/reaching"][...] = results["hazard"]["landings"]
            for name in DANGER:
                group[f"hazard/landing_danger_distance/{name}"][...] = landing[name]
        group["hazard/thresholds/landings"][...] = (landing or results["hazard"])["landings"]
        for name in DANGER:
            group[f"hazard/danger_distance/{name}"][...] = results["hazard"][name]
    if "map" in results:
        for name, values in results["map"].items():
            group[f"hazard/map/{name}"][...] = values
    if "hazard/points" in group and "points" in results:
        n = int(group["stats/pellets"][()]) if pellets is None else pellets
        write_places(group["hazard/points"], results["points"]["counts"], tally.setup.order, n)


# /hazard/points (docs/hazard.md, section 9): (unit, doc) of each statistic (tallies.points.COLUMNS), rows
# places, columns thresholds
PLACE_STATISTICS = {
    "pellets": (
        "1",
        "m: pellets that came within the place's cylinder (body height, radius) above the threshold, each once",
    ),
    "expected_per_shot": ("1", "E = N m / n: pellets per shot passing there above the threshold (its expectation, exactly)"),
    "expected_ci_low": ("1", "lower end of E's 95% interval: N times the Clopper-Pearson lower end of m / n"),
    "expected_ci_high": ("1", "upper end of E's 95% interval: N times the Clopper-Pearson upper end of m / n"),
    "probability": (
        "1",
        "P = 1 - (1 - m / n)^N: the probability that a shot sends at least one pellet there above the threshold "
        "(pellets independent; with pellet-pellet collisions an estimate, and P <= E)",
    ),
    "ci_low": ("1", "lower end of P's 95% interval (Clopper-Pearson on m / n)"),
    "ci_high": ("1", "upper end of P's 95% interval (Clopper-Pearson on m / n)"),
}


def _create_places(g, scene, thresholds: int):
    """/hazard/body_height and, with named places, /hazard/points: their geometry now, their statistics
    NaN (pellets 0) until the end. n (pellets simulated) is /stats/pellets; N the group's attribute."""
    hazard = scene.hazard
    _ds(
        g,
        "body_height",
        hazard.body_height,
        unit="m",
        doc="a pellet's centre at most this far above the map's surface is within body height",
    )
    if not hazard.points:
        return
    p = g.create_group("points")
    p.attrs["pellets_per_shot"] = np.int64(scene.shot.count)
    p.attrs["confidence"] = CONFIDENCE
    places = hazard.points
    _ds(p, "name", np.asarray([x.name.encode("utf-8") for x in places], dtype="S"), unit="", doc="the places' names (UTF-8)")
    _ds(p, "position", np.asarray([x.position for x in places], dtype=np.float64), unit="m", doc="where each person stands")
    _ds(p, "area", np.asarray([x.area for x in places], dtype=np.float64), unit="m^2", doc="the area a person presents")
    _ds(
        p,
        "radius",
        np.asarray(hazard.radii, dtype=np.float64),
        unit="m",
        doc="of the person's vertical cylinder: area / (2 body_height)",
    )
    shape = (len(places), thresholds)
    for name, (unit, doc) in PLACE_STATISTICS.items():
        data = np.zeros(shape, dtype=np.int64) if name == "pellets" else np.full(shape, np.nan)
        _ds(p, name, data, unit=unit, doc=doc + "; rows: places, columns: thresholds")


def write_places(g, counts, order, pellets: int):
    """Fill /hazard/points (group `g`) from the point passages by level (`TallyTotals.points`)."""
    stats = place_statistics(counts, order, pellets, int(g.attrs["pellets_per_shot"]))
    for name in PLACE_STATISTICS:
        g[name][...] = stats[name]
