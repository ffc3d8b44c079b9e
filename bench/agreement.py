"""CPU against GPU, per pellet: `save` runs a fixed scene on one device into an HDF5 file;
`compare` runs it on another and prints the largest differences, relative to each field's
scale, and the share of pellets with the same discrete outcomes (branch, surfaces).
Used because the lent GPU hosts carry Warp without its CPU compiler: save on the CPU here,
compare there. Run: python -m bench.agreement save|compare --device D --file F"""

import argparse
import sys

import h5py
import numpy as np

SETS = ["shot.count=20000", "shot.spin=[0.0, 0.0, 3000.0]", "physics.bounces=2", 'output.fields=["initial", "impact", "landing"]']
WALL = {"point": [40.0, 0.0, 0.0], "normal": [-1.0, 0.2, 0.0], "restitution": 0.3, "mu_s": 0.3, "mu_d": 0.25}


def scene(precision):
    from bench.__main__ import SCENE
    from warp_ricochet.scene import load_scene, scene_from_dict

    sc = load_scene(SCENE, SETS + [f"numerics.precision={precision}", "surfaces.0.mu_s=0.28", "surfaces.0.mu_d=0.25"])
    raw = sc.to_dict()
    raw["surfaces"].append(WALL)
    return scene_from_dict(raw)


def read(path, group):
    out = {}
    with h5py.File(path, "r") as f:
        f[group].visititems(lambda k, o: out.__setitem__(k, o[()]) if isinstance(o, h5py.Dataset) else None)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("action", choices=["save", "compare"])
    ap.add_argument("--device", required=True)
    ap.add_argument("--file", required=True)
    args = ap.parse_args(argv)
    import warp_ricochet as wr

    if args.action == "save":
        with h5py.File(args.file, "w") as f:
            for precision in ("float32", "float64"):
                wr.run(scene(precision), "/tmp/agreement-run.h5", device=args.device, overwrite=True)
                with h5py.File("/tmp/agreement-run.h5", "r") as src:
                    src.copy(src["pellets"], f, name=precision)
        print(f"saved {args.file}")
        return 0
    worst = 0.0
    for precision, rtol in (("float32", 2e-5), ("float64", 1e-12)):
        wr.run(scene(precision), "/tmp/agreement-run.h5", device=args.device, overwrite=True)
        a, b = read(args.file, precision), read("/tmp/agreement-run.h5", "pellets")
        same = (a["impact/slipped"] == b["impact/slipped"]).all(axis=1) & (a["landing/surface"] == b["landing/surface"])
        same &= (a["impact/surface"] == b["impact/surface"]).all(axis=1)
        print(f"{precision}: {same.mean() * 100:.3f}% of {len(same)} pellets with the same outcomes (branch, surfaces)")
        for name in sorted(a):
            x, y = a[name][same], b[name][same]
            if x.dtype.kind != "f":
                continue
            fin = np.isfinite(x)
            scale = np.abs(x[fin]).max() if fin.any() else 1.0
            diff = np.abs(x[fin] - y[fin]).max() / scale if fin.any() else 0.0
            ok = (fin == np.isfinite(y)).all() and diff <= rtol
            worst = max(worst, diff / rtol)
            print(f"  {name:32s} max |cpu - gpu| / scale = {diff:.2e}  (tolerance {rtol:.0e}) {'ok' if ok else 'FAIL'}")
    return 0 if worst <= 1 else 1


if __name__ == "__main__":
    sys.exit(main())
