"""Compile the core kernel of the bench's four configurations for sm_90 (NVRTC, no GPU) and list each
cubin's registers, local memory (spills) and stack from its ELF .nv.info / .nv.local sections."""
import sys, pathlib, struct
import warp as wp
wp.config.quiet = True
from warp_ricochet.spec import RunSpec
from warp_ricochet.core.kernel import ricochet_kernel_for
from bench.hazard import CONFIGS, scene
out = pathlib.Path(sys.argv[1])
for name, settings in CONFIGS.items():
    spec = RunSpec.of(scene(1000, settings), with_output=False)
    k = ricochet_kernel_for(spec)
    d = out / name.replace(" ", "_").replace("+", "p")
    paths = wp.compile_aot_module(k.module, arch=90, module_dir=d, use_ptx=False)
    print(name, paths, flush=True)
