"""Golden digests: the bits of every per-pellet dataset and statistic of a few runs on the CPU.

They hold results bitwise across refactors (issue 11): `python -m tests.golden record` adds this
machine's digests to tests/data/golden-cpu.json; tests/test_golden.py recomputes and compares. Warp's
CPU compiler targets the host CPU (LLVM's host name and features: FMA contraction differs between
CPUs), so the digests are kept per fingerprint of the machine and the Warp version; on a machine
with none the test says so and skips. Record only on code known to be right (e.g. a checkout of
the commit that first recorded them).
"""

from __future__ import annotations

import hashlib
import json
import math
import platform
import sys
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = Path(__file__).parent / "data" / "golden-cpu.json"

COLLISIONS = [
    "collisions.enabled=true",
    "shot.shots=3",
    "shot.count=200",
    'output.fields=["initial", "impact", "landing", "collisions", "release"]',
]
CASES = {
    "paper-float32": ("examples/paper.toml", []),
    "paper-float64": ("examples/paper.toml", ['numerics.precision="float64"']),
    "steel-plate": ("tests/data/golden_steel_plate.toml", []),
    "spin-planes": (
        "tests/data/golden_steel_plate.toml",
        [
            "shot.count=70000",
            "shot.spin=[300.0, -2000.0, 9000.0]",
            "physics.bounces=3",
            'numerics.precision="float64"',
            'output.fields=["initial", "impact", "landing"]',
        ],
    ),
    "collisions-float64": ("examples/paper.toml", COLLISIONS + ['numerics.precision="float64"']),
    "collisions-float32": ("examples/paper.toml", COLLISIONS),
}


def fingerprint() -> str:
    """The CPU model and flags that LLVM's host target depends on, and the Warp version."""
    import warp as wp

    model, flags = platform.processor() or platform.machine(), ""
    try:
        info = Path("/proc/cpuinfo").read_text()
        model = next(line.split(":", 1)[1].strip() for line in info.splitlines() if line.startswith("model name"))
        flags = next(line.split(":", 1)[1] for line in info.splitlines() if line.startswith("flags"))
    except (OSError, StopIteration):
        pass
    wanted = ("fma", "avx2", "avx512f", "avx512vl", "neon", "asimd")
    features = ",".join(f for f in wanted if f in flags.split())
    return f"{model} [{features}] warp {wp.config.version}"


def _sha(array) -> str:
    a = np.ascontiguousarray(array)
    return hashlib.sha256(a.dtype.str.encode() + str(a.shape).encode() + a.tobytes()).hexdigest()[:24]


def digests(path) -> dict[str, str]:
    """{dataset: digest} of /pellets/** and of the /stats a run computes (NaN statistics left out:
    a run without collisions has no collision statistics)."""
    out = {}
    with h5py.File(path, "r") as f:

        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                out[f"pellets/{name}"] = _sha(obj[()])

        f["pellets"].visititems(visit)
        for name, ds in f["stats"].items():
            if not isinstance(ds, h5py.Dataset):  # /stats/quantiles, /stats/shots etc. (issue 15): not in the digests
                continue
            value = float(ds[()])
            if not math.isnan(value):
                out[f"stats/{name}"] = _sha(np.float64(value))
    return out


def run_case(name: str, tmp: Path) -> dict[str, str]:
    import warp_ricochet as wr
    from warp_ricochet.scene import load_scene

    scene_path, overrides = CASES[name]
    scene = load_scene(ROOT / scene_path, overrides)
    out = tmp / f"{name}.h5"
    wr.run(scene, out, device="cpu", overwrite=True)
    return digests(out)


def recorded() -> dict[str, dict]:
    """{fingerprint: {case: {dataset: digest}}} of every machine recorded so far."""
    return json.loads(GOLDEN.read_text())["machines"] if GOLDEN.exists() else {}


def record(tmp: Path) -> tuple[str, dict]:
    machines = recorded()
    key = fingerprint()
    machines[key] = {name: run_case(name, tmp) for name in CASES}
    GOLDEN.write_text(json.dumps({"machines": machines}, indent=1, sort_keys=True) + "\n")
    return key, machines[key]


if __name__ == "__main__":
    import tempfile
    import warnings

    warnings.simplefilter("ignore")
    if sys.argv[1:] != ["record"]:
        raise SystemExit("usage: python -m tests.golden record")
    with tempfile.TemporaryDirectory() as tmp:
        key, cases = record(Path(tmp))
    print(f"recorded {sum(map(len, cases.values()))} digests of {len(cases)} runs for {key}")
