"""Stations and arcs of fire (docs/scenes.md, "Stations, arcs of fire and aim error"): `[[stations]]`
tables validated into `Station`s, the shots each station fires, the frame azimuths are measured in,
and a NumPy reference of the aims the kernels draw (`launch.stations`). Standard library and NumPy
only (never warp).

Angles: `azimuth` is clockwise seen from above (looking along gravity) from the scene's downrange
axis: the horizontal part of `hazard.map_axis`, else of `shot.direction` (the axis of the hazard map,
docs/hazard.md section 5). With `[hazard.site]`, it is from the site's north, as
`hazard.site.azimuth` is (docs/hazard.md section 10): the downrange axis lies at `hazard.site.azimuth`,
so a station's azimuth A is A - site.azimuth from it. `elevation` is above the horizontal (the plane
perpendicular to gravity). The aim is d = cos(e) (cos(a) f + sin(a) r) + sin(e) up, f the
downrange axis, up = -g / |g|, r = f x up (to the right of f seen from above).

Shots (`shot_pieces`): station k fires a contiguous range of shots, n_k of shot.shots in proportion
to the weights by the largest-remainder (Hamilton) method, in scene order. A bounded run
([hazard.bound]) is cut at its checks instead: between two checks each station fires a contiguous
range, its shots of that stretch of a weighted sequence every prefix of which is within one shot of
the weights' proportions (`interleaved`), so a run stopped at any check has fired every station by
its weight. Either way shot j belongs to one station for any chunking, and each station's tallies
are sums over whole chunks (`pipeline`, `tallies.by_station`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from .convert import _finite
from .keys import MISSING, check_keys, err, join
from .schema import MAX_COORDINATE

AIMS = ("uniform", "normal")
KEYS = ("name", "position", "azimuth", "elevation", "aim", "aim_sigma", "weight")
MAX_WEIGHT = 1e6  # (shots * weight / sum of weights stays finite: 1e308 overflowed `allocate`)
MAX_SIGMA = 90.0  # deg


@dataclass(frozen=True)
class Station:
    """A shooting station: `position` (m), the arc `azimuth` (deg, (min, max), clockwise from the
    downrange axis or the site's north), `elevation` (deg above the horizontal, (min, max)), the aim
    drawn "uniform" over both ranges or "normal" about their centres (`aim_sigma` deg; each
    coordinate truncated to its range when the range is wider than a point), and `weight` (its
    share of the shots)."""

    name: str
    position: tuple[float, float, float]
    azimuth: tuple[float, float]
    elevation: tuple[float, float] = (0.0, 0.0)
    aim: str = "uniform"
    aim_sigma: float | None = None
    weight: float = 1.0


def _number(v, path, rule) -> float:
    """A finite number, or a string with its unit (scene.units: "30 deg", "40 yd")."""
    return _finite(v, path, rule)


def _angles(v, path: str, lo: float, hi: float, width: float) -> tuple[float, float]:
    """A number or [min, max] (deg) within [lo, hi], max - min in [0, width]."""
    rule = f"must be a number or [min, max] in degrees within [{lo:g}, {hi:g}], min <= max"
    if isinstance(v, (list, tuple)):
        if len(v) != 2:
            raise err(path, v, rule)
        pair = tuple(_number(x, path, rule) for x in v)
    else:
        pair = (_number(v, path, rule),) * 2
    if not lo <= pair[0] <= pair[1] <= hi:
        raise err(path, v, rule)
    if pair[1] - pair[0] > width:
        raise err(path, v, f"is an arc {pair[1] - pair[0]:g} degrees wide; an arc is at most {width:g} degrees")
    return pair


def _station(raw, path: str) -> Station:
    if not isinstance(raw, dict):
        raise err(path, raw, "must be a table ([[stations]]) with keys " + ", ".join(KEYS))
    check_keys(raw, path, KEYS)
    for key in ("name", "position", "azimuth"):
        if raw.get(key) is None:
            raise err(join(path, key), MISSING, "is required")
    name = raw["name"]
    if not isinstance(name, str) or not name.strip() or not name.isprintable() or "/" in name:
        raise err(join(path, "name"), name, "must be a printable string, not empty, without '/' (an HDF5 group name)")
    pos = raw["position"]
    rule = f"must be a list of 3 numbers (m), each within +-{MAX_COORDINATE:g}"
    if not isinstance(pos, (list, tuple)) or len(pos) != 3:
        raise err(join(path, "position"), pos, rule)
    position = tuple(_number(x, join(path, "position"), rule) for x in pos)
    if max(map(abs, position)) > MAX_COORDINATE:
        raise err(join(path, "position"), pos, rule)
    azimuth = _angles(raw["azimuth"], join(path, "azimuth"), -360.0, 720.0, 360.0)
    elevation = _angles(raw.get("elevation", 0.0), join(path, "elevation"), -90.0, 90.0, 180.0)
    aim = raw.get("aim", "uniform")
    if aim not in AIMS:
        raise err(join(path, "aim"), aim, "must be one of " + ", ".join(map(repr, AIMS)))
    sigma = raw.get("aim_sigma")
    if aim == "normal":
        sigma_rule = f"must be a number in (0, {MAX_SIGMA:g}] (deg): the aim error's standard deviation"
        if sigma is None:
            raise err(join(path, "aim_sigma"), MISSING, 'is required with aim = "normal"; it ' + sigma_rule)
        sigma = _number(sigma, join(path, "aim_sigma"), sigma_rule)
        if not 0.0 < sigma <= MAX_SIGMA:
            raise err(join(path, "aim_sigma"), raw["aim_sigma"], sigma_rule)
    elif sigma is not None:
        raise err(join(path, "aim_sigma"), sigma, 'is only for aim = "normal" (a uniform aim has no spread of its own)')
    weight_rule = f"must be a number > 0 and at most {MAX_WEIGHT:g} (the station's share of the shots)"
    weight = _number(raw.get("weight", 1.0), join(path, "weight"), weight_rule)
    if not 0.0 < weight <= MAX_WEIGHT:
        raise err(join(path, "weight"), raw.get("weight"), weight_rule)
    return Station(name, position, azimuth, elevation, aim, sigma, weight)


def parse_stations(raw) -> tuple[Station, ...]:
    """The validated `[[stations]]` array (empty when absent); names distinct."""
    if raw is None:
        return ()
    if not isinstance(raw, (list, tuple)) or not raw:
        raise err("stations", raw, "must be a non-empty array of tables ([[stations]])")
    stations = tuple(_station(s, f"stations.{i}") for i, s in enumerate(raw))
    seen = {}
    for i, s in enumerate(stations):
        if s.name in seen:
            raise err(f"stations.{i}.name", s.name, f"is the name of stations.{seen[s.name]} too; names must be distinct")
        seen[s.name] = i
    return stations


def allocate(weights, shots: int) -> list[int]:
    """Shots per station in proportion to `weights`: the largest-remainder (Hamilton) method, the
    remainders' ties to the earlier station (deterministic: a function of the scene alone)."""
    total = math.fsum(weights)
    quotas = [shots * w / total for w in weights]
    counts = [math.floor(q) for q in quotas]
    order = sorted(range(len(weights)), key=lambda k: (-(quotas[k] - counts[k]), k))
    for k in order[: shots - sum(counts)]:
        counts[k] += 1
    return counts


def enough_shots(weights) -> int:
    """Shots that give every station one: n with n w_k / sum(w) >= 1 for the least weight (its
    Hamilton quota at least 1; the weighted sequence's counts lie within one shot of n p_k, above
    0 there), and at least one a station."""
    need = max(len(weights), math.ceil(math.fsum(weights) / min(weights)))
    while min(allocate(weights, need)) < 1:  # (the quotient's rounding)
        need += 1
    return need


def check_stations(stations, shot, raw_shot: dict, surfaces, physics, hazard) -> None:
    """A station scene's cross-key rules, before any work: each station fires at least one shot
    (with [hazard.bound], at the first check),
    sampled shots (no shot.file) around each station (no shot.envelope_center), gravity defines the
    horizontal, a downrange axis, and no station below the ground: behind the plane of the hazard
    map's surface (hazard.map_surface), else of the first surface (its normal: the side pellets come
    from), or under a terrain's triangles there; other kinds (box, mesh) are not checked as the
    ground (each station's envelope is checked against the solids by `scene.parse`)."""
    if shot.file is not None:
        raise err(
            "shot.file", shot.file, "not allowed with [[stations]]: stations sample each shot's aim (a pellet file fixes it)"
        )
    if "envelope_center" in raw_shot:
        raise err(
            "shot.envelope_center",
            raw_shot["envelope_center"],
            "not allowed with [[stations]]: each shot starts at its station's position",
        )
    weights = [s.weight for s in stations]
    bound = None if hazard is None else hazard.bound
    if bound is None:
        counts = allocate(weights, shot.shots)
    else:  # (its first check's shots of the weighted sequence, computed up to its budget)
        budget = max(shot.shots, bound.max_pellets // shot.count)
        if min(period(weights), budget) > MAX_INTERLEAVED:
            raise err(
                "hazard.bound.max_pellets",
                bound.max_pellets,
                f"gives {budget:,} shots, and the stations' weights repeat only after {period(weights):,}: "
                f"at most {MAX_INTERLEAVED:,} shots of the weighted sequence are computed (weights in small "
                "integer ratios, such as 1, 2, 1.5, repeat sooner)",
            )
        counts = interleave_counts(weights, [shot.shots])[0]
    if min(counts) < 1:
        k = counts.index(0)
        raise err(
            "shot.shots",
            shot.shots,
            f"gives stations.{k} ({stations[k].name!r}) no shot by the weights; at least one per station "
            f"({enough_shots(weights):,} shots give every station one; or raise that station's weight)",
        )
    if not any(physics.gravity):
        raise err(
            "physics.gravity",
            list(physics.gravity),
            "must not be zero with [[stations]]: elevations are above the plane perpendicular to it",
        )
    try:
        frame(shot, physics, hazard)
    except ValueError as exc:
        key = "hazard.map_axis" if hazard is not None and hazard.map_axis is not None else "shot.direction"
        raise err(key, list(hazard.map_axis if key == "hazard.map_axis" else shot.direction), str(exc)) from None
    index = hazard.map_surface if hazard is not None else 0
    if not surfaces or index >= len(surfaces) or surfaces[index].kind not in (None, "plane", "rectangle", "disc", "terrain"):
        return
    ground = surfaces[index]
    for i, s in enumerate(stations):
        if ground.kind == "terrain":
            height = terrain_height(s.position, surfaces, index, hazard)
        else:
            height = float(np.dot(np.subtract(s.position, ground.point), ground.normal))
        if height < 0.0:
            raise err(
                f"stations.{i}.position",
                list(s.position),
                f"is {-height:.4g} m below the ground (surfaces.{index}, the {'hazard map' if hazard else 'first'} "
                "surface, on the side its normal points away from); a station stands on or above it",
            )


def terrain_height(position, surfaces, index: int, hazard) -> float:
    """Height (m) of `position` above terrain surface `index` along its up (its normal), at the
    triangle under it (`scene.terrain.place_terrain`); 0 where no triangle lies under it (off the raster)."""
    from types import SimpleNamespace

    from .terrain import place_terrain

    vertices, triangles = place_terrain(SimpleNamespace(surfaces=surfaces, hazard=hazard), index)
    up = np.asarray(surfaces[index].normal, dtype=np.float64)
    e1 = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    flat = vertices @ np.stack([e1, e2], axis=1)  # (n, 2) horizontal coordinates
    p = np.asarray(position, dtype=np.float64)
    a, b, c = (flat[triangles[:, k]] for k in range(3))
    q = np.array([p @ e1, p @ e2])
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        wb = ((q[0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (q[1] - a[:, 1])) / det
        wc = ((b[:, 0] - a[:, 0]) * (q[1] - a[:, 1]) - (q[0] - a[:, 0]) * (b[:, 1] - a[:, 1])) / det
    inside = np.flatnonzero((det != 0) & (wb >= -1e-12) & (wc >= -1e-12) & (wb + wc <= 1 + 1e-12))
    if not len(inside):
        return 0.0
    t = triangles[inside[0]]
    z = vertices[t] @ up
    ground = z[0] + wb[inside[0]] * (z[1] - z[0]) + wc[inside[0]] * (z[2] - z[0])
    return float(p @ up - ground)


def frame(shot, physics, hazard) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(f, r, up): the downrange axis (unit, horizontal), r = f x up and up = -g / |g|; ValueError
    when the axis is vertical."""
    g = np.asarray(physics.gravity, dtype=np.float64)
    up = -g / np.linalg.norm(g)
    axis = np.asarray(hazard.map_axis if hazard is not None and hazard.map_axis is not None else shot.direction, dtype=np.float64)
    f = axis - np.dot(axis, up) * up
    if np.linalg.norm(f) <= 1e-9 * np.linalg.norm(axis):
        raise ValueError("is vertical: with [[stations]] its horizontal part is the downrange axis azimuths start from")
    f = f / np.linalg.norm(f)
    return f, np.cross(f, up), up


def azimuth_offset(hazard) -> float:
    """Degrees to subtract from a station's azimuth to measure it from the downrange axis: the
    site's azimuth with [hazard.site] (azimuths from north), else 0."""
    return 0.0 if hazard is None or hazard.site is None else float(hazard.site.azimuth)


MAX_INTERLEAVED = 1 << 20  # shots of the weighted sequence computed on the host (`interleave_counts`)


def _integer_weights(weights) -> list[int]:
    """The weights as coprime integers in the same ratios, each weight read as the decimal it was
    written as (the shortest decimal that reads back as its float: 0.7 is 7/10, not the binary
    fraction 3152519739159347/2^52), so that weights such as 0.7 and 0.3 repeat after 10 shots."""
    fractions = [Fraction(repr(float(w))) for w in weights]
    scale = math.lcm(*(f.denominator for f in fractions))
    integers = [int(f * scale) for f in fractions]
    g = math.gcd(*integers)
    return [w // g for w in integers]


def period(weights) -> int:
    """Shots after which the weighted sequence repeats: the sum of the coprime integer weights."""
    return sum(_integer_weights(weights))


def interleaved(weights, shots: int):
    """The stations of the first `shots` shots of the weighted sequence (a generator): Tijdeman's
    solution of the chairman assignment problem (R. Tijdeman, "The chairman assignment problem",
    Discrete Math. 32 (1980) 323-330). Shot n (1-based) goes, among the stations k with
    n p_k - c_k >= 1/(2m - 2) (c_k: its shots so far, p_k its share, m stations), to the one whose
    deadline (c_k + 1 - 1/(2m - 2)) / p_k is earliest, ties to the earlier station; then every
    prefix of n shots gives each station within 1 - 1/(2m - 2) < 1 shot of n p_k. In integers (the
    weights made coprime integers w, W their sum), and periodic: after W shots c = w exactly."""
    w = _integer_weights(weights)
    m, total = len(w), sum(w)
    q = max(2 * m - 2, 1)
    c = [0] * m
    for n in range(1, shots + 1):
        best = -1
        for k in range(m):  # eligible: (n w_k - c_k W) q >= W; earliest (q c_k + q - 1) / w_k
            if (n * w[k] - c[k] * total) * q >= total and (
                best < 0 or (q * c[k] + q - 1) * w[best] < (q * c[best] + q - 1) * w[k]
            ):
                best = k
        c[best] += 1
        yield best


def interleave_counts(weights, points) -> list[list[int]]:
    """Each station's shots among the first n of the weighted sequence (`interleaved`), for each n
    of the increasing `points`: whole periods in closed form, the rest counted."""
    w, size = _integer_weights(weights), period(weights)
    wanted = sorted({n % size for n in points})
    at, c = {0: [0] * len(w)}, [0] * len(w)
    for n, k in enumerate(interleaved(weights, wanted[-1]), start=1):
        c[k] += 1
        at[n] = list(c)
    return [[(n // size) * wk + ck for wk, ck in zip(w, at[n % size])] for n in points]


def shot_pieces(scene, checks=None) -> list[tuple[int, int, int]]:
    """[(first shot, end shot, station)] in shot order: each station fires contiguous shots.
    Without `checks`: one piece a station in scene order, their shots by `allocate`. With `checks`
    (a bounded run's, in shots, increasing: `bound.station_pieces`): between two checks each
    station fires, in scene order, its shots of that stretch of the weighted sequence
    (`interleave_counts`), so a run stopped at a check has fired each station's share within one shot."""
    weights = [s.weight for s in scene.stations]
    if checks is None:
        counts = [allocate(weights, scene.shot.shots)]
    else:
        counts = interleave_counts(weights, checks)
    out, start, before = [], 0, [0] * len(weights)
    for now in counts:
        for k, (a, b) in enumerate(zip(before, now)):
            if b > a:
                out.append((start, start + b - a, k))
                start += b - a
        before = now
    return out


def station_shots(pieces, k: int, shots: int | None = None) -> np.ndarray:
    """The shots (increasing) station k fires in `pieces`, of the first `shots` (None: all)."""
    ranges = [np.arange(a, b if shots is None else min(b, shots)) for a, b, owner in pieces if owner == k]
    return np.concatenate(ranges) if ranges else np.zeros(0, dtype=np.int64)


SHOT_KEY_BIT = 1 << 31  # a shot's stream is keyed (seed, 2^31 + shot): never a pellet's (seed, index < 2^31)


def reference_aims(scene, shots, pieces=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(station index, position (m), unit aim direction) of each shot in `shots`, in float64 and
    pure Python/NumPy: what `launch.stations` draws (the test's reference; `pieces`: a bounded
    run's, `bound.station_pieces`, else `shot_pieces(scene)`)."""
    from math import erf, sqrt
    from statistics import NormalDist

    f, r, up = frame(scene.shot, scene.physics, scene.hazard)
    pieces = shot_pieces(scene) if pieces is None else pieces
    offset = azimuth_offset(scene.hazard)
    mask, golden, unit = (1 << 64) - 1, 0x9E3779B97F4A7C15, 2.0**-24

    def mix(z):
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
        return z ^ (z >> 31)

    def phi(x):
        return 0.5 * (1.0 + erf(x / sqrt(2.0)))

    def coordinate(lo, hi, sigma, bits):
        if sigma is None:
            return lo + (bits * unit) * (hi - lo)
        mid, u = 0.5 * (lo + hi), (bits + 0.5) * unit
        if hi > lo:
            pa, pb = phi((lo - mid) / sigma), phi((hi - mid) / sigma)
            u = pa + u * (pb - pa)
        return mid + sigma * NormalDist().inv_cdf(u)

    out_k, out_p, out_d = [], [], []
    for shot in shots:
        k = next(owner for a, b, owner in pieces if a <= shot < b)
        s = scene.stations[k]
        z = mix((mix(((scene.shot.seed << 32) | (SHOT_KEY_BIT + shot)) & mask) + golden) & mask)
        sigma = None if s.aim_sigma is None else math.radians(s.aim_sigma)
        az = coordinate(*(math.radians(x - offset) for x in s.azimuth), sigma, (z & 0xFFFFFFFF) >> 8)
        el = coordinate(*map(math.radians, s.elevation), sigma, (z >> 32) >> 8)
        out_k.append(k)
        out_p.append(s.position)
        out_d.append(math.cos(el) * (math.cos(az) * f + math.sin(az) * r) + math.sin(el) * up)
    return np.asarray(out_k), np.asarray(out_p, dtype=np.float64), np.asarray(out_d, dtype=np.float64)
