"""The ground's laws at an impact, as `@wp.func`s (docs/ground.md, "Ground materials" and "Rough ground").

`make_ground(precision)` returns, for the core loop to call at every impact on a surface of
`Material` m (`physics.geometry.material`, `types.Material`; angles in radians):

- `draw(m, normal, velocity, seed, pellet, impact) -> (Material, vec3)`: rough ground. The local
  normal is tilted by an angle with the Rayleigh distribution of mode `m.roughness` (isotropic
  Gaussian slopes), towards an azimuth uniform in [0, 2 pi); a tilted normal the pellet would not
  strike (v . n' >= 0) takes the opposite azimuth (+ pi), which it does strike (the two sum to
  2 cos(tilt) v . n < 0: a pellet meets the facets that face it). E is drawn from the two-sided
  exponential of Montaine et al. (arXiv 1104.0049) with mean m.restitution, below-mode width
  lambda_1 = restitution_scatter E and above-mode width lambda_1 / 3, clipped to [0, 1]; mu_s and
  mu_d are multiplied by one log-normal factor exp(s Z - s^2/2) (mean 1, s = friction_scatter; mu_d
  <= mu_s kept). Each part is drawn only where its parameter is above 0: without roughness and
  scatter the inputs come back unchanged, bitwise.
- `embeds(m, velocity, normal) -> int32`: 1 when the pellet strikes steeper (from the surface) than
  theta_c(v) = critical_angle + critical_angle_rise min(|v|, critical_speed); 0 when theta_c >= pi/2.
- `sinks(m) -> int32`: 1 on a liquid (water): a pellet that would stay on it is embedded.
- `skip(m, velocity, normal, spin) -> (vec3, vec3)`: a skip off water (below theta_c): the velocity
  mirrored about the surface with its speed times exp(-2 theta skip_loss), theta the impact angle
  (the Birkhoff-Johnson model with the water's force at a fixed angle beta to the velocity's normal,
  tan(beta) = skip_loss: d ln|v| = -tan(beta) d(turn), and the velocity turns by 2 theta); the spin
  unchanged (water exerts no Coulomb friction at a contact point). Never more speed than it received.
- `critical_angle_at(m, speed) -> scalar`: theta_c at that speed (rad).

Random bits: a counter-based SplitMix64 stream (`launch.sampling.mix64`) keyed by (seed, pellet,
impact): key = mix64(mix64(mix64(seed 2^32 + pellet) ^ GROUND_SALT) + impact golden), a stream
distinct from the launch's (which uses mix64(seed 2^32 + pellet) + k golden, k small), and outputs
mix64(key + j golden), j = 1, 2, 3: six 24-bit uniforms, centred in (0, 1) (no log of 0). So a draw
depends only on (seed, pellet, impact): the same for any chunk size, device and on resume; the
uniforms are cast to the working precision before any arithmetic (`reference_ground_uniforms`
gives them in Python).
"""

import functools
import math
from types import SimpleNamespace

import warp as wp

from ..launch.sampling import GOLDEN, UNIT24, mix64
from .types import types_for

GROUND_SALT = wp.constant(wp.uint64(0x6A09E667F3BCC909))  # frac(sqrt(2)) 2^64 (SHA-512's first IV word)
ABOVE_MODE = 1.0 / 3.0  # E's width above its mode, as a fraction of the width below (an estimate, docs/ground.md)
TWO_PI = 2.0 * math.pi


def reference_ground_uniforms(seed: int, pellet: int, impact: int) -> list:
    """The six uniforms in (0, 1) of impact `impact` of pellet `pellet` of `seed`, in pure Python
    (what `draw` uses: tilt, azimuth, restitution, two for the friction's normal, one spare)."""
    seed, pellet, impact = int(seed), int(pellet), int(impact)  # (Python's integers: no 64-bit overflow)
    mask = (1 << 64) - 1
    golden = 0x9E3779B97F4A7C15

    def mix(z):
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
        return z ^ (z >> 31)

    key = mix((mix(mix((seed << 32) | pellet) ^ 0x6A09E667F3BCC909) + impact * golden) & mask)
    out = []
    for j in (1, 2, 3):
        z = mix((key + j * golden) & mask)
        out += [(((z & 0xFFFFFFFF) >> 8) + 0.5) * UNIT24, (((z >> 32) >> 8) + 0.5) * UNIT24]
    return out


@functools.cache
def make_ground(precision: str) -> SimpleNamespace:
    """`draw`, `embeds`, `sinks`, `skip` and `critical_angle_at` of one precision ("float32" or "float64")."""
    t = types_for(precision)
    scalar, vec3, Material = t.scalar, t.vec3, t.Material
    ZERO, ONE, HALF = scalar(0.0), scalar(1.0), scalar(0.5)
    HALF_PI = scalar(0.5 * math.pi)  # rounded as the surfaces' pi/2 (types.RIGID_PLANE): equal, so never embeds

    @wp.func
    def uniform(bits: wp.uint32):
        """A 24-bit uniform in (0, 1) from the word's top bits, centred in its cell."""
        return (scalar(bits >> wp.uint32(8)) + HALF) * scalar(UNIT24)

    @wp.func
    def stream(seed: wp.int32, pellet: wp.int32, impact: wp.int32):
        """The three 64-bit outputs of (seed, pellet, impact)'s ground stream."""
        pellet_key = mix64((wp.uint64(seed) << wp.uint64(32)) | wp.uint64(pellet))
        key = mix64(mix64(pellet_key ^ GROUND_SALT) + wp.uint64(impact) * GOLDEN)
        return mix64(key + GOLDEN), mix64(key + wp.uint64(2) * GOLDEN), mix64(key + wp.uint64(3) * GOLDEN)

    @wp.func
    def tangents(n: vec3):
        """An orthonormal pair (e1, e2) perpendicular to unit n (Duff et al., JCGT 6(1) 2017, branchless)."""
        sign = wp.where(n[2] >= ZERO, ONE, -ONE)
        a = -ONE / (sign + n[2])
        b = n[0] * n[1] * a
        e1 = vec3(ONE + sign * n[0] * n[0] * a, sign * b, -sign * n[0])
        e2 = vec3(b, sign + n[1] * n[1] * a, -n[1])
        return e1, e2

    @wp.func
    def tilted(normal: vec3, velocity: vec3, roughness: scalar, u_tilt: scalar, u_azimuth: scalar):
        """The normal tilted by a Rayleigh angle of mode `roughness` towards a uniform azimuth, the
        opposite azimuth when the pellet would not strike it (unchanged if neither faces it)."""
        tilt = roughness * wp.sqrt(-scalar(2.0) * wp.log(u_tilt))
        azimuth = scalar(TWO_PI) * u_azimuth
        e1, e2 = tangents(normal)
        along = wp.cos(azimuth) * e1 + wp.sin(azimuth) * e2
        c = wp.cos(tilt)
        s = wp.sin(tilt)
        n = c * normal + s * along
        if wp.dot(velocity, n) >= ZERO:
            n = c * normal - s * along
            if wp.dot(velocity, n) >= ZERO:
                n = normal  # grazing within rounding: no facet it strikes
        return n

    @wp.func
    def scattered_restitution(mean: scalar, scatter: scalar, u: scalar):
        """Montaine's two exponentials: below the mode width l1 = scatter mean, above l1 ABOVE_MODE,
        the mode mean + l1 - l2 so the mean is `mean` (before the clip to [0, 1])."""
        below = scatter * mean
        above = below * scalar(ABOVE_MODE)
        mode = mean + below - above
        p_below = below / (below + above)
        e = mode
        if u < p_below:
            e = mode + below * wp.log(u / p_below)
        else:
            e = mode - above * wp.log((ONE - u) / (ONE - p_below))
        return wp.clamp(e, ZERO, ONE)

    @wp.func
    def draw(material: Material, normal: vec3, velocity: vec3, seed: wp.int32, pellet: wp.int32, impact: wp.int32):
        """(material, normal) of this impact on rough ground (module docstring); unchanged without roughness."""
        m = material
        n = normal
        if material.roughness > ZERO or material.restitution_scatter > ZERO or material.friction_scatter > ZERO:
            a, b, c = stream(seed, pellet, impact)
            if material.roughness > ZERO:
                n = tilted(normal, velocity, material.roughness, uniform(wp.uint32(a)), uniform(wp.uint32(a >> wp.uint64(32))))
            if material.restitution_scatter > ZERO and material.restitution > ZERO:
                u = uniform(wp.uint32(b))
                m.restitution = scattered_restitution(material.restitution, material.restitution_scatter, u)
            if material.friction_scatter > ZERO:
                u1 = uniform(wp.uint32(b >> wp.uint64(32)))
                u2 = uniform(wp.uint32(c))
                z = wp.sqrt(-scalar(2.0) * wp.log(u1)) * wp.cos(scalar(TWO_PI) * u2)  # Box-Muller
                s = material.friction_scatter
                factor = wp.exp(s * z - HALF * s * s)
                m.mu_s = material.mu_s * factor
                m.mu_d = material.mu_d * factor
        return m, n

    @wp.func
    def critical_angle_at(material: Material, speed: scalar):
        """theta_c (rad) at `speed` (m/s): critical_angle + critical_angle_rise min(speed, critical_speed)."""
        return material.critical_angle + material.critical_angle_rise * wp.min(speed, material.critical_speed)

    @wp.func
    def embeds(material: Material, velocity: vec3, normal: vec3):
        """1 when the pellet strikes steeper than theta_c at its speed (sin theta = -v.n / |v|)."""
        speed = wp.length(velocity)
        theta_c = critical_angle_at(material, speed)
        if theta_c >= HALF_PI:
            return wp.int32(0)
        if -wp.dot(velocity, normal) > speed * wp.sin(theta_c):
            return wp.int32(1)
        return wp.int32(0)

    @wp.func
    def sinks(material: Material):
        """1 when a pellet cannot stay on or move along the surface (water): one that would is embedded."""
        return material.liquid

    @wp.func
    def skip(material: Material, velocity: vec3, normal: vec3, spin: vec3):
        """(velocity', spin') of a skip off water: mirrored, speed times exp(-2 theta skip_loss), spin kept."""
        speed = wp.length(velocity)
        normal_speed = wp.dot(velocity, normal)
        sine = ZERO
        if speed > ZERO:
            sine = wp.clamp(-normal_speed / speed, ZERO, ONE)
        keep = wp.exp(-scalar(2.0) * wp.asin(sine) * material.skip_loss)
        return keep * (velocity - scalar(2.0) * normal_speed * normal), spin

    return SimpleNamespace(draw=draw, embeds=embeds, sinks=sinks, skip=skip, critical_angle_at=critical_angle_at)
