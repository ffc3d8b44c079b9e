"""Initial pellets sampled inside the kernel from a counter-based RNG (Zohdi 2021, section 3.1).

Pellet i draws from its own stream `wp.rand_init(seed, i)`, so its initial state depends only on
(seed, i): the same on CPU and GPU and for any chunk size. Draws are float32, cast to the working
precision before any arithmetic: float32 and float64 runs start from the same draws, and the
transforms (cbrt, sin, cos) run in the working precision, so a float64 run agrees between CPU and
GPU to float64 rounding.

- position: uniform in the sphere of radius `envelope_radius` around `envelope_center`, in
  closed form (radius u^(1/3), direction uniform on the sphere): no rejection loop, whose
  iterations a GPU warp would have to wait out for its slowest lane;
- direction: d = direction + jitter * u, u uniform in [-1, 1]^3, then n = d / |d|
  (the paper's d = (1 +- 0.1, -1 +- 0.1, 0 +- 0.1));
- velocity = speed * n; angular velocity = spin.
"""


import functools

import warp as wp


@functools.cache
def make_sampler(scalar):
    """Return the `@wp.func` that samples one pellet for a Warp scalar type."""
    vec3 = wp.types.vector(3, scalar)

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
    ):
        """Return (position, velocity, angular_velocity) of pellet `index`."""
        state = wp.rand_init(seed, index)
        # uniform in the unit ball: z uniform in [-1, 1], azimuth uniform, radius u^(1/3)
        one = scalar(1.0)
        two = scalar(2.0)
        z = two * scalar(wp.randf(state)) - one
        azimuth = scalar(6.283185307179586) * scalar(wp.randf(state))
        r = wp.cbrt(scalar(wp.randf(state)))
        ring = r * wp.sqrt(wp.max(one - z * z, scalar(0.0)))
        offset = vec3(ring * wp.cos(azimuth), ring * wp.sin(azimuth), r * z)
        jx = two * scalar(wp.randf(state)) - one
        jy = two * scalar(wp.randf(state)) - one
        jz = two * scalar(wp.randf(state)) - one
        d = direction + wp.cw_mul(jitter, vec3(jx, jy, jz))
        position = envelope_center + envelope_radius * offset
        length = wp.length(d)
        velocity = vec3(scalar(0.0), scalar(0.0), scalar(0.0))
        if length > scalar(0.0):
            velocity = d * (speed / length)
        return position, velocity, spin

    return sample_pellet
