"""A shot's station and aim in the kernels (docs/scenes.md, "Stations, arcs of fire and aim error").

Shot j = index // shot.count belongs to the station of the piece (a contiguous range of shots) that
holds it (`bound.station_pieces`: one piece a station, or a bounded run's cut at its checks). Its aim comes from the counter-based
stream of `launch.sampling` in a key space of its own: key = mix64(seed * 2^32 + 2^31 + j). A
pellet's key is mix64(seed * 2^32 + i) with i < 2^31, so no shot shares a key with a pellet (mix64
is a bijection), and the aim depends on (seed, j) alone: the same for every pellet of the shot, any
chunk size, resume, CPU and GPU. Output k = 1 of the stream, mix64(key + golden), gives two
24-bit uniforms u_a (azimuth) and u_e (elevation).

- aim "uniform": a = a_min + u_a (a_max - a_min), e likewise (uniform over the angular ranges);
- aim "normal": about the range's centre c with sigma s, each coordinate truncated to its range when
  the range is wider than a point: x = c + s Phi^-1(Phi(lo') + u (Phi(hi') - Phi(lo'))), lo' = (lo - c) / s,
  u = (bits + 1/2) 2^-24 (so Phi^-1 stays finite): the inverse-CDF draw of the truncated normal
  (no rejection loop);
- direction d = cos(e) (cos(a) f + sin(a) r) + sin(e) up in the frame of `scene.stations.frame`.

The aim is computed in float64 in every precision (the same aims for float32 and float64 runs),
then cast to the working precision. `scene.stations.reference_aims` is its NumPy reference.
"""

import functools
import math

import numpy as np
import warp as wp

from ..bound import station_pieces
from ..physics.types import types_for
from ..scene.stations import SHOT_KEY_BIT, azimuth_offset, frame
from .sampling import GOLDEN, UNIT24, mix64

SQRT2 = 1.4142135623730951


@wp.func
def _phi(x: wp.float64):
    """The standard normal CDF."""
    return wp.float64(0.5) * (wp.float64(1.0) + wp.erf(x / wp.float64(SQRT2)))


@wp.func
def _coordinate(lo: wp.float64, hi: wp.float64, sigma: wp.float64, bits: wp.uint32):
    """One aim coordinate (rad) from 24 bits: uniform over [lo, hi] (sigma 0) or normal about its
    centre, truncated to it when hi > lo."""
    if sigma == wp.float64(0.0):
        return lo + wp.float64(bits) * wp.float64(UNIT24) * (hi - lo)
    mid = wp.float64(0.5) * (lo + hi)
    u = (wp.float64(bits) + wp.float64(0.5)) * wp.float64(UNIT24)
    if hi > lo:
        pa = _phi((lo - mid) / sigma)
        u = pa + u * (_phi((hi - mid) / sigma) - pa)
    return mid + sigma * wp.float64(SQRT2) * wp.erfinv(wp.float64(2.0) * u - wp.float64(1.0))


@functools.cache
def make_station_aim(precision: str):
    """The `@wp.func` station_aim(seed, shot, first, owner, position, azimuth, elevation, sigma,
    frame) -> (station index, position (m), unit aim), in `precision`."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3

    @wp.func
    def station_aim(
        seed: wp.int32,
        shot: wp.int32,
        first: wp.array(dtype=wp.int32),  # first shot of each piece, increasing
        owner: wp.array(dtype=wp.int32),  # each piece's station
        position: wp.array(dtype=vec3),  # m
        azimuth: wp.array(dtype=wp.vec2d),  # rad (min, max), from the downrange axis
        elevation: wp.array(dtype=wp.vec2d),  # rad (min, max)
        sigma: wp.array(dtype=wp.float64),  # rad; 0: uniform
        axes: wp.mat33d,  # rows f, r, up
    ):
        piece = wp.int32(0)
        for p in range(1, first.shape[0]):
            if shot >= first[p]:
                piece = p
        k = owner[piece]
        key = mix64((wp.uint64(seed) << wp.uint64(32)) | (wp.uint64(SHOT_KEY_BIT) + wp.uint64(shot)))
        z = mix64(key + GOLDEN)
        a = _coordinate(azimuth[k][0], azimuth[k][1], sigma[k], wp.uint32(z) >> wp.uint32(8))
        e = _coordinate(elevation[k][0], elevation[k][1], sigma[k], wp.uint32(z >> wp.uint64(32)) >> wp.uint32(8))
        ce = wp.cos(e)
        d = ce * wp.cos(a) * axes[0] + ce * wp.sin(a) * axes[1] + wp.sin(e) * axes[2]
        return k, position[k], vec3(scalar(d[0]), scalar(d[1]), scalar(d[2]))

    return station_aim


@functools.cache
def make_shot_aims(precision: str):
    """The kernel that writes shots [first_shot, first_shot + n)'s station positions and unit aims
    (`station_aim`), one thread a shot."""
    t = types_for(precision)
    vec3, station_aim = t.vec3, make_station_aim(precision)

    @wp.kernel
    def shot_aims(
        seed: wp.int32,
        first_shot: wp.int32,
        first_in: wp.array(dtype=wp.int32),
        owner_in: wp.array(dtype=wp.int32),
        position_in: wp.array(dtype=vec3),
        azimuth_in: wp.array(dtype=wp.vec2d),
        elevation_in: wp.array(dtype=wp.vec2d),
        sigma_in: wp.array(dtype=wp.float64),
        axes: wp.mat33d,
        center_out: wp.array(dtype=vec3),
        aim_out: wp.array(dtype=vec3),
    ):
        j = wp.tid()
        _k, center, aim = station_aim(
            seed, first_shot + j, first_in, owner_in, position_in, azimuth_in, elevation_in, sigma_in, axes
        )
        center_out[j] = center
        aim_out[j] = aim

    return shot_aims


def launch_shot_aims(table: dict, source, first: int, shots: int, precision: str, device) -> None:
    """Fill `source.shot_center` and `source.shot_aim` with the `shots` shots from `first` on (no
    host sync: queued before the chunk's kernels on the device's stream)."""
    inputs = [
        table[k]
        for k in ("station_first", "station_owner", "station_position", "station_azimuth", "station_elevation", "station_sigma")
    ]
    wp.launch(
        make_shot_aims(precision),
        dim=shots,
        inputs=[source.seed, first, *inputs, table["station_axes"]],
        outputs=[source.shot_center, source.shot_aim],
        device=device,
    )


def station_table(scene, precision: str, device) -> dict:
    """The device arrays and frame `station_aim` reads (empty arrays for a scene without stations)."""
    t = types_for(precision)
    stations = scene.stations
    offset = azimuth_offset(scene.hazard) if stations else 0.0
    axes = np.stack(frame(scene.shot, scene.physics, scene.hazard)) if stations else np.eye(3)
    pieces = station_pieces(scene) if stations else []
    radians = [[math.radians(x - offset) for x in s.azimuth] for s in stations]
    return dict(
        station_first=wp.array([a for a, _b, _k in pieces], dtype=wp.int32, device=device),
        station_owner=wp.array([k for _a, _b, k in pieces], dtype=wp.int32, device=device),
        station_position=wp.array([s.position for s in stations], dtype=t.vec3, device=device),
        station_azimuth=wp.array(np.reshape(radians, (-1, 2)), dtype=wp.vec2d, device=device),
        station_elevation=wp.array(
            np.reshape([[math.radians(x) for x in s.elevation] for s in stations], (-1, 2)), dtype=wp.vec2d, device=device
        ),
        station_sigma=wp.array([math.radians(s.aim_sigma or 0.0) for s in stations], dtype=wp.float64, device=device),
        station_axes=wp.mat33d(*np.asarray(axes, dtype=np.float64).ravel()),
    )
