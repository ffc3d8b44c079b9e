"""`output.compression` of the per-pellet datasets: a run of N pellets (the paper's scene, default
fields: initial, impact, landing; float32) written with each setting: its wall time, its file size,
and the time to write the same arrays with h5py alone in the writer's chunks and filters (the
filters' own cost, without the computation). One run each after a warm-up run (kernel builds).

    python -m bench.compression [--device cpu] [--pellets 1e6]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import h5py

from bench.__main__ import SCENE, _wr, device_info

SETTINGS = ("none", "lzf", "gzip-1", "gzip-4", "gzip-9")


def _h5py_write(arrays: dict, path: str, setting: str) -> float:
    from warp_ricochet.scene.schema import COMPRESSIONS

    start = time.perf_counter()
    with h5py.File(path, "w") as f:
        for name, a in arrays.items():
            rows = min(1 << 16, len(a))
            ds = f.create_dataset(
                name,
                shape=(0,) + a.shape[1:],
                maxshape=(None,) + a.shape[1:],
                chunks=(rows,) + a.shape[1:],
                dtype=a.dtype,
                **COMPRESSIONS[setting],
            )
            for lo in range(0, len(a), 1 << 18):  # appended chunk by chunk, as the writer does
                block = a[lo : lo + (1 << 18)]
                ds.resize(lo + len(block), axis=0)
                ds[lo:] = block
    return time.perf_counter() - start


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--device", default="cpu")
    p.add_argument("--pellets", type=float, default=1e6)
    args = p.parse_args(argv)
    wr, wp = _wr()
    from warp_ricochet.scene import load_scene

    n = int(args.pellets)
    print(device_info(wp, args.device))
    with tempfile.TemporaryDirectory() as tmp:
        wr.run(load_scene(SCENE, ["shot.count=1000"]), os.path.join(tmp, "warm.h5"), device=args.device)
        arrays = None
        print(f"{'setting':8} {'run s':>7} {'file MB':>8} {'ratio':>6} {'h5py write s':>12}")
        base = None
        for setting in SETTINGS:
            out = os.path.join(tmp, f"{setting}.h5")
            start = time.perf_counter()
            wr.run(load_scene(SCENE, [f"shot.count={n}", f"output.compression={setting!r}"]), out, device=args.device)
            seconds = time.perf_counter() - start
            size = os.path.getsize(out)
            if arrays is None:
                with h5py.File(out) as f:
                    arrays = {}
                    f["pellets"].visititems(
                        lambda k, o: (
                            arrays.__setitem__(k, o[()]) if isinstance(o, h5py.Dataset) and o.ndim and len(o) == n else None
                        )
                    )
            base = base or size
            write = _h5py_write(arrays, os.path.join(tmp, "w.h5"), setting)
            print(f"{setting:8} {seconds:7.2f} {size / 1e6:8.1f} {base / size:6.2f} {write:12.2f}")


if __name__ == "__main__":
    main()
