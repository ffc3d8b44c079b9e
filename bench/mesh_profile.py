"""The paper's shot on its plane and on a two-triangle mesh of it (`bench.meshes plane`), one case
per process, for Nsight Compute and for the core kernel's registers and local memory (CUDA):

    python3 -m bench.mesh_profile --case mesh [--n 1e7] [--repeats 5]
    ncu -k regex:ricochet_kernel -c 1 --section ... python3 -m bench.mesh_profile --case mesh --repeats 0

Cases: plane, mesh, bare (the mesh with its edge and corner contacts left out, the same kernel),
rect (the plane as a rectangle plate of the mesh's size: the plates' kernel without meshes),
plane-air and mesh-air (in sea-level air, as `bench.meshes plane --flights air`),
terrain and terrain-air (`bench.meshes terrain`'s scene: 1,002,528 triangles, vacuum or sea-level air;
each run also reads the raster and builds its BVH).
Prints the kernel's registers a thread and local bytes, and the median run time. Figures: bench/RESULTS.md.
"""

import argparse
import ctypes
import tempfile
import time

import numpy as np

from bench.meshes import ROOT


def _attributes(scene):
    """(registers a thread, local bytes a thread) of the scene's core kernel (CUDA driver API)."""
    from warp_ricochet.core.kernel import ricochet_kernel_for
    from warp_ricochet.spec import RunSpec

    cuda = ctypes.CDLL("libcuda.so.1")
    import warp as wp

    kernel = ricochet_kernel_for(RunSpec.of(scene, with_output=False, device=wp.get_device("cuda:0")))  # (the build a GPU runs)
    found = []
    for ex in kernel.module.execs.values():
        hooks = ex.get_kernel_hooks(kernel)
        values = []
        for attribute in (4, 3):  # CU_FUNC_ATTRIBUTE_NUM_REGS, _LOCAL_SIZE_BYTES
            value = ctypes.c_int(0)
            cuda.cuFuncGetAttribute(ctypes.byref(value), attribute, ctypes.c_void_p(hooks.forward))
            values.append(value.value)
        found.append(tuple(values))
    return found


def _no_features(vertices, triangles):
    """`physics.mesh_edges.convex_features` of a mesh whose triangles own no edge or corner."""
    none = np.full((len(triangles), 3), -1, dtype=np.int32)
    return {"face_edges": none, "face_corners": none, "edges": np.zeros((0, 2, 3)), "corners": np.zeros((0, 3))}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--case", choices=("plane", "mesh", "bare", "rect", "plane-air", "mesh-air", "terrain", "terrain-air"), default="mesh"
    )
    parser.add_argument("--n", type=float, default=1e7)
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)

    import warp_ricochet as wr
    from warp_ricochet.device import warp
    from warp_ricochet.physics import types
    from warp_ricochet.scene import load_scene

    wp = warp()
    wp.config.lineinfo = True
    n = int(args.n)
    sets = [f"shot.count={n}", "numerics.precision=float32", "output.fields=[]"]
    folder = tempfile.mkdtemp()
    if args.case == "rect":
        sets += ['surfaces.0.kind="rectangle"', "surfaces.0.axis_u=[1.0, 0.0, 0.0]", "surfaces.0.size=[2.0e4, 2.0e4]"]
    elif args.case in ("plane-air", "mesh-air"):
        sets.append('air.drag="loth2021"')  # (an [air] table of defaults: sea-level air)
    if args.case in ("mesh", "bare", "mesh-air"):
        from bench.meshes import plane_mesh

        sets += plane_mesh(folder)
    if args.case == "bare":
        types.convex_features = _no_features
    scene = load_scene(ROOT / "examples" / "paper.toml", sets)
    if args.case.startswith("terrain"):
        from bench.meshes import _paper, terrain_raster, terrain_surfaces

        scene = _paper(n, "float32", args.case == "terrain-air", terrain_surfaces(terrain_raster(folder)))
    wr.run(scene, None, device=args.device)
    wp.synchronize_device(args.device)
    runs = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        wr.run(scene, None, device=args.device)
        wp.synchronize_device(args.device)
        runs.append(time.perf_counter() - start)
    if args.device.startswith("cuda"):
        print(f"{args.case}: registers, local bytes a thread: {_attributes(scene)}")
    if runs:
        median = float(np.median(runs))
        print(f"{args.case}: {median * 1e3:.2f} ms, {n / median:.3g} pellets/s (median of {args.repeats}, n {n:.0e})")


if __name__ == "__main__":
    main()
