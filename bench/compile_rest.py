"""Compile the core kernel of the paper's scene in air followed to rest on turf (float32,
`fast_math` on as in examples/paper.toml, statistics only) for a CUDA architecture, ahead of time
(`wp.compile_aot_module`), without a GPU: a check that the surface motion's code compiles for the
device (docs/ground.md 9).

    python -m bench.compile_rest [--arch 90] [--material turf] [--out DIR]
"""

import argparse
import tempfile
import time


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.compile_rest", description=__doc__.split("\n\n")[0])
    parser.add_argument("--arch", type=int, default=90)
    parser.add_argument("--material", default="turf")
    parser.add_argument("--out", default=None, help="where the source and the compiled module go (a temporary folder)")
    args = parser.parse_args(argv)
    import warp as wp

    from bench.air import paper_scene
    from warp_ricochet.core.kernel import ricochet_kernel_for
    from warp_ricochet.spec import RunSpec

    wp.config.quiet = True
    wp.init()
    extra = ['physics.until="rest"', f'surfaces.0.material="{args.material}"']
    scene = paper_scene(1000, air=True, mu_s=0.5, extra=extra)
    spec = RunSpec.of(scene, with_output=False)
    assert spec.fast_math and spec.to_rest, (spec.fast_math, spec.to_rest)
    kernel = ricochet_kernel_for(spec)
    out = args.out or tempfile.mkdtemp(prefix="compile-rest-")
    start = time.perf_counter()
    paths = wp.compile_aot_module(kernel.module, arch=args.arch, module_dir=out)
    print(f"compiled sm_{args.arch} (fast_math) in {time.perf_counter() - start:.1f} s: {', '.join(map(str, paths))}")


if __name__ == "__main__":
    main()
