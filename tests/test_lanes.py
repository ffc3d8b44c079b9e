"""`physics.lanes`: `any_lane` is, on CUDA, the warp's vote and, on the CPU, the thread's own flag;
loops that wait on a vote, that are warp-uniform (`lanes_here`, `any_in`), or whose lanes meet
(`meet`, `sync_lanes`) compute what each thread alone does."""

import numpy as np
import warp as wp

from warp_ricochet.physics.lanes import any_in, any_lane, lanes_here, meet, sync_lanes


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


@wp.kernel
def _uniform_countdown(start: wp.array(dtype=wp.int32), out: wp.array(dtype=wp.int32)):
    """`surface_line.integrate_line`'s loop shape: one pass of an inner loop a step, its break ending
    the lane's run, the outer loop going on while any lane of those that came in runs."""
    i = wp.tid()
    left = start[i]
    total = wp.int32(0)
    if i % 3 != 0:  # (only some lanes come in)
        here = lanes_here()
        running = wp.int32(1)
        while any_in(here, running) != 0:
            once = running
            while once != 0:
                once = wp.int32(0)
                if left <= 0:
                    running = wp.int32(0)
                    break
                if left % 2 == 1:
                    here_in = lanes_here()
                    total += _odd_work(left)
                    meet(here_in)
                    left -= 1
                    continue
                total += 3
                left -= 1
    out[i] = total


@wp.func
def _odd_work(left: wp.int32):
    extra = wp.int32(0)
    for k in range(left % 7):
        extra += k
    return 3 + extra


@wp.kernel
def _synced(count: wp.int32, out: wp.array(dtype=wp.int32)):
    i = wp.tid()
    total = wp.int32(0)
    for j in range(count):
        sync_lanes()
        if (i + j) % 5 == 0:
            for k in range(i % 9):
                total += k
        total += 1
    out[i] = total


def test_warp_uniform_loops_and_meetings_compute_what_the_thread_alone_does(device):
    n = 96
    start = np.random.default_rng(5).integers(0, 40, size=n).astype(np.int32)
    out = wp.zeros(n, dtype=wp.int32, device=device)
    wp.launch(_uniform_countdown, dim=n, inputs=[wp.array(start, device=device)], outputs=[out], device=device)
    expected = [
        0 if i % 3 == 0 else sum(3 + sum(range(k % 7)) if k % 2 == 1 else 3 for k in range(1, int(start[i]) + 1))
        for i in range(n)
    ]
    np.testing.assert_array_equal(out.numpy(), expected)
    out = wp.zeros(n, dtype=wp.int32, device=device)
    wp.launch(_synced, dim=n, inputs=[11], outputs=[out], device=device)
    expected = [sum(1 + (sum(range(i % 9)) if (i + j) % 5 == 0 else 0) for j in range(11)) for i in range(n)]
    np.testing.assert_array_equal(out.numpy(), expected)
