"""The laws of flight in air, as `@wp.func`s: drag, Magnus lift and spin decay on a sphere, with
the air at rest but for a uniform wind. Their sources, ranges of validity and what is done outside
them are in docs/air.md. SI units; u = v - wind is the velocity relative to the air.

    dv/dt     = g + a_D + a_L,   a_D = F_D / m,  a_L = F_L / m
    domega/dt = T / I,           I = 2/5 m R^2

- Drag F_D = -1/2 rho C_D A |u| u (A = pi R^2, times the scene's drag_factor). `loth2021`: C_D(M, Re)
  of Loth, Daspit, Jeong, Nagata & Nonomura (2021), AIAA J 59(8):3261, eq. (8a) for Re > 45 and the
  paper's rarefaction branch below, evaluated as f = C_D Re / 24 so that F_D = -3 pi mu d f u is
  finite at u = 0. `constant`: a given C_D. `table`: C_D against Mach, interpolated linearly, held
  at its ends (Braun's shot curve, the G-S sphere function, or the user's).
- Lift F_L = 1/2 rho C_L A |u|^2 (omega x u)/|omega x u| with S = R |omega x u| / |u|^2 (the spin
  across u) is evaluated as 1/2 rho A R (C_L/S) (omega x u): no unit vector of omega x u, finite
  at omega x u = 0 and at u = 0. `loth2008` (Loth 2008, AIAA J 46(4):801), `linear` (C_L = k S),
  `sawicki2003` (Sawicki, Hubbard & Stronge 2003, Am J Phys 71:1152); every law capped at
  C_L = lift_max (sawicki2003's own 0.4; else 0.5, above smooth-sphere data, which level off near
  0.37 for S of 0.5 to 6, so that no law grows without bound at S >> 1).
- Torque T = -(rho/2) R^5 C_R |omega| omega, Re_R = rho d^2 |omega| / mu, evaluated as
  T = -8 pi mu R^3 h omega with h = C_R Re_R / (64 pi) (h = 1 in Stokes flow). `dennis1980`: the fit
  to Dennis, Singh & Ingham (1980), J Fluid Mech 101:257, joined to Stokes; `loth2008`.

tanh (in C_M of Loth 2021 and in Loth 2008's lift) is `make_tanh(precision)`: in float32 on the CPU
from one exp, (1 - e) / (1 + e) with e = exp(-2|x|), its odd Taylor series for |x| < 1/8, where
1 - e cancels, and +-1 from |x| = 9 (e < 2^-25: the formula's own result, without the exp): within a
few ulp of tanh, and a run in air on one CPU core takes a sixth less time
than with the C library's tanhf. On CUDA, and in float64, it is wp.tanh (on the H200 the formula
made a run to rest 29% slower: bench/RESULTS.md).

The laws are chosen at code generation (`make_air_laws(precision, drag, lift, spin_decay)`; lift
or spin_decay None: that term is not compiled). The constants they read are premultiplied on the
host in float64 (`physics.types` Air, `model.air_struct`).
"""

import functools
import math
from types import SimpleNamespace

import warp as wp

from .types import types_for

GAMMA_AIR = 1.4  # ratio of specific heats of air: Loth's rarefaction branch only
DRAG_LAWS = ("loth2021", "constant", "table")
LIFT_LAWS = ("loth2008", "linear", "sawicki2003")
SPIN_DECAY_LAWS = ("dennis1980", "loth2008")


_TANH32 = """
#if defined(__CUDA_ARCH__)
return wp::tanh(x);
#else
float a = wp::abs(x);
if (a < 0.125f) {
    float x2 = x * x;
    return x * (1.0f + x2 * (-0.33333334f + x2 * (0.13333334f + x2 * (-0.053968254f + x2 * 0.021869488f))));
}
if (a >= 9.0f) {
    return x < 0.0f ? -1.0f : 1.0f;
}
float e = wp::exp(-2.0f * a);
float t = (1.0f - e) / (1.0f + e);
return x < 0.0f ? -t : t;
#endif
"""


@wp.func_native(_TANH32)
def tanh32(x: wp.float32) -> wp.float32:
    """float32 tanh(x) (module docstring): on the CPU from one exp, below |x| = 1/8 its odd series
    to x^9 (the next term is 8e-12 of x there), from |x| = 9 +-1 (as the formula rounds); on CUDA
    Warp's tanh."""
    ...


@functools.cache
def make_tanh(precision: str):
    """`tanh(x)` of a precision (the module docstring): float32 `tanh32`, float64 wp.tanh."""
    if precision == "float32":
        return tanh32

    @wp.func
    def tanh(x: wp.float64):
        return wp.tanh(x)

    return tanh


@functools.cache
def make_drag_laws(precision: str):
    """`loth_f(mach, re, kn)` (f = C_D Re/24 of Loth 2021) and `table_cd(mach, machs, cds)`."""
    scalar = types_for(precision).scalar
    SQRT_PI = scalar(math.sqrt(math.pi))
    S_PER_M = scalar(math.sqrt(0.5 * GAMMA_AIR))  # speed ratio s = M sqrt(gamma / 2)
    FM_SERIES = scalar(16.0 / (3.0 * math.sqrt(math.pi)) + 2.0 * math.sqrt(math.pi) / 3.0)
    FM_LINEAR = scalar(16.0 / (15.0 * math.sqrt(math.pi)))
    SERIES_BELOW = scalar(0.1 if precision == "float32" else 3e-3)  # the closed form cancels as s -> 0
    tanh = make_tanh(precision)

    @wp.func
    def loth_factors(mach: scalar):
        """(C_M, G_M, H_M) of Loth et al. (2021) eqs. (7a, 7b, 8b-8e); branch points as jCODE."""
        c_m = scalar(1.65) + scalar(0.65) * tanh(scalar(4.0) * mach - scalar(3.4))
        if mach >= scalar(1.5):
            c_m = scalar(2.18) - scalar(0.13) * tanh(scalar(0.9) * mach - scalar(2.7))
        g_m = ((scalar(166.0) * mach + scalar(3.29)) * mach - scalar(10.9)) * mach + scalar(20.0)
        if mach >= scalar(0.8):
            g_m = scalar(5.0) + scalar(40.0) / (mach * mach * mach)
        h_m = ((scalar(0.0239) * mach + scalar(0.212)) * mach - scalar(0.074)) * mach + scalar(1.0)
        if mach >= scalar(1.0):
            h_m = scalar(0.93) + scalar(1.0) / (scalar(3.5) + mach * mach * mach * mach * mach)
        return c_m, g_m, h_m

    @wp.func
    def free_molecular_cd(s: scalar):
        """Free-molecular sphere drag at speed ratio s (diffuse reflection, wall at the gas
        temperature), by its series where the closed form's s^-3 and s^-4 terms cancel."""
        if s < SERIES_BELOW:
            return FM_SERIES / s + FM_LINEAR * s
        s2 = s * s
        return (
            (scalar(1.0) + scalar(2.0) * s2) * wp.exp(-s2) / (s2 * s * SQRT_PI)
            + (scalar(4.0) * s2 * s2 + scalar(4.0) * s2 - scalar(1.0)) * wp.erf(s) / (scalar(2.0) * s2 * s2)
            + scalar(2.0) * SQRT_PI / (scalar(3.0) * s)
        )

    @wp.func
    def loth_low_f(mach: scalar, re: scalar, kn: scalar):
        """f = C_D Re/24 of Loth (2021)'s rarefaction-dominated branch, Re <= 45 (as jCODE)."""
        f_kn = scalar(1.0) / (scalar(1.0) + kn * (scalar(2.514) + scalar(0.8) * wp.exp(scalar(-0.55) / kn)))
        f1 = (scalar(1.0) + scalar(0.15) * wp.pow(re, scalar(0.687))) * f_kn
        m4 = mach * mach * mach * mach
        if mach < scalar(1e-12):  # the M^4 term is below 1e-12 of f1
            return f1 / (scalar(1.0) + m4)
        j_m = scalar(2.26) - scalar(0.1) / mach + scalar(0.14) / (mach * mach * mach)
        if mach > scalar(1.0):
            j_m = scalar(1.6) + scalar(0.25) / mach + scalar(0.11) / (mach * mach) + scalar(0.44) / (mach * mach * mach)
        cd_fm = free_molecular_cd(mach * S_PER_M)
        r = wp.sqrt(re / scalar(45.0))  # 1 + (C_Dfm/J_M - 1) r, written so a tiny C_Dfm/J_M survives
        cd2 = cd_fm / ((scalar(1.0) - r) + cd_fm / j_m * r)
        return (f1 + re / scalar(24.0) * m4 * cd2) / (scalar(1.0) + m4)

    @wp.func
    def loth_f(mach: scalar, re: scalar, kn: scalar):
        """f = C_D Re / 24 of Loth et al. (2021): eq. (8a) above Re = 45, the rarefaction branch
        below. f -> f_Kn (Stokes drag, slip-corrected) as Re -> 0."""
        if re <= scalar(45.0):
            return loth_low_f(mach, re, kn)
        c_m, g_m, h_m = loth_factors(mach)
        return (scalar(1.0) + scalar(0.15) * wp.pow(re, scalar(0.687))) * h_m + re / scalar(24.0) * scalar(0.42) * c_m / (
            scalar(1.0) + scalar(42500.0) / wp.pow(re, scalar(1.16) * c_m) + g_m / wp.sqrt(re)
        )

    @wp.func
    def table_cd(mach: scalar, machs: wp.array(dtype=scalar), cds: wp.array(dtype=scalar)):
        """C_D from a Mach table (increasing machs): linear between its points, its end values outside."""
        last = machs.shape[0] - 1
        if mach <= machs[0]:
            return cds[0]
        if mach >= machs[last]:
            return cds[last]
        k = wp.int32(1)
        while machs[k] < mach:
            k += 1
        w = (mach - machs[k - 1]) / (machs[k] - machs[k - 1])
        return cds[k - 1] + w * (cds[k] - cds[k - 1])

    return SimpleNamespace(loth_factors=loth_factors, free_molecular_cd=free_molecular_cd, loth_f=loth_f, table_cd=table_cd)


@functools.cache
def make_spin_laws(precision: str):
    """Lift ratios C_L/S and the torque factor h(Re_R) of each law."""
    scalar = types_for(precision).scalar
    H_DENNIS_A = scalar(12.9 / (64.0 * math.pi))
    H_DENNIS_B = scalar(128.4 / (64.0 * math.pi))
    H_LOTH = scalar(5.0 / (64.0 * math.pi))
    tanh = make_tanh(precision)

    @wp.func
    def loth2008_lift_ratio(inverse_s: scalar, re: scalar):
        """C_L/S of Loth (2008): 2 [1 - (0.675 + 0.15 (1 + tanh(0.28 (2S - 2)))) tanh(0.18 sqrt(Re))];
        Rubinow-Keller (2) as Re -> 0, about 0.5 at high Re and small S."""
        s = scalar(1.0) / wp.max(inverse_s, scalar(1e-6))  # (tanh saturates long before S = 1e6)
        return scalar(2.0) * (
            scalar(1.0)
            - (scalar(0.675) + scalar(0.15) * (scalar(1.0) + tanh(scalar(0.28) * (scalar(2.0) * s - scalar(2.0)))))
            * tanh(scalar(0.18) * wp.sqrt(re))
        )

    @wp.func
    def sawicki2003_lift_ratio(inverse_s: scalar, cl_max: scalar):
        """C_L/S of Sawicki, Hubbard & Stronge (2003): C_L = 1.5 S (S <= 0.1), 0.09 + 0.6 S above,
        at most cl_max."""
        ratio = scalar(1.5)
        if inverse_s < scalar(10.0):
            ratio = scalar(0.09) * inverse_s + scalar(0.6)
        return wp.min(ratio, cl_max * inverse_s)

    @wp.func
    def dennis1980_factor(re_r: scalar):
        """h = C_R Re_R / (64 pi) with C_R = max(64 pi / Re_R, 12.9 / sqrt(Re_R) + 128.4 / Re_R):
        Stokes below Re_R = 31.7, the fit to Dennis, Singh & Ingham (1980) above (its range
        32-1000; extrapolated beyond, as laminar boundary-layer scaling)."""
        return wp.max(scalar(1.0), H_DENNIS_A * wp.sqrt(re_r) + H_DENNIS_B)

    @wp.func
    def loth2008_factor(re_r: scalar):
        """h = 1 + 5 / (64 pi) Re_R^0.6 (Loth 2008)."""
        return scalar(1.0) + H_LOTH * wp.pow(re_r, scalar(0.6))

    return SimpleNamespace(
        loth2008_lift_ratio=loth2008_lift_ratio,
        sawicki2003_lift_ratio=sawicki2003_lift_ratio,
        dennis1980_factor=dennis1980_factor,
        loth2008_factor=loth2008_factor,
    )


@functools.cache
def make_air_laws(precision: str, drag: str, lift, spin_decay) -> SimpleNamespace:
    """`air_rates(velocity, spin, air) -> (a_D + a_L, domega/dt)` for the laws chosen: drag one of
    DRAG_LAWS; lift one of LIFT_LAWS or None (no Magnus lift); spin_decay one of SPIN_DECAY_LAWS or
    None (spin unchanged in flight)."""
    if (
        drag not in DRAG_LAWS
        or (lift is not None and lift not in LIFT_LAWS)
        or (spin_decay is not None and spin_decay not in SPIN_DECAY_LAWS)
    ):
        raise ValueError(f"air laws {drag!r}, {lift!r}, {spin_decay!r}: see DRAG_LAWS, LIFT_LAWS, SPIN_DECAY_LAWS")
    t = types_for(precision)
    scalar, vec3, Air = t.scalar, t.vec3, t.Air
    dl, sl = make_drag_laws(precision), make_spin_laws(precision)
    DRAG, LIFT, SPIN = drag, lift, spin_decay

    @wp.func
    def drag_acceleration(u: vec3, speed: scalar, air: Air):
        """a_D = F_D / m (m/s^2) on relative velocity u of length `speed`."""
        if wp.static(DRAG == "loth2021"):
            f = dl.loth_f(speed * air.inverse_sound_speed, speed * air.re_per_speed, air.knudsen)
            return (-air.stokes * f) * u
        elif wp.static(DRAG == "constant"):
            return (-air.quadratic * air.drag_coefficient * speed) * u
        else:
            cd = dl.table_cd(speed * air.inverse_sound_speed, air.table_mach, air.table_cd)
            return (-air.quadratic * cd * speed) * u

    @wp.func
    def lift_acceleration(u: vec3, speed: scalar, spin: vec3, air: Air):
        """a_L = F_L / m = lift (C_L/S) (omega x u) (m/s^2); zero when omega x u is."""
        across = wp.cross(spin, u)
        across_length = wp.length(across)
        ratio = scalar(0.0)
        if across_length > scalar(0.0):
            inverse_s = speed * speed / (air.radius * across_length)
            if wp.static(LIFT == "loth2008"):
                ratio = sl.loth2008_lift_ratio(inverse_s, speed * air.re_per_speed)
            elif wp.static(LIFT == "sawicki2003"):
                ratio = sl.sawicki2003_lift_ratio(inverse_s, air.lift_max)
            else:
                ratio = air.lift_slope
            ratio = wp.min(ratio, air.lift_max * inverse_s)  # C_L <= lift_max, every law (docs/air.md)
        return (air.lift * ratio) * across

    @wp.func
    def spin_rate(spin: vec3, air: Air):
        """domega/dt = T / I = -spin h(Re_R) omega (rad/s^2)."""
        re_r = wp.length(spin) * air.re_r_per_spin
        h = scalar(1.0)
        if wp.static(SPIN == "dennis1980"):
            h = sl.dennis1980_factor(re_r)
        else:
            h = sl.loth2008_factor(re_r)
        return (-air.spin * h) * spin

    @wp.func
    def air_rates(velocity: vec3, spin: vec3, air: Air):
        """The air's part of dv/dt (drag and lift) and domega/dt, at velocity and spin."""
        u = velocity - air.wind
        speed = wp.length(u)
        acceleration = drag_acceleration(u, speed, air)
        if wp.static(LIFT is not None):
            acceleration = acceleration + lift_acceleration(u, speed, spin, air)
        spin_change = vec3()
        if wp.static(SPIN is not None):
            spin_change = spin_rate(spin, air)
        return acceleration, spin_change

    return SimpleNamespace(
        drag_acceleration=drag_acceleration,
        lift_acceleration=lift_acceleration,
        spin_rate=spin_rate,
        air_rates=air_rates,
        spins=SPIN is not None or LIFT is not None,
    )
