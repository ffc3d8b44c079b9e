"""The histogram bins of the landing tallies (quantiles, tail fractions, danger distances).

A value x >= 0 is binned by the bits of float32(x): its exponent and its top MANTISSA_BITS mantissa
bits (as HDR histograms do). So the bins are log-spaced, each of relative width at most
2^-MANTISSA_BITS (0.098%), over the span [2^E_LO, 2^(E_LO + OCTAVES)) = [2.3e-10, 4.3e9) in SI units;
bin 0 counts what lies below (zero included), bin BINS - 1 what lies above (and NaN, whatever its
sign bit). The binning is exact integer arithmetic on the value's bits: the same value falls in the
same bin on every device, and NumPy reproduces it (`bin_index`). This module imports no Warp at module level.
"""

from __future__ import annotations

import functools

import numpy as np

MANTISSA_BITS = 10
SHIFT = 23 - MANTISSA_BITS  # float32 has 23 mantissa bits
E_LO = -32  # 2^-32 = 2.3e-10 (m, m/s, J)
OCTAVES = 64
REGULAR = OCTAVES << MANTISSA_BITS  # regular bins
BINS = REGULAR + 2  # with the underflow (0) and overflow (BINS - 1) bins
BASE = (127 + E_LO) << MANTISSA_BITS  # (float32 bits >> SHIFT) of 2^E_LO
RELATIVE_WIDTH = 2.0**-MANTISSA_BITS
ROW_RANGE, ROW_SPEED, ROW_DISTANCE = 0, 1, 2  # rows of the landing histograms: range, speed, distance by hazard level
RESOLUTION = (
    f"log-spaced bins from the float32 bits (exponent and top {MANTISSA_BITS} mantissa bits): "
    f"relative width <= 2^-{MANTISSA_BITS} = {RELATIVE_WIDTH:.4%}, span [2^{E_LO}, 2^{E_LO + OCTAVES}) "
    "(SI units), counts below and above the span kept in the first and last bins"
)


@functools.cache
def edges() -> np.ndarray:
    """The BINS + 1 bin edges (float64, read-only): 0, the REGULAR + 1 edges of the span, inf."""
    bits = ((np.arange(REGULAR + 1, dtype=np.int64) + BASE) << SHIFT).astype(np.uint32)
    inner = bits.view(np.float32).astype(np.float64)
    out = np.concatenate([[0.0], inner, [np.inf]])
    out.setflags(write=False)
    return out


def bin_index(values) -> np.ndarray:
    """The bin of each value, as the kernels compute it (reference for tests)."""
    values = np.asarray(values, dtype=np.float32)
    k = (values.view(np.int32).astype(np.int64) >> SHIFT) - BASE
    return np.where(np.isnan(values), BINS - 1, np.where(k < 0, 0, np.where(k >= REGULAR, BINS - 1, k + 1)))


@functools.cache
def make_bin_of():
    """The Warp function bin_of(x: float32) -> int32 of the rule above."""
    import warp as wp

    shift, base, regular = SHIFT, BASE, REGULAR

    @wp.func
    def bin_of(x: wp.float32):
        k = (wp.cast(x, wp.int32) >> shift) - base  # arithmetic shift: negative values stay negative
        b = k + 1
        if k < 0:
            b = 0
        elif k >= regular:
            b = regular + 1
        if x != x:  # NaN, whatever its sign bit (a NaN of x86 arithmetic has it set)
            b = regular + 1
        return b

    return bin_of
