"""What `warp-ricochet report RUN.h5 --html` shows, read from a run file into plain dicts and
strings for the template (`report.html`): the scene in words, the answers with their intervals,
the places, the references (the scene's `[[hazard.references]]` and Journee's rule for the shot
size), the numerical settings. Numbers are formatted by `fmt` (4 significant digits), the one
function the tests format the file's numbers with too. Needs h5py and numpy only (never warp).
"""

from __future__ import annotations

import math
import os

import numpy as np

from .. import display
from ..scene.loads import describe_load
from .hazard_tables import SHOWN_LEVELS, _fmt

YARD, INCH = 0.9144, 0.0254  # m (exact, international yard and inch, 1959)
JOURNEE_YARDS_PER_INCH = 2200.0  # maximum range of shot (yd) per inch of shot diameter: Journee's rule
JOURNEE_SOURCE = (
    "Journee's rule: maximum range in yards ~ 2200 x shot diameter in inches, for lead shot "
    '(General Journee; quoted in D. Baldwin, "How far will a shotgun shoot?", Gun Club Advisor, Spring 1994)'
)
DENSITIES = {"lead": 11340.0, "bismuth": 9780.0, "steel": 7850.0}  # kg/m^3, to name the pellets' metal


def fmt(x) -> str:
    """A number as the report writes it: 4 significant digits (whole numbers from 1e4 to 1e9, with
    thousands separators, rather than an exponent), `n/a` for NaN, `inf`."""
    x = float(x)
    if math.isfinite(x) and 1e4 <= abs(x) < 1e9:
        return f"{x:,.0f}"
    return _fmt(x)


def dist(x) -> str:
    """A length (m) as the page prints it (`display`: m, or yd with --units imperial), without its unit."""
    return fmt(display.value(x, "m"))


def _short(x, imperial_unit: str) -> str:
    """A height or small length (m): "1.2 m", or in ft or in with --units imperial (`display.short`)."""
    return f"{fmt(x)} m" if not display.imperial() else f"{fmt(float(x) / display.SHORT[imperial_unit])} {imperial_unit}"


def journee_distance(diameter: float) -> float:
    """Journee's maximum range of lead shot (m) for a shot diameter (m): 2200 yd per inch."""
    return JOURNEE_YARDS_PER_INCH * YARD * diameter / INCH


def _text(v) -> str:
    return v.decode("utf-8", "replace") if isinstance(v, bytes) else str(v)


def _names(ds) -> list[str]:
    return [_text(n) for n in ds[()]]


def _up(f) -> np.ndarray:
    g = np.asarray(f["constants/gravity"][()], dtype=np.float64) if "constants/gravity" in f else np.array([0, -9.81, 0])
    n = np.linalg.norm(g)
    return -g / n if n > 0 else np.array([0.0, 1.0, 0.0])


# ------------------------------------------------------------------------------------------ the scene


def metal(density: float) -> str:
    """The metal whose density is within 3% of the pellets' ("" if none)."""
    for name, rho in DENSITIES.items():
        if abs(density - rho) <= 0.03 * rho:
            return name
    return ""


def scene_words(f, scene: dict, stats: dict) -> dict:
    """The shot, surfaces and air in a sentence each, with the numbers they come from."""
    shot, up = scene.get("shot", {}), _up(f)
    radius = float(f["constants/radius"][()])
    density = float(shot.get("density", math.nan))
    mass = float(f["constants/mass"][()])
    kind = metal(density)
    pellets = int(stats.get("pellets", 0))
    shots, count = int(shot.get("shots", 1)), int(shot.get("count", pellets))
    if "hazard/bound/shots" in f:  # [hazard.bound]: the shots run, not the first check's (`shot.shots`)
        shots = int(f["hazard/bound/shots"][()])
    out = {
        "diameter_mm": fmt(2e3 * radius),
        "pellets": f"{pellets:,}",
        "shot": (
            f"{shots:,} shot{'s' if shots != 1 else ''} of {count:,} pellets"
            if shot.get("file") is None
            else f"{pellets:,} pellets read from a pellet file ({shots:,} shot{'s' if shots != 1 else ''})"
        ),
        "pellet": f"{fmt(2e3 * radius)} mm {kind + ' ' if kind else ''}spheres, density {density:,.0f} kg/m³, "
        f"mass {fmt(1e3 * mass)} g",
        "seed": str(shot.get("seed", f.attrs.get("seed", "n/a"))),
        "stations": [],  # [[stations]] in words (`_station_row`), none without them
    }
    if isinstance(shot.get("load"), dict):  # [shot] load (scene.loads): named as the scene gives it
        out["pellet"] = f"{describe_load(shot['load'])}: {out['pellet']}"
    if shot.get("file") is None:
        d = np.asarray(shot.get("direction", (1, -1, 0)), dtype=np.float64)
        elevation = math.degrees(math.asin(float(np.clip(d @ up / np.linalg.norm(d), -1, 1))))
        centre = np.asarray(shot.get("envelope_center", (0, 0, 0)), dtype=np.float64)
        spread = f"direction jitter {', '.join(fmt(x) for x in np.atleast_1d(shot.get('direction_jitter', 0)))}"
        if "pattern" in f["constants"]:  # a choke's pattern (scene.patterns) in place of the jitter
            percent = f"{fmt(float(f['constants/pattern'][()]))}% in a 30-inch circle at 40 yards"
            spread = f"{shot['choke']} choke, {percent}" if "choke" in shot else f"a pattern of {percent}"
        out["launch"] = (
            f"at {fmt(display.value(shot.get('speed'), 'm/s'))} {display.unit('m/s')}, "
            f"{fmt(abs(elevation))} degrees {'above' if elevation >= 0 else 'below'} level, "
            f"from {_height(scene, centre)} (envelope radius {_short(shot.get('envelope_radius', 0), 'in')}, "
            f"{spread})"
        )
        if scene.get("stations"):  # each shot from its station, aimed over its arc (scene.stations)
            out["launch"] = (
                f"at {fmt(display.value(shot.get('speed'), 'm/s'))} {display.unit('m/s')} from "
                f"{len(scene['stations'])} stations (below), each shot aimed within its station's arc of fire "
                f"(envelope radius {_short(shot.get('envelope_radius', 0), 'in')}, {spread})"
            )
            out["stations"] = [_station_row(scene, st) for st in scene["stations"]]
    else:
        out["launch"] = "as given in the pellet file"
    out["surfaces"] = _surfaces(f, scene)
    air = scene.get("air")
    if air is None or float(air.get("density", 0)) == 0:
        out["air"] = "none: the pellets fly in vacuum"
    else:
        wind = np.asarray(air.get("wind", (0, 0, 0)), dtype=np.float64)
        out["air"] = (
            f"density {fmt(air.get('density'))} kg/m³, wind {fmt(display.value(np.linalg.norm(wind), 'm/s'))} "
            f"{display.unit('m/s')} ({', '.join(fmt(display.value(w, 'm/s')) for w in wind)}), drag {air.get('drag', 'loth2021')}, lift {air.get('lift', 'loth2008')}"
            f"{'' if air.get('magnus', True) else ' (Magnus lift off)'}"
        )
    physics = scene.get("physics", {})
    until = physics.get("until", "rest")
    out["until"] = (
        "to rest: bouncing, sliding, rolling and ploughing along the ground until each pellet stops (docs/ground.md)"
        if until == "rest"
        else f"to their landing after {physics.get('bounces', 1)} ricochet(s)"
    )
    collisions = scene.get("collisions", {})
    out["collisions"] = "simulated" if collisions.get("enabled") else "not simulated (pellets pass through each other)"
    return out


def _station_row(scene: dict, station: dict) -> dict:
    """A [[stations]] entry in words: its height above the first surface, arcs (deg), aim, weight."""

    def arc(value):
        lo, hi = (value, value) if np.isscalar(value) else value
        return f"{fmt(lo)}" if lo == hi else f"{fmt(lo)} to {fmt(hi)} ({fmt(hi - lo)} wide)"

    aim = station.get("aim", "uniform")
    if aim == "normal":
        aim = f"normal, sigma {fmt(station.get('aim_sigma'))} deg"
    return {
        "name": station.get("name", ""),
        "height": _height(scene, np.asarray(station.get("position", (0, 0, 0)), dtype=np.float64)),
        "azimuth": arc(station.get("azimuth", 0.0)),
        "elevation": arc(station.get("elevation", 0.0)),
        "aim": aim,
        "weight": fmt(station.get("weight", 1.0)),
    }


def _height(scene: dict, centre) -> str:
    """The launch point's height above the first surface, along its normal (a mesh, whose
    triangles carry theirs: along up, -gravity, above its `point`)."""
    surfaces = scene.get("surfaces") or [{}]
    point = np.asarray(surfaces[0].get("point", (0, 0, 0)), dtype=np.float64)
    normal = np.asarray(surfaces[0].get("normal", (0, 1, 0)), dtype=np.float64)
    if surfaces[0].get("kind") == "mesh":
        normal = -np.asarray((scene.get("physics") or {}).get("gravity", (0, -9.81, 0)), dtype=np.float64)
    name = surfaces[0].get("name") or "surface 0"
    return f"{_short((centre - point) @ normal / np.linalg.norm(normal), 'ft')} above {name}"


def _shape(surface: dict) -> str:
    """A surface's kind in words (docs/geometry.md): its size, and the faces pellets meet."""
    kind = surface.get("kind") or "plane"
    sides = "either face" if surface.get("two_sided") else "its normal's side"
    if kind == "rectangle":
        a, b = surface["size"]
        return f"rectangle {fmt(a)} m x {fmt(b)} m, met from {sides}"
    if kind == "disc":
        return f"disc of radius {fmt(surface['radius'])} m, met from {sides}"
    if kind == "box":
        a, b, c = surface["size"]
        return f"box {fmt(a)} m x {fmt(b)} m x {fmt(c)} m (12 triangles)"
    if kind == "cylinder":
        return f"post (cylinder) of radius {fmt(surface['radius'])} m and length {fmt(surface['length'])} m, closed by its caps"
    if kind in ("mesh", "terrain"):
        what = "triangle mesh" if kind == "mesh" else "terrain raster, as triangles"
        return f"{what} from {os.path.basename(str(surface.get('file', '')))}"
    return "infinite plane"


def _surfaces(f, scene: dict) -> list[dict]:
    rows = []
    given = scene.get("surfaces", [])
    consts = f.get("constants/surfaces")
    for i, s in enumerate(given):
        row = {
            "index": i,
            "name": s.get("name") or f"surface {i}",
            "shape": _shape(s),
            "material": s.get("material") or "rigid plane (no catalogue material)",
            "point": ", ".join(dist(x) for x in s.get("point", ())),
            "normal": "its triangles'" if s.get("kind") == "mesh" else ", ".join(fmt(x) for x in s.get("normal", ())),
        }
        for key in ("restitution", "mu_s", "mu_d"):
            value = consts[key][i] if consts is not None and key in consts else s.get(key, math.nan)
            row[key] = fmt(value)
        rows.append(row)
    return rows


# ---------------------------------------------------------------------------------------- the answers


def danger_rows(f, pellets: float) -> dict | None:
    """The danger distances per threshold and p with their 95% intervals, and what they are of."""
    if "hazard/danger_distance" not in f:
        return None
    h = f["hazard"]
    reach = "landing_danger_distance" in h  # issue 26: from the path within body height
    counted = h["thresholds/reaching"][()] if reach and "thresholds/reaching" in h else h["thresholds/landings"][()]
    names, kinds, values = _names(h["thresholds/name"]), _names(h["thresholds/kind"]), h["thresholds/value"][()]
    fractions = h["danger_distance/fraction"][()]
    d = {k: h[f"danger_distance/{k}"][()] for k in ("distance", "ci_low", "ci_high", "needed_landings")}
    rows = []
    for i, name in enumerate(names):
        unit = "J/m²" if kinds[i] == "energy_density" else display.unit("m/s")
        cells = []
        for j, p in enumerate(fractions):
            cell = {
                "p": f"{p:g}",
                "distance": dist(d["distance"][i, j]),
                "ci": f"[{dist(d['ci_low'][i, j])}, {dist(d['ci_high'][i, j])}]",
            }
            cell["note"] = ""
            if counted[i] == 0:
                cell.update(distance="none above", ci="")
            elif not math.isfinite(d["ci_high"][i, j]):
                need, share = int(d["needed_landings"][i, j]), counted[i] / pellets if pellets else 0.0
                cell["note"] = f"too few: needs {need:,} above it" + (f" (about {need / share:,.0f} pellets)" if share else "")
            cells.append(cell)
        speed, count = fmt(display.value(h["thresholds/speed"][i], "m/s")), f"{int(counted[i]):,}"
        value = values[i] if kinds[i] == "energy_density" else display.value(values[i], "m/s")
        rows.append({"name": name, "value": f"{fmt(value)} {unit}", "speed": speed, "count": count, "cells": cells})
    what = (
        "pellets that pass within body height above the threshold anywhere along their path (their reach)"
        if reach
        else "landings above the threshold (where a pellet first comes down: a proxy for one that would strike a person there)"
    )
    body = _short(h["body_height"][()], "ft") if "body_height" in h else None
    return {"fractions": [f"{p:g}" for p in fractions], "rows": rows, "what": what, "reach": reach, "body_height": body}


def quantile_rows(results: dict | None) -> list[dict]:
    """Landing (and rest) quantiles: the bin [lower, upper] holding each sample quantile."""
    if results is None:
        return []
    units = {"range": "m", "distance": "m", "speed": "m/s", "energy": "J", "rest_distance": "m"}
    words = {
        "range": "range (last ricochet to landing)",
        "distance": "landing distance from the shooter",
        "speed": "speed at landing",
        "energy": "energy at landing",
        "rest_distance": "rest distance from the shooter",
    }
    rows = []
    for name, (value, lower) in results["quantiles"].items():
        rows.append(
            {
                "name": words.get(name, name),
                "unit": display.unit(units.get(name, "")),
                "upper": [fmt(display.value(v, units.get(name, ""))) for v in value],
                "lower": [fmt(display.value(v, units.get(name, ""))) for v in lower],
            }
        )
    return rows


def tail_rows(results: dict | None) -> list[dict]:
    if results is None:
        return []
    t = results["tail"]
    return [
        {"distance": dist(d), "count": f"{int(c):,}", "fraction": fmt(x)}
        for d, c, x in zip(t["distance"], t["count"], t["fraction"])
    ]


def point_rows(f) -> dict | None:
    """The probabilities at the named places (`/hazard/points`, issue 26), or None without them."""
    if "hazard/points" not in f:
        return None
    g, names = f["hazard/points"], _names(f["hazard/thresholds/name"])
    rows = []
    for k, name in enumerate(_names(g["name"])):
        cells = []
        for i in range(len(names)):
            cell = {"probability": fmt(g["probability"][k, i]), "ci": f"[{fmt(g['ci_low'][k, i])}, {fmt(g['ci_high'][k, i])}]"}
            if "expected_per_shot" in g:
                cell["expected"] = fmt(g["expected_per_shot"][k, i])
            if "pellets" in g:
                cell["pellets"] = f"{int(g['pellets'][k, i]):,}"
            cells.append(cell)
        rows.append(
            {
                "name": name,
                "position": ", ".join(dist(x) for x in g["position"][k]),
                "area": fmt(display.value(g["area"][k], "m^2")) if "area" in g else "n/a",
                "cells": cells,
            }
        )
    return {"thresholds": names, "rows": rows, "per_shot": fmt(g.attrs.get("pellets_per_shot", math.nan))}


# ------------------------------------------------------------------------------------ the references


def references(f) -> list[dict]:
    """The scene's `[[hazard.references]]` as written in the run file, then Journee's rule."""
    out = []
    if "hazard/references" in f:
        g = f["hazard/references"]
        for name, distance, source in zip(_names(g["name"]), g["distance"][()], _names(g["source"])):
            out.append({"name": name, "distance": float(distance), "source": source or "(no source given in the scene)"})
    diameter = 2.0 * float(f["constants/radius"][()])
    source = (
        f"{JOURNEE_SOURCE}; shot diameter {fmt(diameter / INCH)} in ({fmt(diameter * 1e3)} mm) gives "
        f"{fmt(journee_distance(diameter) / YARD)} yd"
    )
    density = float(f["constants/mass"][()]) / (4.0 / 3.0 * math.pi * (diameter / 2) ** 3)
    if metal(density) != "lead":
        source += f". The rule is for lead shot; these pellets' density is {density:,.0f} kg/m³ (lead: 11,340)"
    out.append({"name": "Journee's rule for this shot size", "distance": journee_distance(diameter), "source": source})
    return out


def verdict(distance: float, low: float, high: float, reference: float) -> dict:
    """Whether a danger distance lies inside a reference distance, judged by its 95% interval,
    and by how much (m, and % of the reference)."""
    if not math.isfinite(distance):
        return {"verdict": "n/a", "by": "no pellet above", "css": "na"}
    diff = distance - reference
    by = (
        f"{dist(abs(diff))} {display.unit('m')} ({fmt(abs(100.0 * diff / reference))}%) {'beyond' if diff > 0 else 'short of'} it"
    )
    if high < reference:
        return {"verdict": "inside", "by": by, "css": "inside"}
    if low > reference:
        return {"verdict": "OUTSIDE", "by": by, "css": "outside"}
    return {"verdict": "undecided", "by": by, "css": "undecided"}


def comparison(f, refs: list[dict]) -> dict | None:
    """Per threshold and p, the run's danger distance against every reference; None without a
    [hazard] table."""
    if "hazard/danger_distance" not in f:
        return None
    h = f["hazard"]
    names, fractions = _names(h["thresholds/name"]), h["danger_distance/fraction"][()]
    d = {k: h[f"danger_distance/{k}"][()] for k in ("distance", "ci_low", "ci_high")}
    counted = h["thresholds/reaching"][()] if "thresholds/reaching" in h else h["thresholds/landings"][()]
    rows = []
    for i, name in enumerate(names):
        for j, p in enumerate(fractions):
            x, lo, hi = (math.nan,) * 3 if counted[i] == 0 else (float(d[k][i, j]) for k in ("distance", "ci_low", "ci_high"))
            verdicts = [verdict(x, lo, hi, ref["distance"]) for ref in refs]
            rows.append(
                {"threshold": name, "p": f"{p:g}", "distance": dist(x), "ci": f"[{dist(lo)}, {dist(hi)}]", "verdicts": verdicts}
            )
    shown = []
    for k, ref in enumerate(refs):
        seen = [row["verdicts"][k]["verdict"] for row in rows]
        tally = ", ".join(f"{seen.count(v)} {v}" for v in ("inside", "OUTSIDE", "undecided") if v in seen) or "nothing to compare"
        shown.append({"name": ref["name"], "distance": dist(ref["distance"]), "source": ref["source"], "tally": tally})
    return {"references": shown, "rows": rows}


# ---------------------------------------------------------------------------------------- the settings


def settings(f, scene: dict, stats: dict) -> list[tuple[str, str]]:
    """(name, value) of the numerical settings and of the pellets a budget or limit stopped."""
    physics, numerics = scene.get("physics", {}), scene.get("numerics", {})
    g = stats.get

    def count(name):
        v = g(name)
        return "n/a" if v is None or not math.isfinite(v) else f"{int(v):,}"

    rows = [
        ("precision", str(f.attrs.get("precision", numerics.get("precision", "n/a")))),
        ("device", _text(f.attrs.get("device", "not recorded"))),
        ("physics.until", str(physics.get("until", "rest"))),
        ("physics.bounces (ricochets before the landing)", str(physics.get("bounces", 1))),
        ("physics.impact_duration", f"{fmt(physics.get('impact_duration', 0))} s"),
        (
            "physics.max_impacts / max_steps (a pellet's budget)",
            f"{physics.get('max_impacts', 'n/a'):,} / {physics.get('max_steps', 'n/a'):,}",
        ),
        (
            "physics.rest_speed",
            "default (docs/ground.md)"
            if physics.get("rest_speed") is None
            else f"{fmt(display.value(physics['rest_speed'], 'm/s'))} {display.unit('m/s')}",
        ),
        ("numerics.flight_tolerance (relative, flight in air)", fmt(numerics.get("flight_tolerance", math.nan))),
        ("numerics.surface_tolerance (relative, along surfaces)", fmt(numerics.get("surface_tolerance", math.nan))),
        ("numerics.fast_math", str(numerics.get("fast_math", True)).lower()),
        ("histogram bins (relative width)", "0.098%: quantiles and distances are bin upper edges"),
        ("pellets missed / hit, never landed / entered", f"{count('missed')} / {count('escaped')} / {count('entered')}"),
        ("pellets not finished (budget spent)", count("rest_not_finished")),
        ("flights unfinished (in air)", count("flights_unfinished")),
    ]
    if physics.get("until", "rest") == "landing":  # (no budget or rest speed: nothing is followed past the landing)
        rows = [r for r in rows if not r[0].startswith(("physics.max_impacts", "physics.rest_speed"))]
    if "rest_not_finished" not in stats:
        rows = [r for r in rows if not r[0].startswith("pellets not finished")]
    return rows


def limit_flags(scene: dict, reach: bool) -> dict:
    """The facts the template's limits paragraph depends on."""
    air = scene.get("air")
    return {
        "vacuum": air is None or float(air.get("density", 0)) == 0,
        "collisions": bool(scene.get("collisions", {}).get("enabled")),
        "float32": scene.get("numerics", {}).get("precision", "float32") == "float32",
        "landing": scene.get("physics", {}).get("until", "rest") == "landing",
        "reach": reach,
        "materials": any(s.get("material") for s in scene.get("surfaces", [])),
        "plates": any((s.get("kind") or "plane") in ("rectangle", "disc") for s in scene.get("surfaces", [])),
        "triangles": any(s.get("kind") in ("box", "mesh", "terrain") for s in scene.get("surfaces", [])),
        "edges": any(s.get("kind") in ("box", "mesh") for s in scene.get("surfaces", [])),
        "terrain": any(s.get("kind") == "terrain" for s in scene.get("surfaces", [])),
        "posts": any(s.get("kind") == "cylinder" for s in scene.get("surfaces", [])),
        "levels": list(SHOWN_LEVELS),
    }
