"""The core kernel's size on a CUDA architecture, without a GPU: registers a thread, stack frame and
spills, read off `ptxas -v` for the scenes' statistics-only kernels (float32, their fast maths), and
the bytes of machine code (the cubin's .text sections).

Warp's NVRTC writes the kernel's PTX (`wp.compile_aot_module(..., use_ptx=True)`); the CUDA toolkit's
`ptxas` assembles it with `-v` (the PTX's .version is lowered to what that ptxas reads, and NVRTC's
trailing NUL removed). The stack frame is what `cuFuncGetAttribute(CU_FUNC_ATTRIBUTE_LOCAL_SIZE_BYTES)`
reads on the device up to the driver's own additions; on the GPU a large frame (local memory) and
255 registers (one block of 256 threads an SM) are what make the rest and hazard kernels slow
(bench/RESULTS.md). Compare trees side by side: run this in each.

    python -m bench.kernel_size [--cases paper-vacuum,paper-air,turf,post,hazard,hazard-map,hazard-none,mesh,mesh-air,box,
                                         terrain,terrain-air]
                                [--arch 90] [--ptxas ptxas] [--keep DIR]
"""

import argparse
import re
import subprocess
import tempfile
import time
import tomllib
from pathlib import Path
from types import SimpleNamespace

ROOT = Path(__file__).resolve().parent.parent
CASES = {
    "paper-vacuum": "the paper's shot in vacuum to its landing",
    "paper-air": "the paper's shot in sea-level air to its landing",
    "turf": "the paper's shot in air to rest on turf",
    "post": "the hazard example's shot to rest on turf with a fence post 20 m out, no hazard",
    "hazard": "the hazard example (the reach along the path), no map and no places",
    "hazard-map": "the hazard example with its 0.5 m exposure map",
    "hazard-none": "the hazard example without its [hazard] table (what the watch adds: the difference)",
    "mesh": "the paper's shot in vacuum on a two-triangle mesh of its plane",
    "mesh-air": "the same in sea-level air",
    "box": "the paper's shot in vacuum on its plane with bench.meshes' box on it (convex edges and corners)",
    "terrain": "the paper's shot in vacuum over a terrain (bench.meshes: a large mesh without edges) and a plane",
    "terrain-air": "the same in sea-level air",
}


def scene_of(case: str, folder: Path):
    """The Scene of a case (CASES), statistics only (a mesh's file written in `folder`)."""
    from bench.air import paper_scene
    from warp_ricochet.scene import scene_from_dict

    if case in ("paper-vacuum", "paper-air", "turf", "mesh", "mesh-air"):
        extra = ['physics.until="rest"', 'surfaces.0.material="turf"'] if case == "turf" else []
        if case.startswith("mesh"):
            from bench.meshes import plane_mesh

            extra = plane_mesh(folder)
        return paper_scene(1000, air=case in ("paper-air", "turf", "mesh-air"), mu_s=0.5, extra=extra)
    if case in ("box", "terrain", "terrain-air"):
        from bench.meshes import BOX, MATERIAL, _paper, terrain_raster, terrain_surfaces

        if case == "box":
            plane = tomllib.loads((ROOT / "examples" / "paper.toml").read_text())["surfaces"]
            return _paper(1000, "float32", False, plane + [{"kind": "box", **BOX, **MATERIAL}])
        surfaces = terrain_surfaces(terrain_raster(folder, 16), 16)  # (its code: any size)
        return _paper(1000, "float32", case == "terrain-air", surfaces)
    if case == "post":
        from bench.meshes import hazard_shot

        return scene_from_dict(hazard_shot(4 * 280, True))
    raw = tomllib.loads((ROOT / "examples" / "hazard.toml").read_text())
    raw["shot"]["shots"] = 4
    raw["output"] = {"fields": []}
    if case == "hazard-none":
        raw.pop("hazard")
    elif case == "hazard":
        raw["hazard"].pop("map_cell")
        raw["hazard"].pop("map_extent")
        raw["hazard"].pop("points")
    return scene_from_dict(raw)


def size_of(case: str, arch: int, ptxas: str, folder: Path) -> dict:
    """{registers, stack, spill_stores, spill_loads, code, seconds} of the case's core kernel."""
    import warp as wp

    from warp_ricochet.core.kernel import ricochet_kernel_for
    from warp_ricochet.spec import RunSpec

    gpu = SimpleNamespace(is_cuda=True)  # (the build a GPU runs: a run to rest that watches its path records it)
    kernel = ricochet_kernel_for(RunSpec.of(scene_of(case, folder), with_output=False, device=gpu))
    start = time.perf_counter()
    (ptx,) = wp.compile_aot_module(kernel.module, arch=arch, module_dir=folder, use_ptx=True)
    text = ptx.read_text().replace("\0", "")
    found = {}
    for version in ("9.0", "8.8", "8.5"):  # the highest this ptxas reads
        source = folder / f"{case}.ptx"
        source.write_text(re.sub(r"^\.version \d+\.\d+", f".version {version}", text, count=1, flags=re.M))
        done = subprocess.run([ptxas, "-v", f"-arch=sm_{arch}", str(source), "-o", str(folder / f"{case}.cubin")], capture_output=True, text=True)  # fmt: skip
        if done.returncode == 0:
            found = _entry(done.stderr)
            found["code"] = code_bytes(folder / f"{case}.cubin")
            break
    found["seconds"] = time.perf_counter() - start
    return found


def code_bytes(cubin: Path) -> int:
    """Bytes of machine code in a cubin: the sizes of its ELF64 sections named .text.*."""
    import struct

    data = cubin.read_bytes()
    (shoff,) = struct.unpack_from("<Q", data, 0x28)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x3A)
    headers = [struct.unpack_from("<IIQQQQIIQQ", data, shoff + i * shentsize) for i in range(shnum)]
    names = headers[shstrndx][4]
    total = 0
    for name, _type, _flags, _addr, _offset, size, *_rest in headers:
        label = data[names + name : data.index(b"\0", names + name)]
        if label.startswith(b".text."):
            total += size
    return total


def _entry(log: str) -> dict:
    """The kernel entry's registers, stack frame and spills from `ptxas -v`'s log."""
    lines = log.splitlines()
    at = next(i for i, line in enumerate(lines) if "Compiling entry function" in line and "_cuda_kernel_forward" in line)
    frame = re.search(
        r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads", "\n".join(lines[at : at + 4])
    )
    used = re.search(r"Used (\d+) registers(.*?(\d+) bytes cumulative stack size)?", "\n".join(lines[at : at + 5]))
    return {
        "registers": int(used.group(1)),
        "stack": int(used.group(3) or 0),
        "frame": int(frame.group(1)),
        "spill_stores": int(frame.group(2)),
        "spill_loads": int(frame.group(3)),
    }


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.kernel_size", description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", default=",".join(CASES))
    parser.add_argument("--arch", type=int, default=90)
    parser.add_argument("--ptxas", default="ptxas")
    parser.add_argument("--keep", default=None, help="a folder for the sources, PTX and cubins (a temporary one)")
    args = parser.parse_args(argv)
    import warp as wp

    wp.config.quiet = True
    wp.init()
    for case in args.cases.split(","):
        if case not in CASES:
            raise SystemExit(f"--cases: {case!r} is not a case; allowed: {', '.join(CASES)}")
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(args.keep or scratch)
        folder.mkdir(parents=True, exist_ok=True)
        print(f"sm_{args.arch}, float32, statistics only; ptxas -v of the core kernel's entry")
        for case in args.cases.split(","):
            s = size_of(case, args.arch, args.ptxas, folder)
            if "registers" not in s:
                print(f"  {case}: ptxas could not read the PTX")
                continue
            print(
                f"  {case:12s} {s['registers']:4d} registers, {s['stack']:6,d} bytes stack ({s['frame']:,d} frame),"
                f" spills {s['spill_stores']:,d} / {s['spill_loads']:,d} bytes stored / loaded,"
                f" {s['code']:,d} bytes of code  [{s['seconds']:.0f} s]"
                f"  {CASES[case]}"
            )


if __name__ == "__main__":
    main()
