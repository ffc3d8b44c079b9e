"""The replay kernel: a chunk's pellets' recorded watch given to the hazard's tallies after the core
kernel (`tallies.path_replay`; `spec.RunSpec.replay`), one thread a pellet; and `Replay`, its launch
after the core's, then the core kernel again, following only the pellets whose records did not fit,
with the watch in it and nothing else counted (`spec.RunSpec.watch_only`)."""

import dataclasses
import functools

import warp as wp

from ..tallies.landing import make_landing_tally
from ..tallies.path_chord import make_path_watch
from ..tallies.path_keep import make_path_keep
from ..tallies.path_replay import OVERFLOWED, make_path_replay
from .kernel import kernel_options, ricochet_kernel_for
from .outputs import make_outputs
from .release import make_release

# The replay kernel's occupancy on CUDA: 168 registers a thread in blocks of 128 threads give 12 warps an
# SM (255 registers in blocks of 256: 8). bench/RESULTS.md, "The replay kernel's occupancy".
REPLAY_MAX_REGISTERS, REPLAY_BLOCK_DIM = 168, 128


@functools.cache
def replay_kernel_for(spec):
    """The replay kernel of `spec`: each chunk row's track begun as the core begins it (at its
    launch, or where the dense phase left it), its records replayed in order (a pass enters a map
    cell once across records), then counted (`finish`) and written (`write`, with the hazard's
    per-pellet fields) as the core does; rows whose records did not fit (OVERFLOWED) counted into
    `overflowed` and left to the rerun."""
    watcher = make_path_watch(spec.precision, *spec.watch[:4])
    rp = make_path_replay(spec.precision, *spec.watch[:4])
    load_track = make_path_keep(spec.precision, *spec.watch[:3])[0]
    Tally, Track = make_landing_tally(spec.precision).Tally, watcher.Track
    Outputs, Release = make_outputs(spec.precision).Outputs, make_release(spec.precision)
    RELEASE, WRITE = spec.collisions, any(f.startswith("hazard.") for f in spec.core_fields)
    options = kernel_options(spec, in_place=not spec.hazard_map)  # (bench/RESULTS.md "Kernel parameters read in place")
    options["cuda_max_registers"] = REPLAY_MAX_REGISTERS

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

    return replay_kernel


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

    @property
    def reruns(self) -> int:
        """Pellets followed again in the run so far (a read of the device)."""
        return int(self.overflowed.numpy()[0]) if self.on else 0

    def after_core(self, rows: int, outputs, release, tally, rerun) -> None:
        """After the core kernel of a chunk of `rows` pellets: the replay kernel, then `rerun(kernel)`,
        which launches the rerun kernel as the core was launched (its statistics partials thrown
        away): it follows the rows whose records did not fit (OVERFLOWED) and passes over the rest.
        No read of the device: the host never waits for the replay."""
        if not self.on or rows <= 0:
            return
        wp.launch(
            replay_kernel_for(self.spec),
            dim=rows,
            inputs=[rows, outputs, release, tally, self.overflowed],
            device=self.device,
            block_dim=REPLAY_BLOCK_DIM,
        )
        rerun(ricochet_kernel_for(rerun_spec(self.spec)))
