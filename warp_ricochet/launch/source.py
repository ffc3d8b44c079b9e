"""Launch states in the kernels: the `Source` struct, the `launch_state` function every kernel that
launches pellets calls (so the core kernel and the dense phase launch exactly the same pellets),
and `PelletSource`, which fills the struct on the host and copies a pellet file's states to the
device chunk by chunk.
"""

import functools
from types import SimpleNamespace

import numpy as np
import warp as wp

from ..physics.types import types_for
from ..scene.vectors import scale_exponent, scaled, unit_vector
from ..struct_refs import read_only
from .sampling import make_sampler
from .stations import launch_shot_aims, station_table

ARRAYS = ("position", "velocity", "angular_velocity")


@functools.cache
def make_source(precision: str, from_file: bool, pattern: bool = False, stations: bool = False) -> SimpleNamespace:
    """The `Source` struct and `launch_state` of one precision; `from_file`: states read from the
    struct's arrays (chunk-local rows), else sampled from the seed and the global index (`pattern`:
    directions from the shot's pattern; `stations`: each shot's envelope centre and aim from its
    station, `launch.stations`)."""
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    sample_pellet = make_sampler(precision, pattern)
    FROM_FILE, STATIONS = from_file, stations

    @wp.struct
    class Source:
        """Launch states: sampled from the seed, or (from_file) read from the arrays."""

        seed: wp.int32
        speed: scalar  # m/s
        direction: vec3
        jitter: vec3
        envelope_center: vec3  # m
        envelope_radius: scalar  # m
        spin: vec3  # rad/s
        spread: scalar  # the pattern's (scene.patterns), 0 without one
        position: wp.array(dtype=vec3)  # chunk-local explicit states (empty when sampling)
        velocity: wp.array(dtype=vec3)
        angular_velocity: wp.array(dtype=vec3)
        count: wp.int32  # pellets per shot
        shot_first: wp.int32  # with stations: the first shot of the chunk (`PelletSource.load`)
        shot_center: wp.array(dtype=vec3)  # m: its shots' stations' positions, from shot_first on
        shot_aim: wp.array(dtype=vec3)  # their unit aims (launch.stations; empty without stations)

    @wp.func
    def launch_state(source: Source, index: wp.int32, row: wp.int32):
        """Position (m), velocity (m/s), angular velocity (rad/s) of global pellet `index` at `row`."""
        position = vec3()
        velocity = vec3()
        spin = vec3()
        if wp.static(FROM_FILE):
            position = source.position[row]
            velocity = source.velocity[row]
            spin = source.angular_velocity[row]
        else:
            if wp.static(STATIONS):
                shot = index // source.count - source.shot_first
                center, aim = source.shot_center[shot], source.shot_aim[shot]
                position, velocity, spin = sample_pellet(
                    source.seed,
                    index,
                    source.speed,
                    aim,
                    source.jitter,
                    center,
                    source.envelope_radius,
                    source.spin,
                    source.spread,
                )
            else:
                position, velocity, spin = sample_pellet(
                    source.seed,
                    index,
                    source.speed,
                    source.direction,
                    source.jitter,
                    source.envelope_center,
                    source.envelope_radius,
                    source.spin,
                    source.spread,
                )
        return position, velocity, spin

    read_only(Source)
    return SimpleNamespace(Source=Source, launch_state=launch_state)


class PelletSource:
    """A scene's launch states on a device: the `Source` struct of its shot (sampling parameters)
    and, for a pellet file, device arrays of `capacity` rows that `load` fills chunk by chunk."""

    def __init__(self, scene, precision: str, device, capacity: int, arrays=None):
        self.arrays = arrays  # host float64 (N, 3) arrays of a pellet file, else None
        self.precision = precision
        shot = scene.shot
        t = types_for(precision)
        struct = make_source(precision, self.from_file, shot.pattern is not None, bool(scene.stations)).Source()
        struct.seed = shot.seed
        struct.speed = t.scalar(shot.speed)
        # scaled together by a power of two (exact): the kernel forms |d|^2 of d = direction + jitter u
        # without underflow, and ordinary directions are left as they are (scene.vectors)
        k = scale_exponent(shot.direction, shot.direction_jitter)
        struct.direction = t.vec3(*scaled(shot.direction, k))
        if shot.pattern is not None:  # the pattern's draw turns a unit aim (launch.pattern)
            struct.direction = t.vec3(*unit_vector(shot.direction))
        struct.jitter = t.vec3(*scaled(shot.direction_jitter, k))
        struct.envelope_center = t.vec3(*shot.envelope_center)
        struct.envelope_radius = t.scalar(shot.envelope_radius)
        struct.spin = t.vec3(*shot.spin)
        struct.spread = t.scalar(shot.pattern_spread or 0.0)
        struct.count = shot.count
        if scene.stations:  # a unit aim: the jitter as given (docs/scenes.md)
            struct.jitter = t.vec3(*shot.direction_jitter)
        self.stations = station_table(scene, precision, device) if scene.stations else None
        shots = capacity // max(shot.count, 1) + 2 if scene.stations else 0  # a chunk's shots, at most
        struct.shot_center = wp.empty(shots, dtype=t.vec3, device=device)
        struct.shot_aim = wp.empty(shots, dtype=t.vec3, device=device)
        self.device = device
        rows = capacity if self.from_file else 0
        for name in ARRAYS:
            setattr(struct, name, wp.empty(rows, dtype=t.vec3, device=device))
        self.struct = struct

    @property
    def from_file(self) -> bool:
        return self.arrays is not None

    def load(self, start: int, rows: int) -> None:
        """Ready the launch of pellets [start, start + rows): with stations, the aims of their shots
        (`launch.stations.shot_aims`, once a shot instead of once a pellet); from a pellet file, copy
        its rows to the device; else nothing."""
        if self.stations is not None and rows > 0:
            count = self.struct.count
            first, last = start // count, (start + rows - 1) // count
            self.struct.shot_first = first
            launch_shot_aims(self.stations, self.struct, first, last - first + 1, self.precision, self.device)
        if not self.from_file:
            return
        dtype = np.dtype(self.precision)
        for name in ARRAYS:
            getattr(self.struct, name)[:rows].assign(np.ascontiguousarray(self.arrays[name][start : start + rows], dtype=dtype))
