"""Initial pellets sampled inside the kernel from a counter-based RNG (Zohdi 2021, section 3.1).

Pellet i draws from its own stream `wp.rand_init(seed, i)`, so its initial state depends only on
(seed, i): the same on CPU and GPU and for any chunk size. Draws are float32 and cast to the
working precision, so float32 and float64 runs start from the same pellets.

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
        z = 2.0 * wp.randf(state) - 1.0
        azimuth = 6.283185307179586 * wp.randf(state)
        r = wp.cbrt(wp.randf(state))
        ring = r * wp.sqrt(wp.max(1.0 - z * z, 0.0))
        offset = vec3(scalar(ring * wp.cos(azimuth)), scalar(ring * wp.sin(azimuth)), scalar(r * z))
        jx = scalar(2.0 * wp.randf(state) - 1.0)
        jy = scalar(2.0 * wp.randf(state) - 1.0)
        jz = scalar(2.0 * wp.randf(state) - 1.0)
        d = direction + wp.cw_mul(jitter, vec3(jx, jy, jz))
        position = envelope_center + envelope_radius * offset
        velocity = speed * wp.normalize(d)
        return position, velocity, spin

    return sample_pellet
