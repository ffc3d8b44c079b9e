"""Ensemble statistics of a run (Zohdi 2021, section 3.1 and Tables 1-3), in SI units.

The kernels reduce per-pellet quantities into the sums below on the device: per thread (at most
256 pellets) in the working precision, counts in int32; from there on in float64, combined in a
fixed order over fixed segments of pellet indices (see `tallies.reduce.SEGMENT`), so the statistics are
bitwise the same for any chunk size on a given device.

Impact quantities refer to each pellet's first impact, on the plane it hit:
v_t = |tangential velocity|, v_n = signed normal velocity, omega the angular velocity vector,
W_T = m |v|^2 / 2, W_R = I |omega|^2 / 2. Ratios are to the mean launch energy of the same
pellets (the paper's <W(t=0)>). Ranges (eq. 42) run from the last ricochet point to the
landing point; L+ / L- are their maximum / minimum, also split by the branch (stick or slip)
of the last ricochet. The flight scale M of a flight from x0 at speed v0 lasting t under g is
|x0| + |v0| t + |g| t^2 / 2 with |.| the largest absolute component: every coordinate along the
flight is at most M, so the working precision resolves it to eps M (docs/stability.md, "Precision").
"""

from __future__ import annotations

import math

import numpy as np

# the counts the kernels accumulate per thread (int32), then the float sums (working precision
# per thread, float64 from there on); stick = hits - slip, landed_stick = landed - landed_slip
COUNT_NAMES = ("hits", "slip", "landed", "landed_slip")
FLOAT_NAMES = (
    "vt_pre",
    "vn_pre",
    "wx_pre",
    "wy_pre",
    "wz_pre",
    "v2_pre",
    "w2_pre",
    "vt_post",
    "vn_post",
    "wx_post",
    "wy_post",
    "wz_post",
    "v2_post",
    "w2_post",
    "v2_launch",
    "w2_launch",  # launch state of the pellets that hit
    "range",
    "range_m2",
    "range_stick",
    "range_slip",
    "time_aloft",
    "v2_landing",
    "flight_steps",
    "flight_unfinished",  # flight in air: integration steps, flights given up
    "entered",  # pellets that entered the ground or water at their first impact (no ricochet)
    "end_stopped",
    "end_at_rest",
    "end_not_finished",  # physics.until = "rest": pellets that stopped (at rest or embedded), at rest, not finished
    "end_distance",
    "end_distance_m2",
    "end_shift",  # rest distances of the stopped pellets (as the ranges; end_shift: a thread's first, 0 once stored)
    "end_path",
    "end_impacts",  # path lengths along surfaces of the stopped pellets, impacts of all pellets
    "end_steps",  # integration steps after the landing (flights in air and motion along surfaces), all pellets
)  # range_m2, end_distance_m2: squared deviations from their mean, merged with Chan's formula
SUM_NAMES = COUNT_NAMES + FLOAT_NAMES
SUM = {name: i for i, name in enumerate(SUM_NAMES)}
NUM_SUMS = len(SUM_NAMES)
NUM_COUNTS = len(COUNT_NAMES)
NUM_FLOATS = len(FLOAT_NAMES)
# extremes of the range: all landed pellets, last ricochet stuck, last ricochet slipped; then the
# flight scale (its maximum only: the precision rule, docs/stability.md "Precision")
EXTREME_NAMES = ("all", "stick", "slip", "flight_scale", "rest")
FLIGHT_SCALE = EXTREME_NAMES.index("flight_scale")
REST = EXTREME_NAMES.index("rest")  # the rest distances of the stopped pellets (physics.until = "rest")
# the (count, sum, squared deviations) rows whose spreads are merged by Chan's formula: ranges, rest distances
SPREADS = (("landed", "range", "range_m2"), ("end_stopped", "end_distance", "end_distance_m2"))
NUM_EXTREMES = len(EXTREME_NAMES)

# name -> (unit, description) of every statistic `finalize` returns
STAT_UNITS = {
    "pellets": ("1", "pellets launched"),
    "hits": ("1", "pellets that hit a surface"),
    "missed": ("1", "pellets that never hit a surface"),
    "entered": ("1", "pellets that entered the ground or water at their first impact, without a ricochet (physics.ground)"),
    "stick": ("1", "first impacts that stuck (eq. 22 not met)"),
    "slip": ("1", "first impacts that slipped (eq. 22)"),
    "landed": ("1", "pellets that landed after their last ricochet"),
    "escaped": ("1", "pellets that ricocheted and never met a surface again"),
    "pre_mean_vt": ("m/s", "mean tangential speed before the first impact"),
    "pre_mean_vn": ("m/s", "mean normal velocity before the first impact"),
    "pre_norm_mean_omega": ("rad/s", "norm of the mean angular velocity before the first impact"),
    "pre_mean_WT": ("J", "mean translational energy before the first impact"),
    "pre_mean_WR": ("J", "mean rotational energy before the first impact"),
    "pre_ratio_WT": ("1", "pre_mean_WT / mean launch energy"),
    "pre_ratio_WR": ("1", "pre_mean_WR / mean launch energy"),
    "post_mean_vt": ("m/s", "mean tangential speed after the first impact"),
    "post_mean_vn": ("m/s", "mean normal velocity after the first impact"),
    "post_norm_mean_omega": ("rad/s", "norm of the mean angular velocity after the first impact"),
    "post_mean_WT": ("J", "mean translational energy after the first impact"),
    "post_mean_WR": ("J", "mean rotational energy after the first impact"),
    "post_ratio_WT": ("1", "post_mean_WT / mean launch energy"),
    "post_ratio_WR": ("1", "post_mean_WR / mean launch energy"),
    "launch_mean_W": ("J", "mean launch energy (translational + rotational) of the pellets that hit"),
    "range_mean": ("m", "mean range <L> (eq. 42) of the landed pellets"),
    "range_std": ("m", "standard deviation of the range"),
    "range_max": ("m", "L+, the largest range"),
    "range_min": ("m", "L-, the smallest range"),
    "range_stick_mean": ("m", "mean range of pellets whose last ricochet stuck"),
    "range_stick_max": ("m", "L+ of pellets whose last ricochet stuck"),
    "range_stick_min": ("m", "L- of pellets whose last ricochet stuck"),
    "range_slip_mean": ("m", "mean range of pellets whose last ricochet slipped"),
    "range_slip_max": ("m", "L+ of pellets whose last ricochet slipped"),
    "range_slip_min": ("m", "L- of pellets whose last ricochet slipped"),
    "mean_time_aloft": ("s", "mean time from the last ricochet to landing"),
    "landing_mean_WT": ("J", "mean translational energy at landing"),
    "flight_scale_max": (
        "m",
        "largest flight scale M = |x0| + |v0| t + |g| t^2 / 2 (largest components) of a flight "
        "that met a surface; positions are resolved to about eps M (docs/stability.md)",
    ),
    # runs with pellet-pellet collisions
    "collided_fraction": ("1", "fraction of the pellets that collided with another pellet"),
    "pair_collisions": ("1", "pellet-pellet collisions"),
    "pair_energy_lost": ("J", "kinetic energy lost in pellet-pellet collisions, all pellets"),
    "pair_energy_lost_mean": ("J", "pair_energy_lost per pellet launched"),
    "dense_steps_max": ("1", "most time steps a shot took in the dense phase"),
    "dense_time_max": ("s", "latest time a shot left the dense phase (s since launch)"),
    "dense_steps_mean": ("1", "time steps a shot took in the dense phase, mean over shots"),
    "dense_time_mean": ("s", "time a shot left the dense phase (s since launch), mean over shots"),
    "skin_overrun_max": (
        "1",
        "largest distance a pellet moved between neighbour-list builds, in half skins, when "
        "above 1 (0 otherwise); above 1 a pair contact beyond the lists could have been missed",
    ),
    # runs in air
    "flight_steps_mean": ("1", "integration steps of a pellet's flights in air (after the dense phase), mean over pellets"),
    "flights_unfinished": ("1", "flights in air given up after MAX_FLIGHT_STEPS steps (counted as escaped)"),
    # runs that follow every pellet to where it ends (physics.until = "rest", `ends`, docs/ground.md)
    "rest_at_rest": ("1", "pellets that ended at rest on a surface"),
    "rest_embedded": ("1", "pellets that ended in water or soft ground"),
    "rest_escaped": ("1", "pellets that never met a surface again"),
    "rest_not_finished": ("1", "pellets whose budget of impacts and steps ran out first (never counted at rest)"),
    "rest_distance_mean": ("m", "mean rest distance from the shooter (horizontal) of the pellets at rest or embedded"),
    "rest_distance_std": ("m", "standard deviation of the rest distance"),
    "rest_distance_max": ("m", "largest rest distance"),
    "rest_distance_min": ("m", "smallest rest distance"),
    "rest_path_mean": ("m", "mean path length along surfaces of the pellets at rest or embedded"),
    "rest_impacts_mean": ("1", "mean number of impacts of a pellet, all pellets launched"),
    "rest_steps_mean": ("1", "mean integration steps of a pellet after its landing (flights in air, motion along surfaces)"),
}
REST_STATS = tuple(name for name in STAT_UNITS if name.startswith("rest_"))
COLLISION_STATS = (
    "collided_fraction",
    "pair_collisions",
    "pair_energy_lost",
    "pair_energy_lost_mean",
    "dense_steps_max",
    "dense_time_max",
    "dense_steps_mean",
    "dense_time_mean",
    "skin_overrun_max",
)
AIR_STATS = ("flight_steps_mean", "flights_unfinished")


def empty_totals():
    """Identity elements: zero sums, +inf minima, -inf maxima, no segments."""
    return (
        np.zeros(NUM_SUMS),
        np.full(NUM_EXTREMES, math.inf),
        np.full(NUM_EXTREMES, -math.inf),
        np.zeros((0, 3 * len(SPREADS))),
    )


def combine(totals, segment_results):
    """Fold per-segment results (rows in pellet order: NUM_SUMS sums, then NUM_EXTREMES minima and
    NUM_EXTREMES maxima) into running totals.

    Sums are added strictly left to right (np.cumsum is sequential), so they do not depend on how
    the segments were split into chunks. Each segment's (count, sum, m2) of each of SPREADS is kept
    (48 bytes per 65,536 pellets) for `finalize` to merge the spreads in one stable pass.
    """
    sums, mins, maxs, segments = totals
    segment_sums = segment_results[:, :NUM_SUMS]
    segment_mins = segment_results[:, NUM_SUMS : NUM_SUMS + NUM_EXTREMES]
    segment_maxs = segment_results[:, NUM_SUMS + NUM_EXTREMES :]
    if len(segment_sums):
        spread = segment_sums[:, [SUM[name] for names in SPREADS for name in names]]
        segments = np.vstack([segments, spread])
        sums = np.cumsum(np.vstack([sums[None, :], segment_sums]), axis=0)[-1]
        mins = np.minimum(mins, segment_mins.min(axis=0))
        maxs = np.maximum(maxs, segment_maxs.max(axis=0))
    return sums, mins, maxs, segments


def merged_m2(segments, k: int = 0) -> float:
    """Squared deviations about the overall mean from per-segment (n, sum, m2) (columns 3k to
    3k + 2: SPREADS[k]): the segments' own plus n_s (mean_s - mean)^2 (Chan et al.: no
    cancellation, so numerically stable)."""
    n, total, m2 = segments[:, 3 * k], segments[:, 3 * k + 1], segments[:, 3 * k + 2]
    landed = n > 0
    if not landed.any():
        return 0.0
    mean = total.sum() / n.sum()
    return float(m2[landed].sum() + (n[landed] * (total[landed] / n[landed] - mean) ** 2).sum())


def finalize(totals, *, pellets: int, mass: float, inertia: float, air: bool = False, rest: bool = False) -> dict[str, float]:
    """Turn the reduced sums into the statistics of `STAT_UNITS` (NaN where a mean is empty)."""
    sums, mins, maxs, segments = totals
    rows = finalize_rows(
        sums[None, :],
        mins[None, :],
        maxs[None, :],
        np.array([merged_m2(segments)]),
        pellets=pellets,
        mass=mass,
        inertia=inertia,
        air=air,
        rest_m2=np.array([merged_m2(segments, 1)]) if rest else None,
    )
    return {name: float(values[0]) for name, values in rows.items()}


def finalize_rows(
    sums, mins, maxs, range_m2, *, pellets: int, mass: float, inertia: float, air: bool = False, rest_m2=None
) -> dict[str, np.ndarray]:
    """`finalize` of many totals at once (rows: sums (K, NUM_SUMS), range minima and maxima
    (K, NUM_EXTREMES), merged range_m2 (K,); with `rest_m2`, the merged end_distance_m2 (K,), the
    statistics of where pellets end, REST_STATS): name -> (K,) values, each row's bitwise as
    `finalize` gives it (elementwise IEEE operations; the norm row by row)."""
    s = {name: sums[:, i] for i, name in enumerate(SUM_NAMES)}
    s["range_m2"] = np.asarray(range_m2, np.float64)
    nan = np.full(len(sums), math.nan)

    def mean(key, count):
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(s[count] > 0, s[key] / s[count], nan)

    def extreme(value, count):
        return np.where(s[count] > 0, value, nan)

    def ratio(energy, launch):
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(launch > 0, energy / launch, nan)

    launch_energy = 0.5 * mass * mean("v2_launch", "hits") + 0.5 * inertia * mean("w2_launch", "hits")
    out = {
        "pellets": np.full(len(sums), float(pellets)),
        "hits": s["hits"],
        "missed": float(pellets) - s["hits"] - s["entered"],
        "entered": s["entered"],
        "stick": s["hits"] - s["slip"],
        "slip": s["slip"],
        "landed": s["landed"],
        "escaped": s["hits"] - s["landed"],
        "launch_mean_W": launch_energy,
    }
    for phase in ("pre", "post"):
        omega = np.stack([mean(f"w{axis}_{phase}", "hits") for axis in "xyz"], axis=1)
        energy_t = 0.5 * mass * mean(f"v2_{phase}", "hits")
        energy_r = 0.5 * inertia * mean(f"w2_{phase}", "hits")
        out[f"{phase}_mean_vt"] = mean(f"vt_{phase}", "hits")
        out[f"{phase}_mean_vn"] = mean(f"vn_{phase}", "hits")
        out[f"{phase}_norm_mean_omega"] = np.array([float(np.linalg.norm(row)) for row in omega])
        out[f"{phase}_mean_WT"] = energy_t
        out[f"{phase}_mean_WR"] = energy_r
        out[f"{phase}_ratio_WT"] = ratio(energy_t, launch_energy)
        out[f"{phase}_ratio_WR"] = ratio(energy_r, launch_energy)
    out["range_mean"] = mean("range", "landed")
    out["range_std"] = np.where(s["landed"] > 0, np.sqrt(np.maximum(mean("range_m2", "landed"), 0.0)), nan)
    out["range_max"] = extreme(maxs[:, 0], "landed")
    out["range_min"] = extreme(mins[:, 0], "landed")
    s["landed_stick"] = s["landed"] - s["landed_slip"]
    for j, branch in enumerate(EXTREME_NAMES[1:FLIGHT_SCALE], start=1):
        out[f"range_{branch}_mean"] = mean(f"range_{branch}", f"landed_{branch}")
        out[f"range_{branch}_max"] = extreme(maxs[:, j], f"landed_{branch}")
        out[f"range_{branch}_min"] = extreme(mins[:, j], f"landed_{branch}")
    out["mean_time_aloft"] = mean("time_aloft", "landed")
    out["landing_mean_WT"] = 0.5 * mass * mean("v2_landing", "landed")
    out["flight_scale_max"] = np.where(maxs[:, FLIGHT_SCALE] >= 0, maxs[:, FLIGHT_SCALE], nan)
    if air:
        out["flight_steps_mean"] = s["flight_steps"] / pellets if pellets else nan
        out["flights_unfinished"] = s["flight_unfinished"]
    if rest_m2 is not None:
        s["end_distance_m2"] = np.asarray(rest_m2, np.float64)
        out.update(_rest_rows(s, mins, maxs, pellets, mean, extreme, nan))
    assert set(out) == set(stat_names(False, air, rest_m2 is not None)) - set(COLLISION_STATS)
    return out


def _rest_rows(s, mins, maxs, pellets, mean, extreme, nan) -> dict[str, np.ndarray]:
    """REST_STATS from the sums `s` (end_distance_m2 merged): embedded = stopped - at rest,
    escaped = pellets - stopped - not finished."""
    return {
        "rest_at_rest": s["end_at_rest"],
        "rest_embedded": s["end_stopped"] - s["end_at_rest"],
        "rest_escaped": float(pellets) - s["end_stopped"] - s["end_not_finished"],
        "rest_not_finished": s["end_not_finished"],
        "rest_distance_mean": mean("end_distance", "end_stopped"),
        "rest_distance_std": np.where(
            s["end_stopped"] > 0, np.sqrt(np.maximum(mean("end_distance_m2", "end_stopped"), 0.0)), nan
        ),
        "rest_distance_max": extreme(maxs[:, REST], "end_stopped"),
        "rest_distance_min": extreme(mins[:, REST], "end_stopped"),
        "rest_path_mean": mean("end_path", "end_stopped"),
        "rest_impacts_mean": s["end_impacts"] / pellets if pellets else nan,
        "rest_steps_mean": s["end_steps"] / pellets if pellets else nan,
    }


def statistics_from_arrays(
    *,
    pellets,
    mass,
    inertia,
    launch_velocity,
    launch_angular_velocity,
    hit,
    normal,
    velocity_before,
    angular_velocity_before,
    velocity_after,
    angular_velocity_after,
    slipped_first,
    landed,
    range_,
    slipped_last,
    time_aloft,
    landing_velocity,
    flight_scale=None,
) -> dict[str, float]:
    """The same statistics from per-pellet float64 arrays (the NumPy reference path); flight_scale:
    each pellet's largest flight scale (m, NaN where none of its flights met a surface)."""
    sums = np.zeros(NUM_SUMS)
    h = np.asarray(hit, bool)
    n = normal[h]

    def tangential(v):
        vn = np.einsum("ij,ij->i", v, n)
        return np.linalg.norm(v - vn[:, None] * n, axis=1), vn

    sums[SUM["hits"]] = h.sum()
    sums[SUM["slip"]] = np.asarray(slipped_first)[h].sum()
    for phase, v, w in (
        ("pre", velocity_before[h], angular_velocity_before[h]),
        ("post", velocity_after[h], angular_velocity_after[h]),
    ):
        vt, vn = tangential(v)
        sums[SUM[f"vt_{phase}"]] = vt.sum()
        sums[SUM[f"vn_{phase}"]] = vn.sum()
        for axis, name in enumerate("xyz"):
            sums[SUM[f"w{name}_{phase}"]] = w[:, axis].sum()
        sums[SUM[f"v2_{phase}"]] = (v * v).sum()
        sums[SUM[f"w2_{phase}"]] = (w * w).sum()
    sums[SUM["v2_launch"]] = (launch_velocity[h] ** 2).sum()
    sums[SUM["w2_launch"]] = (launch_angular_velocity[h] ** 2).sum()
    land = np.asarray(landed, bool)
    last_slip = np.asarray(slipped_last, bool)
    r = np.asarray(range_)
    sums[SUM["landed"]] = land.sum()
    sums[SUM["range"]] = r[land].sum()
    sums[SUM["range_m2"]] = ((r[land] - r[land].mean()) ** 2).sum() if land.any() else 0.0
    sums[SUM["time_aloft"]] = np.asarray(time_aloft)[land].sum()
    sums[SUM["v2_landing"]] = (landing_velocity[land] ** 2).sum()
    mins, maxs = np.full(NUM_EXTREMES, math.inf), np.full(NUM_EXTREMES, -math.inf)
    if flight_scale is not None and np.isfinite(flight_scale).any():
        maxs[FLIGHT_SCALE] = np.nanmax(flight_scale)
    for j, mask in enumerate((land, land & ~last_slip, land & last_slip)):
        if j:
            branch = EXTREME_NAMES[j]
            sums[SUM[f"range_{branch}"]] = r[mask].sum()
            if branch == "slip":
                sums[SUM["landed_slip"]] = mask.sum()
        if mask.any():
            mins[j], maxs[j] = r[mask].min(), r[mask].max()
    spread = np.array([[sums[SUM[name]] for names in SPREADS for name in names]])
    return finalize((sums, mins, maxs, spread), pellets=pellets, mass=mass, inertia=inertia)


def stat_names(collisions: bool, air: bool = False, rest: bool = False) -> tuple[str, ...]:
    """The statistics a run computes: those of `finalize`, with pair collisions COLLISION_STATS,
    in air AIR_STATS, followed to rest (physics.until = "rest") REST_STATS."""
    return tuple(
        name
        for name in STAT_UNITS
        if (collisions or name not in COLLISION_STATS) and (air or name not in AIR_STATS) and (rest or name not in REST_STATS)
    )
