"""The replay kernel: a chunk's pellets' recorded watch given to the hazard's tallies after the core
kernel (`tallies.path_replay`; `spec.RunSpec.replay`), one thread a pellet; and `Replay`, its launch
after the core's, then the core kernel again over the pellets whose records did not fit, with the watch
in it and nothing else counted (`spec.RunSpec.watch_only`)."""

import dataclasses
import functools

import warp as wp

from ..physics.types import types_for
from ..tallies.landing import make_landing_tally
from ..tallies.path_chord import make_path_watch
from ..tallies.path_keep import kept_shapes, make_path_keep
from ..tallies.path_replay import OVERFLOWED, make_path_replay
from .kernel import kernel_options, ricochet_kernel_for
from .outputs import make_outputs
from .release import make_release


@functools.cache
def replay_kernels_for(spec):
    """The replay kernels of `spec`: each chunk row's track begun as the core begins it (at its
    launch, or where the dense phase left it), its records replayed, then counted (`finish`) and
    written (`write`, with the hazard's per-pellet fields) as the core does; rows whose records did
    not fit (OVERFLOWED) counted into `overflowed` and left to the rerun. With a map, one kernel
    replays each column in order (a pass enters a cell once across records); without one (the reach
    alone, a maximum; named places come with a map), a kernel replays the phases along a line and keeps the track
    (`make_path_keep`), then another the flights, so that a warp's lanes replay records of one kind."""
    watcher = make_path_watch(spec.precision, *spec.watch[:4])
    rp = make_path_replay(spec.precision, *spec.watch[:4])
    load_track, store_track = make_path_keep(spec.precision, *spec.watch[:3])
    Tally, scalar, Track = make_landing_tally(spec.precision).Tally, types_for(spec.precision).scalar, watcher.Track
    Outputs, Release = make_outputs(spec.precision).Outputs, make_release(spec.precision)
    RELEASE, WRITE, ORDERED = spec.collisions, any(f.startswith("hazard.") for f in spec.core_fields), spec.hazard_map
    options = kernel_options(spec)
    options.pop("cuda_max_registers", None)

    @wp.func
    def begin(release: Release, tally: Tally, row: wp.int32):
        track = watcher.start()
        if wp.static(RELEASE):
            track = load_track(release.watch_reach, release.watch_ints, row)
        return watcher.seat(track, tally, row)

    @wp.func
    def end(track: Track, out: Outputs, tally: Tally, row: wp.int32):
        watcher.finish(track, tally, row)
        if wp.static(WRITE):
            watcher.write(track, out.hazard_reach, row)

    @wp.kernel(module="unique", enable_backward=False, **options)
    def replay_kernel(rows: wp.int32, out: Outputs, release: Release, tally: Tally, overflowed: wp.array(dtype=wp.int32)):
        row = wp.tid()
        if row < rows:
            count = wp.int32(rp.get(tally, row, 0))
            if count == wp.int32(OVERFLOWED):
                wp.atomic_add(overflowed, 0, 1)
            elif count >= 0:
                end(rp.replay(begin(release, tally, row), tally, row, count), out, tally, row)

    @wp.kernel(module="unique", enable_backward=False, **options)
    def lines_kernel(rows: wp.int32, release: Release, tally: Tally, reach: wp.array2d(dtype=scalar), ints: wp.array2d(dtype=wp.int32), overflowed: wp.array(dtype=wp.int32)):  # fmt: skip
        row = wp.tid()
        if row < rows:
            count = wp.int32(rp.get(tally, row, 0))
            if count == wp.int32(OVERFLOWED):
                wp.atomic_add(overflowed, 0, 1)
            elif count >= 0:
                store_track(rp.replay_lines(begin(release, tally, row), tally, row, count), reach, ints, row)

    @wp.kernel(module="unique", enable_backward=False, **options)
    def flights_kernel(rows: wp.int32, out: Outputs, tally: Tally, reach: wp.array2d(dtype=scalar), ints: wp.array2d(dtype=wp.int32)):  # fmt: skip
        row = wp.tid()
        if row < rows:
            count = wp.int32(rp.get(tally, row, 0))
            if count >= 0:
                track = watcher.seat(load_track(reach, ints, row), tally, row)
                end(rp.replay_flights(track, tally, row, count), out, tally, row)

    return (replay_kernel,) if ORDERED else (lines_kernel, flights_kernel)


def rerun_spec(spec):
    """The spec of the core kernel that follows again the pellets whose records did not fit: the
    watch in the core, each step at once, nothing but the watch counted or written."""
    return dataclasses.replace(spec, replay=False, watch_only=True, log_steps=0)


class Replay:
    """A stage's replay of its chunks' recorded watch (`spec.watch[4]`; else nothing is done)."""

    def __init__(self, spec, device):
        self.spec, self.device = spec, device
        self.on = bool(spec.watch[4])
        self.overflowed = wp.zeros(1, dtype=wp.int32, device=device) if self.on else None
        self.reruns = 0  # pellets followed again in the run so far
        self._kept = None

    def kept(self, rows: int):
        """The tracks kept between the two replay kernels (`replay_kernels_for`): arrays of at least `rows` rows."""
        if self._kept is None or self._kept[0].shape[0] < rows:
            shapes = kept_shapes(rows, *self.spec.watch[:2])
            scalar = types_for(self.spec.precision).scalar
            self._kept = (
                wp.empty(shapes[0], dtype=scalar, device=self.device),
                wp.empty(shapes[1], dtype=wp.int32, device=self.device),
            )
        return self._kept

    def after_core(self, rows: int, outputs, release, tally, rerun) -> None:
        """After the core kernel of a chunk of `rows` pellets: the replay kernel; where some pellets'
        records did not fit, `rerun(kernel)` launches the rerun kernel as the core was launched (its
        statistics partials thrown away). One read of the device a chunk."""
        if not self.on or rows <= 0:
            return
        self.overflowed.zero_()
        kernels = replay_kernels_for(self.spec)
        if len(kernels) == 1:
            wp.launch(kernels[0], dim=rows, inputs=[rows, outputs, release, tally, self.overflowed], device=self.device)
        else:
            reach, ints = self.kept(rows)
            wp.launch(kernels[0], dim=rows, inputs=[rows, release, tally, reach, ints, self.overflowed], device=self.device)
            wp.launch(kernels[1], dim=rows, inputs=[rows, outputs, tally, reach, ints], device=self.device)
        count = int(self.overflowed.numpy()[0])
        if count:
            self.reruns += count
            rerun(ricochet_kernel_for(rerun_spec(self.spec)))
