"""NumPy float64 reference of the kernels' launch states (`launch.sampling`, `launch.pattern`).

`uniforms` is SplitMix64 over NumPy uint64 arrays (wrapping arithmetic), vectorised over pellets:
the six uniforms pellet i of a seed draws. `launch_states` turns them into the kernels' position,
velocity and spin by the same formulas, so a float64 run's launch states agree with it to rounding;
`pattern_directions` is `launch.pattern`'s draw.
"""

from __future__ import annotations

import numpy as np

from ..scene.vectors import scale_exponent, scaled, unit_vector

_MIX1, _MIX2 = np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)
_GOLDEN = 0x9E3779B97F4A7C15
_UNIT24 = 1.0 / 16777216.0


def _mix64(z: np.ndarray) -> np.ndarray:
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return z ^ (z >> np.uint64(31))


def uniforms(seed: int, index) -> np.ndarray:
    """(n, 6) float64: the uniforms u1 ... u6 in [0, 1) of pellets `index` (ints) of `seed`."""
    index = np.asarray(index, dtype=np.uint64)
    with np.errstate(over="ignore"):
        key = _mix64((np.uint64(seed) << np.uint64(32)) | index)
        out = []
        for k in (1, 2, 3):
            z = _mix64(key + np.uint64((k * _GOLDEN) & ((1 << 64) - 1)))
            low, high = z & np.uint64(0xFFFFFFFF), z >> np.uint64(32)
            out += [(low >> np.uint64(8)).astype(np.float64) * _UNIT24, (high >> np.uint64(8)).astype(np.float64) * _UNIT24]
    return np.stack(out, axis=1)


def pattern_directions(aim, spread: float, u_a, u_b) -> np.ndarray:
    """(n, 3) unnormalised directions: the unit `aim` (3,) or (n, 3) turned by tan(theta) = spread
    sqrt(-2 ln(1 - u_a)) at azimuth 2 pi u_b in Duff et al.'s frame (as `launch.pattern`)."""
    a = np.asarray(aim, np.float64)
    x, y, z = a[..., 0], a[..., 1], a[..., 2]
    sign = np.where(z >= 0.0, 1.0, -1.0)
    k = -1.0 / (sign + z)
    b = x * y * k
    e1 = np.stack(np.broadcast_arrays(1.0 + sign * x * x * k, sign * b, -sign * x), axis=-1)
    e2 = np.stack(np.broadcast_arrays(b, sign + y * y * k, -y), axis=-1)
    rho = spread * np.sqrt(-2.0 * np.log(1.0 - np.asarray(u_a, np.float64)))
    phi = 2.0 * np.pi * np.asarray(u_b, np.float64)
    return a + (rho * np.cos(phi))[:, None] * e1 + (rho * np.sin(phi))[:, None] * e2


def launch_states(shot, index) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(position m, velocity m/s, spin rad/s), each (n, 3), of pellets `index` of a sampled `shot`,
    drawn as the kernels draw them."""
    u = uniforms(shot.seed, index)
    z, azimuth, r = 2.0 * u[:, 0] - 1.0, 2.0 * np.pi * u[:, 1], np.cbrt(u[:, 2])
    ring = r * np.sqrt(np.maximum(1.0 - z * z, 0.0))
    offset = np.stack([ring * np.cos(azimuth), ring * np.sin(azimuth), r * z], axis=1)
    k = scale_exponent(shot.direction, shot.direction_jitter)  # as `launch.source`
    direction = np.asarray(scaled(shot.direction, k))
    if shot.pattern is not None:  # the aim normalised on the host, as `launch.source`
        d = pattern_directions(unit_vector(shot.direction), shot.pattern_spread, u[:, 3], u[:, 4])
    else:
        d = direction + np.asarray(scaled(shot.direction_jitter, k)) * (2.0 * u[:, 3:6] - 1.0)
    velocity = d * (shot.speed / np.linalg.norm(d, axis=1))[:, None]
    position = np.asarray(shot.envelope_center) + shot.envelope_radius * offset
    spin = np.broadcast_to(np.asarray(shot.spin, np.float64), velocity.shape).copy()
    return position, velocity, spin
