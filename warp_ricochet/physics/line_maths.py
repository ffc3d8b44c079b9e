"""The float32-safe forms of `surface_line` (docs/ground.md 9): log1p, L(x) = log1p(x)/x, phi1, phi2,
G(z) = atan(sqrt z)/sqrt z, sin and cos of small angles, and the bracket updates of its root finders."""

import functools
import math
from types import SimpleNamespace

import warp as wp

from .types import types_for


@functools.cache
def make_line_maths(precision: str, noise: tuple = (0.0, 0.0)) -> SimpleNamespace:
    """The float32-safe forms: log1p, L(x) = log1p(x)/x, phi1(x) = expm1(x)/x, G(z) = atan(sqrt z)/sqrt z.

    Each is a series where the direct form cancels (log1p and L: 2 atanh(u), u = x / (2 + x), for
    |x| <= 1/2, |u| <= 1/3, to u^17: 2e-9; phi1: Taylor to x^9 / 10! for |x| <= 1/2: 5e-10; G:
    to z^12 for z <= 1/4: 5e-10) and the direct form elsewhere, where an error of the transcendental
    of relative eps (or absolute eps over [0.5, 2], __logf's) gives at most ~3 eps relative: log(1 + x)
    for 1 + x >= 3/2 is >= 0.405, e^x - 1 for |x| >= 1/2 is >= 0.39 in size, atan(r) / r for r >= 1/2
    is >= 0.785. `noise` = (relative, absolute): every exp, log, sqrt and atan result r becomes
    r (1 + relative) + absolute (log: absolute over [0.5, 2], relative elsewhere) - the tests'
    stand-in for approximate maths."""
    t = types_for(precision)
    scalar = t.scalar
    ZERO, ONE, HALF = scalar(0.0), scalar(1.0), scalar(0.5)
    REL, ABS = scalar(noise[0]), scalar(noise[1])
    NOISY = noise != (0.0, 0.0)
    QUARTER = scalar(0.25)
    H6, H8, H10 = scalar(1.0 / 6.0), scalar(1.0 / 8.0), scalar(1.0 / 10.0)
    H3, H5, H7, H9, H11, H13 = (scalar(1.0 / n) for n in (3, 5, 7, 9, 11, 13))
    H15, H17, H19, H21, H23, H25 = (scalar(1.0 / n) for n in (15, 17, 19, 21, 23, 25))
    F2, F3, F4, F5, F6, F7, F8, F9, F10, F11, F12 = (scalar(1.0 / math.factorial(n)) for n in range(2, 13))

    @wp.func
    def exp_(x: scalar):
        """exp(x) (perturbed by `noise`, relative)."""
        r = wp.exp(x)
        if wp.static(NOISY):
            r = r * (ONE + REL * (ONE + wp.abs(x)))
        return r

    @wp.func
    def log_(x: scalar):
        """log(x) (perturbed by `noise`: absolute over [0.5, 2], relative elsewhere)."""
        r = wp.log(x)
        if wp.static(NOISY):
            if x >= HALF and x <= scalar(2.0):
                r = r + ABS
            else:
                r = r * (ONE + REL)
        return r

    @wp.func
    def sqrt_(x: scalar):
        """sqrt(x) of x >= 0 (perturbed by `noise`, relative)."""
        r = wp.sqrt(wp.max(x, ZERO))
        if wp.static(NOISY):
            r = r * (ONE + REL)
        return r

    @wp.func
    def atanh_series(u: scalar):
        """atanh(u) / u for |u| <= 1/3: 1 + u^2/3 + ... + u^16/17 (Horner)."""
        z = u * u
        s = H17
        s = H15 + z * s
        s = H13 + z * s
        s = H11 + z * s
        s = H9 + z * s
        s = H7 + z * s
        s = H5 + z * s
        s = H3 + z * s
        return ONE + z * s

    @wp.func
    def log_ratio(x: scalar):
        """L(x) = log1p(x) / x for x > -1 (1 at x = 0)."""
        if wp.abs(x) <= HALF:
            return scalar(2.0) / (scalar(2.0) + x) * atanh_series(x / (scalar(2.0) + x))
        return log_(ONE + x) / x

    @wp.func
    def log1p(x: scalar):
        """log(1 + x) for x > -1."""
        return x * log_ratio(x)

    @wp.func
    def phi2_series(x: scalar):
        """The sum of x^j / (j + 2)!, j <= 10 (Horner): phi2 for |x| <= 1 (to 2e-9), and phi1 = 1 + x phi2."""
        s = F12
        s = F11 + x * s
        s = F10 + x * s
        s = F9 + x * s
        s = F8 + x * s
        s = F7 + x * s
        s = F6 + x * s
        s = F5 + x * s
        s = F4 + x * s
        s = F3 + x * s
        return F2 + x * s

    @wp.func
    def phi1(x: scalar):
        """(e^x - 1) / x (1 at x = 0)."""
        if wp.abs(x) <= HALF:
            return ONE + x * phi2_series(x)
        return (exp_(x) - ONE) / x

    @wp.func
    def phi2(x: scalar):
        """(e^x - 1 - x) / x^2 (1/2 at x = 0)."""
        if wp.abs(x) <= ONE:
            return phi2_series(x)
        return (phi1(x) - ONE) / x

    @wp.func
    def secant(lo: scalar, hi: scalar, f_lo: scalar, f_hi: scalar):
        """The regula falsi point of a bracket (f_lo > 0 >= f_hi), or its middle."""
        mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not (mid > lo and mid < hi):
            mid = HALF * (lo + hi)
        return mid

    @wp.func
    def illinois(lo: scalar, hi: scalar, f_lo: scalar, f_hi: scalar, side: wp.int32, at: scalar, f: scalar):
        """The bracket (lo, hi, f_lo, f_hi, side) updated by f at `at`, the kept end's value halved
        after two moves to the same side (Illinois: Dowell & Jarratt, BIT 11 (1971) 168)."""
        if f > ZERO:
            if side == 1:
                f_hi = HALF * f_hi
            return at, hi, f, f_hi, wp.int32(1)
        if side == -1:
            f_lo = HALF * f_lo
        return lo, at, f_lo, f, wp.int32(-1)

    @wp.func
    def atan_ratio(z: scalar):
        """G(z) = atan(sqrt z) / sqrt z for z >= 0 (1 at z = 0)."""
        if z <= QUARTER:  # sum of (-z)^k / (2 k + 1), k <= 12 (Horner)
            s = H25
            s = H23 - z * s
            s = H21 - z * s
            s = H19 - z * s
            s = H17 - z * s
            s = H15 - z * s
            s = H13 - z * s
            s = H11 - z * s
            s = H9 - z * s
            s = H7 - z * s
            s = H5 - z * s
            s = H3 - z * s
            return ONE - z * s
        r = sqrt_(z)
        a = wp.atan(r)
        if wp.static(NOISY):
            a = a * (ONE + REL)
        return a / r

    @wp.func
    def turn(psi: scalar):
        """(cos psi - 1, sin psi) for |psi| <= 1/4 by their series to psi^10 and psi^11 (errors < 2e-14)."""
        z = psi * psi
        c = -HALF * z * (ONE - z * H3 * QUARTER * (ONE - z * H3 * H5 * HALF * (ONE - z * H7 * H8 * (ONE - z * H9 * H10))))
        s = psi * (ONE - z * H3 * HALF * (ONE - z * H5 * QUARTER * (ONE - z * H7 * H6 * (ONE - z * H9 * H8))))
        return c, s

    return SimpleNamespace(
        turn=turn,
        exp=exp_,
        log=log_,
        sqrt=sqrt_,
        log_ratio=log_ratio,
        log1p=log1p,
        phi1=phi1,
        phi2=phi2,
        atan_ratio=atan_ratio,
        secant=secant,
        illinois=illinois,
    )
