"""Limits the flight code is built with, as numbers (no warp), so the scene can check them."""

MAX_PLANES_IN_AIR = 31  # a flight in air keeps its planes' states in the bits of an int32

# The precision rule (docs/stability.md, "Precision"): a flight of scale M (tallies.sums) holds its
# coordinates to eps M (eps = 2^-24 in float32, 2^-53 in float64); a run warns when that exceeds
# this fraction of the pellet's radius.
POSITION_RESOLUTION = 1.0 / 16.0
UNIT_ROUNDOFF = {"float32": 2.0**-24, "float64": 2.0**-53}
