"""`core.lanes.any_lane`: on CUDA the warp's vote, on the CPU the thread's own flag; and the turf run
to rest, which waits on it, gives the same statistics on every device as the CPU's run."""

import numpy as np
import warp as wp

from warp_ricochet.core.lanes import any_lane


@wp.kernel
def _vote(flags: wp.array(dtype=wp.int32), out: wp.array(dtype=wp.int32)):
    i = wp.tid()
    out[i] = any_lane(flags[i])


def test_any_lane_is_the_warp_vote_on_cuda_and_the_own_flag_on_the_cpu(device):
    flags = np.zeros(96, dtype=np.int32)
    flags[37] = 1  # in the second warp only
    flags[70] = 5
    out = wp.zeros(96, dtype=wp.int32, device=device)
    wp.launch(_vote, dim=96, inputs=[wp.array(flags, device=device)], outputs=[out], device=device)
    got = out.numpy()
    if wp.get_device(device).is_cuda:
        expected = np.repeat([0, 1, 1], 32)
    else:
        expected = (flags != 0).astype(np.int32)
    np.testing.assert_array_equal(got, expected)


def test_a_loop_that_waits_on_the_vote_computes_what_the_thread_alone_does(device):
    """Each thread counts down its own number, a thread at an odd count waiting while any other of
    its warp is at an even one: the result is each thread's own count whatever the waits."""
    n = 64
    start = np.random.default_rng(3).integers(0, 40, size=n).astype(np.int32)
    out = wp.zeros(n, dtype=wp.int32, device=device)
    wp.launch(_countdown, dim=n, inputs=[wp.array(start, device=device)], outputs=[out], device=device)
    np.testing.assert_array_equal(out.numpy(), start * 3)


@wp.kernel
def _countdown(start: wp.array(dtype=wp.int32), out: wp.array(dtype=wp.int32)):
    i = wp.tid()
    left = start[i]
    total = wp.int32(0)
    while left > 0:
        even = any_lane(wp.int32(left % 2 == 0))
        if left % 2 == 1 and even != 0:
            continue
        total += 3
        left -= 1
    out[i] = total
