"""Benchmarks of the no-collision pipeline (figures, not tests). Run `python -m bench --help`.

  throughput  pellets/s of a statistics-only run against N, on a Warp device, beside the
              vectorised NumPy float64 version (warp_ricochet.reference) in the same run
  write       a run that writes per-pellet landing data: total time against compute-only time
              and against the time to write the same bytes with h5py alone (is it disk-bound?)
  memory      peak host memory (RSS) of runs in fresh processes, and device bytes per pellet
  tradeoff    run time against error: float32, float32 + fast_math and float64 on the device,
              each against the NumPy float64 reference on the same launch states
  all         throughput, write and memory, with a JSON record under --out

Every figure states the device it was measured on. Warm-up runs (kernel compilation) are not timed.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "examples" / "paper.toml"


def _wr():
    import warp_ricochet as wr
    from warp_ricochet.device import warp as _warp

    return wr, _warp()


def scene_for(n: int, precision="float32", fields=(), mu_s=0.05, fast_math=None):
    """The paper's scene with N pellets; fast_math None keeps the scene's default."""
    from warp_ricochet.scene import load_scene

    sets = [
        f"shot.count={n}",
        f"numerics.precision={precision}",
        f"output.fields={list(fields)!r}".replace("'", '"'),
        f"surfaces.0.mu_s={mu_s}",
        f"surfaces.0.mu_d={0.9 * mu_s}",
    ]
    if fast_math is not None:
        sets.append(f"numerics.fast_math={str(fast_math).lower()}")
    return load_scene(SCENE, sets)


MODES = (("float32", False), ("float32", True), ("float64", False))


def tradeoff(device, n, big, repeats, out_dir):
    """Run time (statistics-only, `big` pellets) against error (`n` pellets, per pellet against
    the NumPy float64 reference on the same launch states) for each precision mode. The mixed
    stick/slip friction mu_s = 0.28 puts pellets on both sides of eq. (22)."""
    wr, wp = _wr()
    import h5py

    from warp_ricochet.reference import ballistic as reference

    rows = []
    for precision, fast in MODES:
        label = precision + (" + fast_math" if fast else "")
        scene = scene_for(n, precision, ("initial", "landing.range", "impact.slipped"), mu_s=0.28, fast_math=fast)
        path = Path(out_dir) / "tradeoff.h5"
        stats = wr.run(scene, path, device=device, overwrite=True)
        with h5py.File(path, "r") as f:
            p0, v0, w0 = (f[f"pellets/initial/{k}"][()].astype(np.float64) for k in ("position", "velocity", "angular_velocity"))
            rng_ = f["pellets/landing/range"][()].astype(np.float64)
            slipped = f["pellets/impact/slipped"][:, 0]
        path.unlink()
        ref, ref_stats = reference.simulate(scene_for(n, "float64", mu_s=0.28), p0, v0, w0)
        same = ref["impact.slipped"][:, 0] == slipped
        err = np.abs(rng_ - ref["landing.range"])[same] / ref["landing.range"][same]
        big_scene = scene_for(big, precision, mu_s=0.28, fast_math=fast)
        wr.run(big_scene, device=device)

        def go():
            wr.run(big_scene, device=device)
            wp.synchronize_device(device)

        t, _ = _timed(go, repeats)
        row = {
            "mode": label,
            "pellets_per_s": big / t,
            "N_timed": big,
            "N_checked": n,
            "range_max_rel_error": float(err.max()),
            "range_median_rel_error": float(np.median(err)),
            "mean_range_rel_error": abs(stats["range_mean"] - ref_stats["range_mean"]) / ref_stats["range_mean"],
            "branch_mismatches": int((~same).sum()),
        }
        rows.append(row)
        print(
            f"tradeoff {label:20s} {row['pellets_per_s']:.3e} pellets/s | range error per pellet: max {row['range_max_rel_error']:.1e}, "
            f"median {row['range_median_rel_error']:.1e}; mean range {row['mean_range_rel_error']:.1e}; "
            f"stick/slip branch differs for {row['branch_mismatches']} of {n:,d}",
            flush=True,
        )
    return rows


def device_info(wp, device):
    dev = wp.get_device(device)
    info = {
        "device": str(dev),
        "name": dev.name,
        "warp": wp.config.version,
        "host": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
    }
    if dev.is_cuda:
        info["total_memory_GiB"] = round(dev.total_memory / 2**30, 1)
    return info


def _timed(fn, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), times


def throughput(device, sizes, numpy_max, repeats, precision="float32"):
    wr, wp = _wr()
    from warp_ricochet.reference import ballistic as reference

    wr.run(scene_for(1000, precision), device=device)  # compile
    rows = []
    for n in sizes:
        scene = scene_for(n, precision)

        def go():
            wr.run(scene, device=device)
            wp.synchronize_device(device)

        t, _ = _timed(go, repeats)
        row = {"N": n, "precision": precision, "warp_s": t, "warp_pellets_per_s": n / t}
        if n <= numpy_max:
            rng = np.random.default_rng(1)

            def go_numpy():
                pos, vel, spin = reference.sample_launch(scene.shot, rng)
                reference.simulate(scene, pos, vel, spin)

            tn, _ = _timed(go_numpy, max(1, min(repeats, 3)))
            row.update(numpy_s=tn, numpy_pellets_per_s=n / tn, speedup=tn / t)
        rows.append(row)
        print(_fmt_row(row), flush=True)
    return rows


def _fmt_row(row):
    s = f"N={row['N']:>12,d} {row['precision']}  warp {row['warp_pellets_per_s']:.3e} pellets/s ({row['warp_s'] * 1e3:9.2f} ms)"
    if "numpy_pellets_per_s" in row:
        s += f"  numpy {row['numpy_pellets_per_s']:.3e} pellets/s  speed-up {row['speedup']:.1f}x"
    return s


def write_bench(device, n, out_dir, fields=("landing",)):
    """Per-pellet output run vs compute-only run vs writing the same bytes with h5py alone."""
    wr, wp = _wr()
    import h5py

    from warp_ricochet.fields import FIELDS

    expanded = [f for f in FIELDS if f in fields or f.split(".")[0] in fields]
    wr.run(scene_for(1000, fields=expanded), Path(out_dir) / "warm.h5", device=device, overwrite=True)
    t0 = time.perf_counter()
    wr.run(scene_for(n), device=device)
    wp.synchronize_device(device)
    compute = time.perf_counter() - t0
    path = Path(out_dir) / "bench-write.h5"
    t0 = time.perf_counter()
    wr.run(scene_for(n, fields=expanded), path, device=device, overwrite=True)
    total = time.perf_counter() - t0
    size = path.stat().st_size
    # the same bytes written by h5py alone, in the same chunked layout: the disk's own rate
    raw = Path(out_dir) / "bench-raw.h5"
    with h5py.File(path, "r") as src:
        shapes = {name: (ds.shape, ds.dtype, ds.chunks) for name, ds in src["pellets/landing"].items()}
    block = 1 << 22
    t0 = time.perf_counter()
    with h5py.File(raw, "w") as f:
        for name, (shape, dtype, chunks) in shapes.items():
            ds = f.create_dataset(name, shape=shape, dtype=dtype, chunks=chunks)
            data = np.ones((min(block, shape[0]),) + shape[1:], dtype)
            for start in range(0, shape[0], block):
                stop = min(start + block, shape[0])
                ds[start:stop] = data[: stop - start]
    raw_time = time.perf_counter() - t0
    raw.unlink()
    path.unlink()
    row = {
        "N": n,
        "fields": expanded,
        "bytes": size,
        "total_s": total,
        "compute_only_s": compute,
        "h5py_only_s": raw_time,
        "pellets_per_s": n / total,
        "write_GB_per_s": size / total / 1e9,
        "h5py_only_GB_per_s": size / raw_time / 1e9,
        "total_over_h5py_only": total / raw_time,
    }
    print(
        f"write N={n:,d}: total {total:.2f} s ({row['write_GB_per_s']:.2f} GB/s), compute only {compute:.3f} s, "
        f"h5py alone {raw_time:.2f} s ({row['h5py_only_GB_per_s']:.2f} GB/s): total/h5py-alone = {row['total_over_h5py_only']:.2f}",
        flush=True,
    )
    return row


MEMORY_CHILD = """
import json, sys, time
sys.path.insert(0, {root!r})

def hwm():  # peak resident memory of this process, MiB (VmHWM; ru_maxrss would include the parent's peak)
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024

from bench.__main__ import scene_for, _wr
wr, wp = _wr()
n, device, out = {n}, {device!r}, {out!r}
fields = {fields!r}
wr.run(scene_for(1000, fields=fields), out, device=device, overwrite=True) if out else wr.run(scene_for(1000), device=device)
base = hwm()
t0 = time.perf_counter()
wr.run(scene_for(n, fields=fields), out, device=device, overwrite=True) if out else wr.run(scene_for(n), device=device)
wp.synchronize_device(device)
dt = time.perf_counter() - t0
print(json.dumps({{"peak_rss_MiB": hwm(), "rss_after_warmup_MiB": base, "seconds": dt}}))
"""


def memory(device, cases, out_dir):
    """Peak host RSS of fresh processes (ru_maxrss), and device bytes per pellet by mode."""
    from warp_ricochet.fields import FIELDS
    from warp_ricochet.model import State

    rows = []
    for n, fields in cases:
        expanded = [f for f in FIELDS if f in fields or f.split(".")[0] in fields]
        out = str(Path(out_dir) / "bench-mem.h5") if expanded else ""
        code = MEMORY_CHILD.format(root=str(ROOT), n=n, device=device, out=out, fields=expanded)
        res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        if res.returncode != 0:
            print(res.stderr[-2000:])
            continue
        row = json.loads(res.stdout.strip().splitlines()[-1])
        row.update(N=n, fields=expanded, device_bytes_per_pellet=State.bytes_per_pellet("float32", expanded, 1))
        if out:
            Path(out).unlink(missing_ok=True)
        rows.append(row)
        print(
            f"memory N={n:,d} fields={fields or 'stats only'}: peak host RSS {row['peak_rss_MiB']:.0f} MiB "
            f"(after warm-up {row['rss_after_warmup_MiB']:.0f}), {row['seconds']:.2f} s, device {row['device_bytes_per_pellet']:.2f} B/pellet",
            flush=True,
        )
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(
        prog="python -m bench", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("what", choices=["throughput", "write", "memory", "tradeoff", "all"])
    ap.add_argument("--device", default=None, help="cpu, cuda:0 (default: CUDA if present)")
    ap.add_argument("--sizes", default="1e4,1e5,1e6", help="pellet counts for throughput")
    ap.add_argument("--numpy-max", type=float, default=1e6, help="largest N also run with NumPy")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--precision", default="float32", choices=["float32", "float64"])
    ap.add_argument("--write-n", type=float, default=1e6)
    ap.add_argument("--tradeoff-n", default="1e5,1e6", help="N checked against NumPy, N timed")
    ap.add_argument("--memory-cases", default="1e6:,1e6:landing", help="N:fields,... (fields empty = statistics only)")
    ap.add_argument("--out", default=None, help="folder for results.json (default: a temp folder)")
    args = ap.parse_args(argv)
    wr, wp = _wr()
    device = args.device or str(wp.get_preferred_device())
    out_dir = Path(args.out or tempfile.mkdtemp(prefix="wr-bench-"))
    out_dir.mkdir(parents=True, exist_ok=True)
    record = {"info": device_info(wp, device), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}
    print(json.dumps(record["info"]))
    if args.what in ("throughput", "all"):
        sizes = [int(float(s)) for s in args.sizes.split(",")]
        record["throughput"] = throughput(device, sizes, args.numpy_max, args.repeats, args.precision)
    if args.what in ("write", "all"):
        record["write"] = write_bench(device, int(args.write_n), out_dir)
    if args.what in ("memory", "all"):
        cases = []
        for case in args.memory_cases.split(","):
            n, _, fields = case.partition(":")
            cases.append((int(float(n)), tuple(f for f in fields.split("+") if f)))
        record["memory"] = memory(device, cases, out_dir)
    if args.what == "tradeoff":
        n, big = (int(float(x)) for x in args.tradeoff_n.split(","))
        record["tradeoff"] = tradeoff(device, n, big, args.repeats, out_dir)
    path = out_dir / f"results-{args.what}-{device.replace(':', '')}.json"
    path.write_text(json.dumps(record, indent=1))
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
