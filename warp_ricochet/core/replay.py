"""The replay kernel: a chunk's pellets' recorded watch given to the hazard's tallies after the core
kernel (`tallies.path_replay`; `spec.RunSpec.replay`), one thread a pellet, and `launch_replay`, its
launch after the core's."""

import functools

import warp as wp

from ..tallies.landing import make_landing_tally
from ..tallies.path_keep import make_path_keep
from ..tallies.path_replay import make_path_replay
from ..tallies.path_chord import make_path_watch
from .kernel import kernel_options
from .outputs import make_outputs
from .release import make_release


@functools.cache
def replay_kernel_for(spec):
    """The replay kernel of `spec`: each chunk row's track begun as the core begins it (at its launch,
    or where the dense phase left it), its records replayed, then counted (`finish`) and written
    (`write`, with the hazard's per-pellet fields) as the core does; rows the core watched itself
    (count -1: `tallies.path_replay.spill`) left alone."""
    watcher = make_path_watch(spec.precision, *spec.watch[:4])
    rp = make_path_replay(spec.precision, *spec.watch[:4])
    load_track = make_path_keep(spec.precision, *spec.watch[:3])[0]
    Tally = make_landing_tally(spec.precision).Tally
    Outputs, Release = make_outputs(spec.precision).Outputs, make_release(spec.precision)
    RELEASE, WRITE = spec.collisions, any(f.startswith("hazard.") for f in spec.core_fields)
    options = kernel_options(spec)
    options.pop("cuda_max_registers", None)

    @wp.kernel(module="unique", enable_backward=False, **options)
    def replay_kernel(rows: wp.int32, out: Outputs, release: Release, tally: Tally):
        row = wp.tid()
        if row < rows:
            count = wp.int32(rp.get(tally, row, 0))
            if count >= 0:
                track = watcher.start()
                if wp.static(RELEASE):
                    track = load_track(release.watch_reach, release.watch_ints, row)
                track = watcher.seat(track, tally, row)
                track, _pending = rp.replay(track, tally, row, count)
                watcher.finish(track, tally, row)
                if wp.static(WRITE):
                    watcher.write(track, out.hazard_reach, row)

    return replay_kernel


def launch_replay(spec, rows: int, outputs, release, tally, device) -> None:
    """After the core kernel of a chunk of `rows` pellets (rows 0 .. rows - 1 of its outputs, its
    release and its tally's record log): the replay kernel, where the run replays its watch."""
    if spec.watch[4] and rows > 0:
        wp.launch(replay_kernel_for(spec), dim=rows, inputs=[rows, outputs, release, tally], device=device)
