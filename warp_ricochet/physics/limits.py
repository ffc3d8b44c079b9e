"""Limits the flight code is built with, as numbers (no warp), so the scene can check them."""

MAX_PLANES_IN_AIR = 31  # a flight in air keeps its planes' states in the bits of an int32
