"""The collision statistics of a run with pair collisions, from per-shot totals.

Each shot's dense phase ends with one row of SHOT_TOTALS (the dense phase's `shot_totals_kernel`);
chunks keep them in shot order (`/progress/shot_totals` of a run file), and the run's statistics
are exact sums (math.fsum) and maxima of those rows, so they do not depend on the chunk size and a
resumed run's are bitwise those of an uninterrupted one.
"""

import math

SHOT_TOTALS = ("collided", "pair_collisions", "pair_energy_lost", "dense_steps", "dense_end_time", "skin_overrun")
SHOT_TOTALS_UNITS = "1, 1, J, 1, s, 1 (per shot, in shot order: the columns named in `columns`)"

# an overrun below this (in half skins) is rounding of the float32 positions the skin is measured from
OVERRUN_TOLERANCE = 1.01
SKIN_OVERRUN = (
    "a pellet moved {:.2f} half skins between neighbour-list builds (an event in a step, such as a plane "
    "rebound, made it faster than the step allowed for): a pair contact beyond the lists could have been "
    "missed; lower collisions.step_fraction, raise collisions.skin, or set a collisions.time_step short "
    "enough for the rebound speed (docs/collisions.md)"
)


def collision_statistics(table, pellets: int) -> dict:
    """Per-shot totals (rows in shot order) -> the run's collision statistics."""
    collided = math.fsum(table[:, 0])
    return {
        "collided_fraction": collided / pellets,
        "pair_collisions": math.fsum(table[:, 1]) / 2.0,
        "pair_energy_lost": math.fsum(table[:, 2]),
        "pair_energy_lost_mean": math.fsum(table[:, 2]) / pellets,
        "dense_steps_max": float(table[:, 3].max()),
        "dense_time_max": float(table[:, 4].max()),
        "dense_steps_mean": math.fsum(table[:, 3]) / len(table),
        "dense_time_mean": math.fsum(table[:, 4]) / len(table),
        "skin_overrun_max": float(table[:, 5].max()),
    }
