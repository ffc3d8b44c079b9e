"""Initial pellets sampled inside the kernel from a counter-based RNG (Zohdi 2021, section 3.1).

Counter-based: pellet i of seed s draws from a SplitMix64 stream (Steele, Lea & Flood 2014)
keyed by the full 63 bits of (s, i): key = mix64(s * 2^32 + i), a bijection (distinct pellets,
distinct keys), and its three 64-bit outputs mix64(key + k * golden), k = 1, 2, 3, give six 24-bit
uniforms. Two streams share a state only if their keys differ by +-golden or +-2 golden: with
scrambled keys, about 2 n^2 / 2^64 such pairs are expected among n pellets (0.1 at n = 1e9).
(Unscrambled keys s * 2^32 + i would collide for some seed pairs: -2 golden = 0xC3910C8D 016B07D6.) So the launch
state depends only on (seed, i): the same on CPU and GPU and for any chunk size; and unlike a
32-bit generator state (`wp.rand_init`), streams of different pellets or seeds do not overlap,
even for billions of pellets. The uniforms are cast to the working precision before any
arithmetic: float32 and float64 runs start from the same draws, and the transforms (cbrt, sin,
cos) run in the working precision, so a float64 run agrees between CPU and GPU to float64 rounding.

- position: uniform in the sphere of radius `envelope_radius` around `envelope_center`, in
  closed form (radius u^(1/3), direction uniform on the sphere): no rejection loop, whose
  iterations a GPU warp would have to wait out for its slowest lane;
- direction: d = direction + jitter * u, u uniform in [-1, 1]^3, then n = d / |d|
  (the paper's d = (1 +- 0.1, -1 +- 0.1, 0 +- 0.1)); `launch.source` scales direction and jitter
  together by a power of two on the host (`scene.vectors`), so |d|^2 does not underflow; or, in a
  scene with a choke's pattern (compiled in only then), d = `launch.pattern`'s draw from u4, u5;
- velocity = speed * n; angular velocity = spin.

With pellet-pellet collisions a shot is sampled without overlaps (`dense.separation`): a
pellet whose centre lies closer than a diameter to an earlier pellet of its shot takes a new
position, attempt r = 1, 2, ... drawn by `redraw_position` from outputs k = 2r + 2, 2r + 3 of its
own stream (k = 1, 2, 3 are its launch state), at most `launch.packing.MAX_REDRAWS` times; its velocity and spin
stay. The envelope's packing fraction (pellet volume over envelope volume) may be at most
`launch.packing.MAX_PACKING` (scene check).
"""

import functools

import warp as wp

from ..physics.types import types_for
from .pattern import make_pattern_direction

GOLDEN = wp.constant(wp.uint64(0x9E3779B97F4A7C15))  # 2^64 / golden ratio: the SplitMix64 increment
MIX1 = wp.constant(wp.uint64(0xBF58476D1CE4E5B9))
MIX2 = wp.constant(wp.uint64(0x94D049BB133111EB))
UNIT24 = 1.0 / 16777216.0  # 2^-24


@wp.func
def mix64(z: wp.uint64):
    """The SplitMix64 output function (a bijection of 64-bit words)."""
    z = (z ^ (z >> wp.uint64(30))) * MIX1
    z = (z ^ (z >> wp.uint64(27))) * MIX2
    return z ^ (z >> wp.uint64(31))


def reference_uniforms(seed: int, index: int):
    """The six uniforms of pellet `index` of `seed`, in pure Python (what the kernels draw)."""
    mask = (1 << 64) - 1

    def mix(z):
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
        return z ^ (z >> 31)

    key = mix((seed << 32) | index)
    out = []
    for k in (1, 2, 3):
        z = mix((key + k * 0x9E3779B97F4A7C15) & mask)
        out += [((z & 0xFFFFFFFF) >> 8) * UNIT24, ((z >> 32) >> 8) * UNIT24]
    return out


@functools.cache
def make_sampler(precision: str, pattern: bool = False):
    """Return the `@wp.func` that samples one pellet, of one precision ("float32" or "float64");
    `pattern`: directions from the shot pattern of spread `spread` (else from the jitter)."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    PATTERN, pattern_direction = pattern, make_pattern_direction(precision)

    @wp.func
    def sample_pellet(
        seed: wp.int32,
        index: wp.int32,
        speed: scalar,  # m/s
        direction: vec3,
        jitter: vec3,
        envelope_center: vec3,  # m
        envelope_radius: scalar,  # m
        spin: vec3,  # rad/s
        spread: scalar,  # the pattern's (tan theta per axis), read only with PATTERN
    ):
        """Return (position, velocity, angular_velocity) of pellet `index`."""
        key = mix64((wp.uint64(seed) << wp.uint64(32)) | wp.uint64(index))
        a = mix64(key + GOLDEN)
        b = mix64(key + wp.uint64(2) * GOLDEN)
        c = mix64(key + wp.uint64(3) * GOLDEN)
        unit = scalar(UNIT24)
        u1 = scalar(wp.uint32(a) >> wp.uint32(8)) * unit  # 24-bit uniforms in [0, 1)
        u2 = scalar(wp.uint32(a >> wp.uint64(32)) >> wp.uint32(8)) * unit
        u3 = scalar(wp.uint32(b) >> wp.uint32(8)) * unit
        u4 = scalar(wp.uint32(b >> wp.uint64(32)) >> wp.uint32(8)) * unit
        u5 = scalar(wp.uint32(c) >> wp.uint32(8)) * unit
        u6 = scalar(wp.uint32(c >> wp.uint64(32)) >> wp.uint32(8)) * unit
        # uniform in the unit ball: z uniform in [-1, 1], azimuth uniform, radius u^(1/3)
        one = scalar(1.0)
        two = scalar(2.0)
        z = two * u1 - one
        azimuth = scalar(6.283185307179586) * u2
        r = wp.cbrt(u3)
        ring = r * wp.sqrt(wp.max(one - z * z, scalar(0.0)))
        offset = vec3(ring * wp.cos(azimuth), ring * wp.sin(azimuth), r * z)
        d = vec3()
        if wp.static(PATTERN):
            d = pattern_direction(direction, spread, u4, u5)
        else:
            jx = two * u4 - one
            jy = two * u5 - one
            jz = two * u6 - one
            d = direction + wp.cw_mul(jitter, vec3(jx, jy, jz))
        position = envelope_center + envelope_radius * offset
        length = wp.length(d)
        velocity = vec3(scalar(0.0), scalar(0.0), scalar(0.0))
        if length > scalar(0.0):
            velocity = d * (speed / length)
        return position, velocity, spin

    return sample_pellet


@functools.cache
def make_redraw(precision: str):
    """Return the `@wp.func` that draws attempt r >= 1 of a new position of pellet `index` (one precision)."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3

    @wp.func
    def redraw_position(seed: wp.int32, index: wp.int32, attempt: wp.int32, envelope_center: vec3, envelope_radius: scalar):
        """Uniform in the envelope sphere, as `sample_pellet`'s position, from stream outputs
        k = 2 attempt + 2 and 2 attempt + 3 of pellet `index` of `seed` (m)."""
        key = mix64((wp.uint64(seed) << wp.uint64(32)) | wp.uint64(index))
        k = wp.uint64(2 * attempt + 2)
        a = mix64(key + k * GOLDEN)
        b = mix64(key + (k + wp.uint64(1)) * GOLDEN)
        unit = scalar(UNIT24)
        u1 = scalar(wp.uint32(a) >> wp.uint32(8)) * unit
        u2 = scalar(wp.uint32(a >> wp.uint64(32)) >> wp.uint32(8)) * unit
        u3 = scalar(wp.uint32(b) >> wp.uint32(8)) * unit
        one = scalar(1.0)
        z = scalar(2.0) * u1 - one
        azimuth = scalar(6.283185307179586) * u2
        r = wp.cbrt(u3)
        ring = r * wp.sqrt(wp.max(one - z * z, scalar(0.0)))
        return envelope_center + envelope_radius * vec3(ring * wp.cos(azimuth), ring * wp.sin(azimuth), r * z)

    return redraw_position
