"""A sweep's host memory against its points (issue 24, item 5; figures, not tests).
Run `python -m bench.sweep_memory --help`.

Each mode runs one sweep of `--points` points through `warp_ricochet.sweep` in a fresh process
and reads its anonymous resident memory (RssAnon, Linux: the heap, where kept arrays grow; VmRSS
adds file-backed pages, which come and go with the machine's load) as each point completes (the
sweep's progress callback) and once the sweep has returned:

  file    with a sweep file (-o): the points written to OUT.h5.partial/, then assembled
  memory  no file: the statistics returned in a list

The scene: `examples/hazard.toml` (four hazard thresholds, a map; landing tallies on, the default)
as one shot of `--count` pellets, or `--scene paper` (examples/paper.toml, no thresholds), swept
over surfaces.0.mu_s in [0, 0.5] with mu_d = 0.9 mu_s. The growth a point is the least-squares
slope of RssAnon from point 10 to the last.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SCENES = {"hazard": ROOT / "examples" / "hazard.toml", "paper": ROOT / "examples" / "paper.toml"}
MARKS = (1, 10, 100, 1000, 10000)


def rss_mib(field: str = "RssAnon") -> float:
    """This process's resident memory, MiB: `field` of /proc/self/status (RssAnon or VmRSS)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1]) / 1024
    raise RuntimeError(f"no {field} in /proc/self/status")


def sweep_rss(scene_name: str, count: int, points: int, device: str, output: str | None) -> dict:
    """Run the sweep here; returns RssAnon (MiB) after each point, before the first and at the end
    (and VmRSS there)."""
    import warp_ricochet as wr
    from warp_ricochet.scene import load_scene

    sets = ["shot.shots=1", f"shot.count={count}"] if scene_name == "hazard" else [f"shot.count={count}"]
    scene = load_scene(SCENES[scene_name], sets)
    wr.run(scene, device=device)  # kernels compiled and loaded before the first sample
    samples, t0 = [], time.perf_counter()

    def progress(done, total):
        if done * points % total == 0 and done * points // total > len(samples):  # a point complete
            samples.append(rss_mib())

    params = {"surfaces.0.mu_s": [float(x) for x in np.linspace(0.0, 0.5, points)]}
    ties = [("surfaces.0.mu_d", 0.9, "surfaces.0.mu_s")]
    before = rss_mib()
    results = wr.sweep(scene, params, ties, output, device, overwrite=True, progress=progress)
    seconds = time.perf_counter() - t0
    assert len(results) == points == len(samples), (len(results), len(samples))
    return {
        "rss_before_MiB": before,
        "rss_MiB": samples,
        "rss_end_MiB": rss_mib(),
        "seconds": seconds,
        "vmrss_end_MiB": rss_mib("VmRSS"),
    }


def summary(row: dict) -> str:
    """One line: RSS at the marks, the growth a point, the end."""
    rss = row["rss_MiB"]
    marks = ", ".join(f"point {m:,}: {rss[m - 1]:.0f}" for m in MARKS if m <= len(rss))
    return (
        f"{row['mode']:6} {row['scene']} x{row['count']} pellets, {len(rss):,} points: RssAnon MiB before "
        f"{row['rss_before_MiB']:.0f}, {marks}, after the sweep {row['rss_end_MiB']:.0f} (VmRSS "
        f"{row['vmrss_end_MiB']:.0f}); growth {row['growth_KiB_per_point']:.1f} KiB a point; {row['seconds']:.0f} s"
    )


def measure(mode: str, args) -> dict:
    """One mode in a fresh process (this module's --child)."""
    folder = Path(args.out or tempfile.mkdtemp(prefix="wr-sweep-mem-"))
    output = str(folder / "sweep-memory.h5") if mode == "file" else ""
    cmd = [
        sys.executable,
        "-m",
        "bench.sweep_memory",
        "--child",
        mode,
        "--scene",
        args.scene,
        "--count",
        str(args.count),
        "--points",
        str(args.points),
        "--device",
        args.device,
        "--child-output",
        output,
    ]
    res = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    if res.returncode != 0:
        raise SystemExit(res.stderr[-3000:])
    row = json.loads(res.stdout.strip().splitlines()[-1])
    if output:
        Path(output).unlink(missing_ok=True)
        Path(output).with_suffix(".xmf").unlink(missing_ok=True)
    rss = np.asarray(row["rss_MiB"])
    tail = np.arange(10, len(rss) + 1)
    row["growth_KiB_per_point"] = float(np.polyfit(tail, rss[9:], 1)[0] * 1024) if len(tail) > 1 else float("nan")
    row.update(mode=mode, scene=args.scene, count=args.count)
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(
        prog="python -m bench.sweep_memory", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--modes", default="file,memory", help="file, memory or both (comma-separated)")
    ap.add_argument("--scene", default="hazard", choices=sorted(SCENES))
    ap.add_argument("--count", type=int, default=20, help="pellets a point")
    ap.add_argument("--points", type=int, default=1000)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", default=None, help="folder for the sweep file and results JSON (default: a temp folder)")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--child-output", default="", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(sweep_rss(args.scene, args.count, args.points, args.device, args.child_output or None)))
        return 0
    import warp_ricochet

    record = {
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "device": args.device,
        "package": str(Path(warp_ricochet.__file__).parent),
        "rows": [],
    }
    for mode in args.modes.split(","):
        row = measure(mode, args)
        record["rows"].append(row)
        print(summary(row), flush=True)
    if args.out:
        path = Path(args.out) / f"sweep-memory-{args.scene}-{args.points}.json"
        path.write_text(json.dumps(record, indent=1))
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
