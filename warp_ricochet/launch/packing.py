"""How densely a shot's envelope may be filled when its pellets are sampled without overlaps (runs
with pellet-pellet collisions, `dense.separation`); no Warp here: scenes are checked before
Warp is imported.

Sequential placement with redraws is random sequential addition (RSA) of hard spheres, which jams
at a volume fraction of about 0.38 (Torquato, Uche & Stillinger, Phys. Rev. E 74, 061308, 2006);
near it the free volume, and so the chance that a draw lands in it, vanishes. MAX_PACKING = 0.25
keeps a pellet's redraws few (measured in bench/RESULTS.md) and MAX_REDRAWS far away.
"""

MAX_PACKING = 0.25  # pellet volume / envelope volume
MAX_REDRAWS = 10_000  # new positions a pellet may draw before its shot is declared too dense


def packing_fraction(count: int, diameter: float, envelope_radius: float) -> float:
    """Pellet volume over envelope volume: count (R / R^e)^3."""
    return count * (0.5 * diameter / envelope_radius) ** 3
