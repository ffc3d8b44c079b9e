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


def _own_nodes(func):
    """The nodes of a function's body, not those of the functions defined in it."""
    import ast

    stack = [n for n in func.body if not isinstance(n, ast.FunctionDef)]
    while stack:
        node = stack.pop()
        yield node
        stack.extend(c for c in ast.iter_child_nodes(node) if not isinstance(c, ast.FunctionDef))


def _lane_masks(tree):
    """(function, mask name, its line, the lines of the calls given it first (`meet`, `any_in` or a
    vote built on them), the lines of its returns) for every `X = lanes_here()` in a module."""
    import ast

    for func in ast.walk(tree):
        if not isinstance(func, ast.FunctionDef):
            continue
        nodes = list(_own_nodes(func))
        returns = [n.lineno for n in nodes if isinstance(n, ast.Return)]
        calls = [n for n in nodes if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.args]
        for node in nodes:
            if isinstance(node, ast.Assign) and getattr(getattr(node.value, "func", None), "id", "") == "lanes_here":
                name = node.targets[0].id
                uses = [c.lineno for c in calls if c.func.id != "lanes_here" and getattr(c.args[0], "id", "") == name]
                yield func.name, name, node.lineno, uses, returns


def test_every_lane_mask_is_met_before_any_return():
    """A lane that leaves between `lanes_here` and the `meet`/`any_in` of its mask would leave the
    others of the mask waiting for it on a GPU (CI has none): in the package's code every mask is
    used, and no `return` of its function lies between the mask and its last use."""
    import ast
    from pathlib import Path

    import warp_ricochet

    found = 0
    for path in Path(warp_ricochet.__file__).parent.rglob("*.py"):
        if path.name == "lanes.py":
            continue
        for func, name, line, uses, returns in _lane_masks(ast.parse(path.read_text())):
            found += 1
            where = f"{path.name}:{line} {func}"
            assert uses, f"{where}: mask {name} never met"
            assert not [r for r in returns if line < r < max(uses)], f"{where}: a return before {name} is met"
    assert found >= 5  # segment, line, the surface phase's, the flight's, the line integrator's
