"""How fast Ctrl-C and SIGTERM end a run (figures, not tests). Run `python -m bench.interrupts --help`.

Each trial runs the command line (`cli.main`) in this process, statistics only, and sends SIGINT or
SIGTERM (in turn) to the process from a timer thread at a random moment of the run; the latency is
the time from the signal to `cli.main` returning its status 130 (the output closed; the interpreter's
own exit, ~0.1 s, is not in it). The kernels are loaded by a first, short run of each kind.

  core   the paper's scene, vacuum, 1e8 pellets (chunks of 2^21 on the CPU)
  air    the paper's scene in air, 1e6 pellets (chunks of one segment on the CPU)
  shots  pellet-pellet collisions, 20,000 shots of 20 pellets, float64
  paper-shots  pellet-pellet collisions, 10,000 paper shots of 450 (sized for a GPU)
  shot   pellet-pellet collisions, one shot of 3e6 pellets, float64, launches not separated (its
         dense phase is one launch on the CPU, stopped by its flag; on CUDA its launches are
         bounded: the frame's sums a thread a block, the horizon and the separation in pieces)
  separated-shot  the same shot with its launches separated (the separation: one thread a shot,
         in pieces of SEPARATION_PELLETS_PER_LAUNCH pellets on CUDA)

Every figure states the device it was measured on.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import random
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SCENE = str(ROOT / "examples" / "paper.toml")
COLLISIONS = ["collisions.enabled=true", 'numerics.precision="float64"']
LOST = 0.05  # s: a signal this long before a run returned must have interrupted it
# kind: (--set overrides, the overrides of its short warm-up run, the window of the signal's moment in s)
KINDS = {
    "core": (["shot.count=100000000"], ["shot.count=1000"], (0.5, 4.0)),
    "air": (["shot.count=1000000", "air.density=1.225"], ["shot.count=1000", "air.density=1.225"], (0.5, 4.0)),
    "shots": (
        ["shot.count=20", "shot.shots=20000", "shot.envelope_center=[0.0, 0.05, 0.0]", "surfaces.0.restitution=0.5", *COLLISIONS],
        ["shot.count=20", "shot.shots=2", *COLLISIONS],
        (0.5, 4.0),
    ),
    "paper-shots": (["shot.shots=10000", *COLLISIONS], ["shot.shots=2", *COLLISIONS], (0.5, 4.0)),  # GPU-sized
    "shot": (
        ["shot.count=3000000", "shot.envelope_radius=0.5", "collisions.separate=false", *COLLISIONS],
        ["shot.count=20", "collisions.separate=false", *COLLISIONS],
        (0.5, 6.0),
    ),
    "separated-shot": (
        ["shot.count=3000000", "shot.envelope_radius=0.5", *COLLISIONS],
        ["shot.count=20", *COLLISIONS],
        (0.5, 6.0),
    ),
}


def quiet_main(args):
    """`cli.main(args)`: (status, stderr lines, unraisable exceptions seen meanwhile)."""
    from warp_ricochet import cli

    err, unraisable = io.StringIO(), []
    hook, sys.unraisablehook = sys.unraisablehook, unraisable.append
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            status = cli.main(args)
    finally:
        sys.unraisablehook = hook
    return status, err.getvalue().splitlines(), unraisable


def trial(args, delay, signum):
    """`cli.main(args)` with `signum` sent to this process after `delay` s: (status, stderr lines,
    unraisable exceptions, latency in s, or None when the run had ended before the signal). An outer
    `interrupts.honoured` catches a signal that lands after cli.main returned (then: None). A signal
    sent more than LOST s before the run returned with status 0 was lost: AssertionError."""
    from warp_ricochet import interrupts

    sent = []
    timer = threading.Timer(delay, lambda: (os.kill(os.getpid(), signum), sent.append(time.perf_counter())))
    late = False
    try:
        with interrupts.honoured((signal.SIGINT, signal.SIGTERM)):
            timer.start()
            try:
                status, lines, unraisable = quiet_main(args)
                end = time.perf_counter()
            finally:
                timer.cancel()
                timer.join()
                time.sleep(0.01)  # (a signal sent just now is handled here, by the outer handler)
    except KeyboardInterrupt:
        late = True
    if sent and status == 0 and sent[0] < end - LOST:
        raise AssertionError(f"a signal sent {end - sent[0]:.3f} s before the run ended was lost: {lines}")
    latency = None if late or not sent or status == 0 else end - sent[0]
    return status, lines, unraisable, latency


def command(device, sets):
    return ["run", SCENE, "--device", device, *(a for s in sets for a in ("--set", s))]


def measure(kind, device, trials, seed=2021):
    """Latencies (s) of `trials` signals at random moments of a `kind` run on `device`."""
    sets, warm, (lo, hi) = KINDS[kind]
    status, lines, _, _ = trial(command(device, warm), 1e6, signal.SIGINT)  # load the kernels
    assert status == 0, lines
    rng = random.Random(seed)
    latencies, late, bad = [], 0, []
    for k in range(trials):
        status, lines, unraisable, latency = trial(
            command(device, sets), rng.uniform(lo, hi), (signal.SIGINT, signal.SIGTERM)[k % 2]
        )
        if latency is None:
            late += 1
            continue
        lines = [line for line in lines if ": warning: " not in line]  # (a scene's warnings before it)
        if status != 130 or len(lines) != 1 or unraisable:
            bad.append((status, lines, len(unraisable)))
        latencies.append(latency)
    lat = np.array(latencies)
    if not len(lat):
        print(f"{kind:6s} every run ended before its signal: a longer run is needed on this device", flush=True)
        return {"kind": kind, "sets": sets, "trials": trials, "late": late}
    row = {
        "kind": kind,
        "sets": sets,
        "trials": trials,
        "late": late,
        "not_one_line_130": len(bad),
        "latency_max_s": float(lat.max()),
        "latency_median_s": float(np.median(lat)),
        "latency_p90_s": float(np.quantile(lat, 0.9)),
        "latencies_s": [round(x, 4) for x in latencies],
    }
    print(
        f"{kind:6s} {len(lat)} interrupted ({late} after the end, {len(bad)} not one line/130): latency "
        f"median {row['latency_median_s']:.3f} s, p90 {row['latency_p90_s']:.3f} s, max {row['latency_max_s']:.3f} s",
        flush=True,
    )
    return row


def main(argv=None):
    from bench.__main__ import _wr, device_info

    p = argparse.ArgumentParser(
        prog="python -m bench.interrupts", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--device", default="cpu")
    p.add_argument("--kinds", default=",".join(KINDS), help=f"comma-separated, of {', '.join(KINDS)}")
    p.add_argument("--trials", type=int, default=10, help="signals per kind")
    p.add_argument("--out", metavar="DIR", help="write interrupts-DEVICE.json there")
    args = p.parse_args(argv)
    _wr_, wp = _wr()
    wp.config.quiet = True
    info = device_info(wp, args.device)
    print(f"device: {info}", flush=True)
    rows = [measure(kind, args.device, args.trials) for kind in args.kinds.split(",")]
    if args.out:
        path = Path(args.out) / f"interrupts-{args.device.replace(':', '')}.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({"device": info, "rows": rows}, indent=1))
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
