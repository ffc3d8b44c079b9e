"""Vectors that only give a direction (`shot.direction` with its `direction_jitter`, surface normals),
scaled on the host in float64 by a power of two so that their largest component lies in
[2^-20, 2^20).

Multiplying by a power of two is exact in binary floating point (for results above the smallest
normal number), and so are the sums, products, square roots and quotients that turn such a
vector into a unit vector: scaled, a direction gives bitwise the same unit vector, while its
squared length no longer underflows (a component of 1e-30 squares to 0 in float32, 1e-165 to 0
in float64). A vector whose largest component already lies in the range is left as it is.
"""

from __future__ import annotations

import math

LOWEST, HIGHEST = -20, 20  # the largest component is brought into [2^LOWEST, 2^HIGHEST)


def scale_exponent(*vectors) -> int:
    """k such that 2^k times the largest absolute component of `vectors` lies in [2^-20, 2^20):
    0 when it already does (or all are zero), else the k that brings it into [1/2, 1)."""
    largest = max((abs(x) for v in vectors for x in v), default=0.0)
    if largest == 0.0:
        return 0
    exponent = math.frexp(largest)[1]  # largest in [2^(exponent - 1), 2^exponent)
    return 0 if LOWEST < exponent <= HIGHEST else -exponent


def scaled(vector, k: int) -> tuple[float, ...]:
    """`vector` times 2^k (exact in float64 for every component that stays a normal number)."""
    return tuple(math.ldexp(float(x), k) for x in vector)


def unit_vector(vector) -> tuple[float, ...]:
    """`vector` (non-zero) scaled to unit length in float64, without underflow or overflow."""
    v = scaled(vector, scale_exponent(vector))
    norm = math.hypot(*v)
    return tuple(x / norm for x in v)
