"""The landing quantiles, tail fractions and danger distances of one run as short text lines: from
the counts a run returns (`pipeline.RunStats.tally`, the CLI summary) or from a run file (`report`).
Both go through the same plain dict (`tallies.quantiles.summarize`'s layout). Needs numpy and h5py
only (never warp)."""

from __future__ import annotations

import math

import numpy as np

from .. import display
from ..tallies.bins import RELATIVE_WIDTH
from ..tallies.points import COLUMNS as PLACE_COLUMNS

SHOWN_LEVELS = ("P50", "P75", "P90", "P99", "P99.9", "1-1e-6")


def _dist(x) -> str:
    """A distance (m) and its unit as printed (`display`)."""
    return f"{_fmt(display.value(x, 'm'))} {display.unit('m')}"


def _fmt(x) -> str:
    x = float(x)
    if math.isnan(x):
        return "n/a"
    if math.isinf(x):
        return "inf"
    return f"{x:.4g}"


def from_run(stats, scene=None) -> dict | None:
    """The results of a run's landing counts (None when it counted none), for its summary lines:
    without the map's layers; with `scene`'s named places, their statistics as "places"."""
    tally = getattr(stats, "tally", None)
    if tally is None:
        return None
    from ..tallies.points import place_statistics
    from ..tallies.quantiles import summarize

    out = summarize(tally, int(stats["landed"]), with_map=False)
    places = () if scene is None or scene.hazard is None else scene.hazard.points
    if places and "points" in out:
        per_shot = scene.shot.count
        out["places"] = {
            "names": [p.name for p in places],
            **place_statistics(out["points"]["counts"], tally.setup.order, int(stats["pellets"]), per_shot),
        }
    return out


def from_file(group) -> dict | None:
    """The same results read back from a run file's group (None when it has none)."""
    if "stats/quantiles" not in group:
        return None
    q = group["stats/quantiles"]
    out = {
        "levels": np.asarray(q.attrs["levels"]),
        "landed": int(group["stats/histograms/counts"][0].sum()),
        "quantiles": {
            name: (q[name][()], q[f"lower/{name}"][()])
            for name in ("range", "distance", "speed", "energy", "rest_distance")
            if name in q
        },
        "tail": {name: group[f"stats/tail/{name}"][()] for name in ("distance", "count", "fraction")},
    }
    if "hazard/danger_distance" in group:
        h = group["hazard"]
        along = "landing_danger_distance" in h  # the danger distances are the reach's (issue 26)
        threshold = {
            "names": [n.decode() for n in h["thresholds/name"][()]],
            "kinds": [k.decode() for k in h["thresholds/kind"][()]],
            "values": h["thresholds/value"][()],
        }
        for key, group_name, counted in (
            ("hazard", "danger_distance", "reaching" if along else "landings"),
            ("landing_hazard", "landing_danger_distance", "landings"),
        ):
            if group_name in h:
                out[key] = {
                    **threshold,
                    "fractions": h[f"{group_name}/fraction"][()],
                    "landings": h[f"thresholds/{counted}"][()],
                    **{name: h[f"{group_name}/{name}"][()] for name in DANGER},
                }
    if "hazard/points" in group:
        g = group["hazard/points"]
        out["places"] = {
            "names": [n.decode("utf-8", "replace") for n in g["name"][()]],
            "pellets_per_shot": int(g.attrs["pellets_per_shot"]),
            "pellets_simulated": int(np.nan_to_num(group["stats/pellets"][()])) if "stats/pellets" in group else 0,
            **{name: g[name][()] for name in PLACE_COLUMNS},
        }
    return out


def place_lines(places: dict | None, thresholds) -> list[str]:
    """The table "probability of a hit at named places": per place and threshold, the probability
    that a shot sends a pellet above the threshold there (95% CI) and the pellets per shot."""
    if not places or not len(places["names"]) or not len(thresholds):
        return []
    rows = []
    for p, place in enumerate(places["names"]):
        for i, threshold in enumerate(thresholds):
            rows.append(
                [
                    place,
                    threshold,
                    f"{int(places['pellets'][p, i]):,}",
                    f"{_fmt(places['probability'][p, i])} [{_fmt(places['ci_low'][p, i])}, {_fmt(places['ci_high'][p, i])}]",
                    f"{_fmt(places['expected_per_shot'][p, i])} "
                    f"[{_fmt(places['expected_ci_low'][p, i])}, {_fmt(places['expected_ci_high'][p, i])}]",
                ]
            )
    header = ["place", "threshold", "pellets", "P(hit) per shot [95% CI]", "pellets per shot [95% CI]"]
    widths = [max(len(r[k]) for r in [header, *rows]) for k in range(len(header))]
    text = ["  " + "  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in [header, *rows]]
    return [
        f"probability of a hit at named places (per shot of {places['pellets_per_shot']:,} pellets, "
        f"from {places['pellets_simulated']:,}; pellets independent, P <= pellets per shot)",
        *text,
    ]


DANGER = ("distance", "ci_low", "ci_high", "needed_landings")


def danger_lines(hazard: dict, pellets: float, title: str, counted: str) -> list[str]:
    """A title, then per threshold its danger distances at each p with their 95% intervals (`counted`:
    what its count counts, "landings" or "pellets")."""
    lines = [title]
    for i, name in enumerate(hazard["names"]):
        si = "J/m^2" if hazard["kinds"][i] == "energy_density" else "m/s"
        parts = []
        for j, p in enumerate(hazard["fractions"]):
            if hazard["landings"][i] == 0:
                parts.append(f"p={p:g}: none above")
                continue
            low, high = (_fmt(display.value(hazard[k][i, j], "m")) for k in ("ci_low", "ci_high"))
            text = f"p={p:g}: {_fmt(display.value(hazard['distance'][i, j], 'm'))} {display.unit('m')} [{low}, {high}]"
            if math.isinf(hazard["ci_high"][i, j]):
                need = hazard["needed_landings"][i, j]
                share = hazard["landings"][i] / pellets if pellets else math.nan
                text += (
                    f" too few: needs {need:,} {counted} above it (about {need / share:,.0f} pellets)"
                    if share > 0
                    else f" too few: needs {need:,} {counted} above it"
                )
            parts.append(text)
        lines.append(
            f"  {name} ({_fmt(display.value(hazard['values'][i], si))} {display.unit(si)}, "
            f"{int(hazard['landings'][i]):,} {counted}): " + "; ".join(parts)
        )
    return lines


def tally_lines(results: dict | None, pellets: float) -> list[str]:
    """Quantiles (one line per quantity), tail fractions and danger distances, compactly."""
    if results is None:
        return []
    units = {"range": "m", "distance": "m", "speed": "m/s", "energy": "J", "rest_distance": "m"}
    lines = ["quantiles " + " / ".join(SHOWN_LEVELS) + f" (bin upper edges, <= {RELATIVE_WIDTH:.2%} above)"]
    unresolved = [(name, q) for name, q in zip(SHOWN_LEVELS, results["levels"]) if results["landed"] * (1.0 - q) < 1.0]
    if unresolved and results["landed"]:
        name, q = unresolved[0]
        lines[0] += (
            f"; from {name} on the largest value: a level q needs 1 / (1 - q) landings "
            f"({round(1.0 / (1.0 - q)):,} for {name}), this run has {results['landed']:,}"
        )
    for name, (value, _lower) in results["quantiles"].items():  # (rest_distance: of the pellets at rest or embedded)
        label = f"{name:<9}" if len(name) < 9 else name + " "
        lines.append(
            f"  {label}" + " / ".join(_fmt(display.value(v, units[name])) for v in value) + f" {display.unit(units[name])}"
        )
    tail = results["tail"]
    fractions = np.asarray(tail["fraction"], dtype=np.float64)
    split = (fractions > 0) & (fractions < 1)
    if split.any():
        lines.append(
            "landed beyond  " + ", ".join(f">={_dist(d)}: {_fmt(f)}" for d, f in zip(tail["distance"][split], fractions[split]))
        )
    elif len(fractions) and np.isfinite(fractions).all():
        within = [f"all >= {_dist(tail['distance'][fractions == 1].max())}"] if (fractions == 1).any() else []
        within += [f"none >= {_dist(tail['distance'][fractions == 0].min())}"] if (fractions == 0).any() else []
        lines.append("landed beyond  " + ", ".join(within))
    hazard, landing = results.get("hazard"), results.get("landing_hazard")
    if hazard is not None:
        if landing is None:
            lines += danger_lines(
                hazard, pellets, "danger distance (all but p of the landings above the threshold; 95% CI)", "landings"
            )
        else:
            title = "danger distance along the path (all but p of the pellets within body height above the threshold; 95% CI)"
            lines += danger_lines(hazard, pellets, title, "pellets")
            lines += danger_lines(landing, pellets, "landing distance of the landings above the threshold (95% CI)", "landings")
        lines += place_lines(results.get("places"), hazard["names"])
    return lines
