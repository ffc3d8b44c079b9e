"""Where the CPU kernel's time goes, by the inlined @wp.func: a run under `perf record`, its samples
mapped onto the kernel's object file with its line tables.

    perf record -o perf.data python -m bench.cpu_profile run --n 2e4 --out prof/ [--set KEY=VALUE ...]
    perf record -o perf.data python -m bench.cpu_profile run --case terrain --n 2e4 --out prof/
    python -m bench.cpu_profile report perf.data prof/

`run`: the paper's shot (mu_s 0.5, float32 unless --precision) in sea-level air to rest on turf
(`--set` adds settings); `--case terrain` or `terrain-air`: `bench.meshes terrain`'s scene (the
paper's shot to the landing over 1,002,528 triangles, vacuum or sea-level air; `--set` ignored),
or `plane` / `plane-air`: the same shot on the paper's plane (a warm-up run first); compiled with
line tables (`-debug-info-kind=line-tables-only`, the same machine code) in its own kernel cache
(prof/cache), then run --repeats times; it writes where the
ricochet kernel was loaded (prof/kernel.json) and /tmp/perf-PID.map (its functions that were not
inlined, for `perf report`). Warp loads CPU kernels through its own JIT, without symbols for perf:
this relies on Warp 1.19's internals (`warp._src.build.build_cpu`, `runtime.llvm.wp_lookup`).
`report`: the shares of the samples by library, then of the kernel's samples by the innermost
function of the package's (inlined) @wp.funcs, self and inclusive (`addr2line -i`), and by the
Python line (Warp's comments in the generated C++; "?" where the optimiser left no line). A call
into libm leaves no frame of the kernel (it keeps no frame pointer), so libm's samples are not
attributed. The run's first compilation is in the samples too (warp-clang.so).
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import subprocess
import time
from pathlib import Path

KERNEL = "ricochet_kernel"


def run(n, repeats, precision, settings, out: Path, case="rest"):
    out.mkdir(parents=True, exist_ok=True)
    os.environ["WARP_CACHE_PATH"] = str(out / "cache")
    import warp as wp
    import warp._src.build as build
    import warp._src.context as context

    plain = build.build_cpu

    def with_lines(*args, **kwargs):
        kwargs["extra_flags"] = (kwargs.get("extra_flags") or "") + " -debug-info-kind=line-tables-only"
        return plain(*args, **kwargs)

    build.build_cpu = with_lines
    wp.init()
    found = {}
    lookup = context.runtime.llvm.wp_lookup

    def recorded(handle, name):
        address = lookup(handle, name)
        found[name.decode()] = address
        return address

    context.runtime.llvm.wp_lookup = recorded
    import warp_ricochet as wr
    from bench.air import paper_scene

    if case == "rest":
        extra = ['physics.until="rest"', 'surfaces.0.material="turf"', *settings]
        scene = paper_scene(n, precision, air=True, mu_s=0.5, extra=extra)
    else:
        import tempfile

        from bench.meshes import _paper, terrain_raster, terrain_surfaces

        surfaces = terrain_surfaces(terrain_raster(tempfile.mkdtemp())) if case.startswith("terrain") else None
        scene = _paper(n, precision, case.endswith("-air"), surfaces)
        wr.run(scene, device="cpu")  # compiles, reads the raster and builds its BVH before the timed runs
    for _ in range(repeats):
        started, cpu = time.perf_counter(), time.process_time()
        wr.run(scene, device="cpu")
        print(f"{n} pellets: {time.perf_counter() - started:.3f} s, CPU {time.process_time() - cpu:.3f} s", flush=True)
    entry = next(name for name in found if KERNEL in name and name.endswith("_cpu_forward"))
    obj = next(o for o in (out / "cache").rglob("*.o") if KERNEL in o.name and entry in _symbols(o))
    symbols = _symbols(obj)
    base = found[entry] - symbols[entry][0]
    size = int(subprocess.run(["size", "-A", str(obj)], capture_output=True, text=True).stdout.split(".ltext")[1].split()[0])
    (out / "kernel.json").write_text(json.dumps({"object": str(obj), "base": base, "size": size}))
    lines = [f"{base + offset:x} {length:x} {name}" for name, (offset, length) in symbols.items()]
    Path(f"/tmp/perf-{os.getpid()}.map").write_text("\n".join(lines) + "\n")


def _symbols(obj) -> dict:
    """{name: (offset, size)} of the object's defined functions."""
    out = {}
    for line in subprocess.run(["nm", "-S", str(obj)], capture_output=True, text=True).stdout.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[2] in "tT":
            out[parts[3]] = (int(parts[0], 16), int(parts[1], 16))
    return out


def _short(function):
    name = function.split("(")[0].replace("__locals__", ".")
    return re.sub(r"_\d+$", "", name.split("::")[-1])[-60:]


def _python_line(source, where):
    """The Python source (Warp's `// ... <L n>` comment) nearest above the generated line `where`."""
    number = where.rsplit(":", 1)[-1].split()[0]
    if ".cpp:" not in where or not number.isdigit():
        return "?"
    for k in range(int(number) - 1, max(int(number) - 60, 0), -1):
        found = re.search(r"// (.*)<L (\d+)>", source[k])
        if found:
            return f"{found.group(1).strip()[:70]} (L {found.group(2)})"
        if source[k].startswith("static CUDA_CALLABLE"):  # the function's start (a native one has no comments)
            break
    return "?"


def report(data, folder: Path, top=25):
    kernel = json.loads((folder / "kernel.json").read_text())
    base, size = kernel["base"], kernel["size"]
    script = subprocess.run(["perf", "script", "-i", data, "-F", "ip,dso"], capture_output=True, text=True).stdout
    libraries, offsets = collections.Counter(), collections.Counter()
    for line in script.splitlines():
        parts = line.split(None, 1)
        if len(parts) != 2:
            continue
        ip = int(parts[0], 16)
        if base <= ip < base + size:
            libraries["the kernel"] += 1
            offsets[ip - base] += 1
        else:
            libraries[Path(parts[1].strip("()")).name] += 1
    total = sum(libraries.values())
    print(f"{total} samples")
    for name, count in libraries.most_common(8):
        print(f"{100 * count / total:6.2f}%  {name}")
    addresses = sorted(offsets)
    lines = subprocess.run(
        ["addr2line", "-i", "-f", "-C", "-a", "-e", kernel["object"], *map(hex, addresses)], capture_output=True, text=True
    ).stdout.splitlines()
    chains, current, at = {}, None, 0
    for line in lines:  # each address, then (function, file:line) pairs, innermost first
        if line.startswith("0x"):
            current, at = int(line, 16), 0
            chains[current] = []
        elif current is not None:
            if at % 2 == 0:
                chains[current].append([line, ""])
            else:
                chains[current][-1][1] = line
            at += 1
    for chain in chains.values():  # a leaf without a name (Warp's builtins) gets the symbol's, with its signature
        if len(chain) > 1 and "(" in chain[0][0]:
            chain[0][0] = "(Warp's builtins)"
        for pair in chain:
            pair[0] = _short(pair[0])
    source = Path(kernel["object"]).with_suffix("").with_suffix(".cpp").read_text().splitlines()
    own, inclusive, lines_of = collections.Counter(), collections.Counter(), collections.Counter()
    for address, count in offsets.items():
        ours = [(f, where) for f, where in chains.get(address, []) if "make_" in f or "tanh32" in f or KERNEL in f]
        own[ours[0][0] if ours else "(Warp's builtins)"] += count
        for function in {f for f, _where in ours}:
            inclusive[function] += count
        if ours:  # (the location paired with a function is the line in it that is running)
            lines_of[(ours[0][0], _python_line(source, ours[0][1]))] += count
    n = sum(offsets.values())
    lines_of = collections.Counter({f"{f}: {text}": count for (f, text), count in lines_of.items()})
    for title, counter in (
        ("self (innermost of the package's functions)", own),
        ("inclusive", inclusive),
        ("self, by the Python line before the C++ line", lines_of),
    ):
        print(f"kernel's samples, {title}:")
        for name, count in counter.most_common(top):
            print(f"{100 * count / n:6.2f}%  {name}")


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.cpu_profile", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    one = sub.add_parser("run")
    one.add_argument("--n", type=lambda s: int(float(s)), default=20_000)
    one.add_argument("--repeats", type=int, default=3)
    one.add_argument("--precision", default="float32", choices=("float32", "float64"))
    one.add_argument("--case", default="rest", choices=("rest", "terrain", "terrain-air", "plane", "plane-air"))
    one.add_argument("--set", action="append", default=[], help="KEY=VALUE, more scene settings")
    one.add_argument("--out", type=Path, required=True)
    two = sub.add_parser("report")
    two.add_argument("data")
    two.add_argument("folder", type=Path)
    args = parser.parse_args(argv)
    if args.what == "run":
        run(args.n, args.repeats, args.precision, args.set, args.out, args.case)
    else:
        report(args.data, args.folder)


if __name__ == "__main__":
    main()
