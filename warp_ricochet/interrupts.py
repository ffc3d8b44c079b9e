"""Ctrl-C and SIGTERM as a request that the run honours at safe points, never as an exception raised
from a signal handler.

A KeyboardInterrupt raised by a signal handler lands wherever the main thread happens to be: inside
a weakref callback or a destructor Python prints "Exception ignored ..." and goes on, and inside a
native call (a Warp launch on the CPU) the handler does not run at all until the call returns. So
while a run is `honoured`, the handler only records the signal (and raises the stop flags of the
launches running, see `wait`); the run calls `check()` at safe points (between chunks, between the
dense phase's blocks and launches) and it raises KeyboardInterrupt there, so the output file is
closed as "interrupted" with its completed chunks. A long CPU launch runs in a worker thread
(`wait`) while the main thread waits in short timed waits, so the handler runs within them.

Only the main thread can install handlers and run them; elsewhere `honoured` changes nothing.
"""

from __future__ import annotations

import contextlib
import functools
import signal
import threading

WAIT_SLICE = 0.05  # s: the main thread's timed waits on a launch running in a worker thread

_requested: list[int] = []  # the signals received while honoured (the first one acts)
_stops: list = []  # 1-element host arrays (numpy views) of the launches running: set to 1 on a request
_depth = 0  # nesting of `honoured` contexts that installed or found our handler
_raised = False  # check() has raised for the current request


def _record(signum, frame):
    """The signal handler: record the request and tell the running launches to stop; nothing else."""
    _requested.append(signum)
    for stop in _stops:
        stop[0] = 1


def check(**notes) -> None:
    """A safe point: raise KeyboardInterrupt if an interrupt was requested (`notes` become its
    attributes, e.g. completed_path for the command line's message)."""
    global _raised
    if _requested:
        _raised = True
        exc = KeyboardInterrupt()
        for name, value in notes.items():
            setattr(exc, name, value)
        raise exc


@contextlib.contextmanager
def honoured(signals=(signal.SIGINT,)):
    """While inside, `signals` only record a request (acted on by `check()`). A signal whose
    handler is not Python's default (SIGINT: raise KeyboardInterrupt; SIGTERM: end the process) is
    left alone, unless our handler is already installed. The outermost context starts with no
    request and, leaving without an exception, raises KeyboardInterrupt (once the previous handlers
    are back) for a request that no `check()` acted on (a signal that came after the last safe
    point is not lost)."""
    global _depth, _raised
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}
    for signum in signals:
        handler = signal.getsignal(signum)
        if handler is signal.default_int_handler or (signum == signal.SIGTERM and handler == signal.SIG_DFL):
            previous[signum] = handler
            signal.signal(signum, _record)
    if _depth == 0:
        _requested.clear()
        _raised = False
    _depth += 1
    try:
        yield
    finally:
        _depth -= 1
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    if _depth == 0 and pending():  # after the handlers are back: a signal in between is not lost either
        check()


def pending() -> bool:
    """Whether a request was recorded that no `check()` has acted on."""
    return bool(_requested) and not _raised


def honour_until_exit(signals) -> None:
    """`signals` only record a request from now until the process ends (the command line's entry
    point: an outer `honoured` that never closes, so no signal meets a default handler between the
    command's last safe point and its exit; `pending()` says whether one came). Main thread only."""
    global _depth, _raised
    for signum in signals:
        signal.signal(signum, _record)
    _requested.clear()
    _raised = False
    _depth += 1


def honouring(fn):
    """`fn` runs `honoured` (Ctrl-C only: SIGTERM keeps its handler, the command line's or the
    default)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with honoured():
            return fn(*args, **kwargs)

    return wrapper


@contextlib.contextmanager
def held():
    """Signals recorded, not acted on, inside (the rename of a finished file: never half done), and
    delivered again on leaving, to whatever handler was there. Under `honoured` (our handler
    installed) nothing needs holding: it never raises."""
    if threading.current_thread() is not threading.main_thread():
        yield  # (Python runs signal handlers in the main thread only)
        return
    signals = (signal.SIGINT, signal.SIGTERM)
    previous = {signum: signal.getsignal(signum) for signum in signals}
    caught = []
    swapped = [signum for signum, handler in previous.items() if handler is not _record and handler is not None]
    for signum in swapped:
        signal.signal(signum, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        for signum in swapped:
            signal.signal(signum, previous[signum])
        for signum in caught:
            signal.raise_signal(signum)


def wait(work, stop=None) -> None:
    """Run `work()` (a long native call: a Warp launch on the CPU) in a worker thread while the main
    thread waits in short timed waits, so a signal's handler runs at once; `stop`, a 1-element host
    array the launch reads, is set to 1 on a request (the launch then returns early). Raises
    KeyboardInterrupt after the worker ended if an interrupt was requested, and re-raises the
    worker's exception. Off the main thread, or with no run honouring interrupts, `work()` runs
    here."""
    if _depth == 0 or threading.current_thread() is not threading.main_thread():
        work()
        return
    failure = []

    def target():
        try:
            work()
        except BaseException as exc:  # noqa: BLE001 - handed to the main thread
            failure.append(exc)

    if stop is not None:
        stop[0] = 1 if _requested else 0
        _stops.append(stop)
    worker = threading.Thread(target=target, name="warp-ricochet launch", daemon=True)
    try:
        worker.start()
        while worker.is_alive():
            worker.join(WAIT_SLICE)
            if _requested and stop is not None:
                stop[0] = 1
    except BaseException:  # another handler raised: the launch stops and ends before we go on
        if stop is not None:
            stop[0] = 1
        worker.join()
        raise
    finally:
        if stop is not None:
            _stops.remove(stop)
    if failure:
        raise failure[0]
    check()
