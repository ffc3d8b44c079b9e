"""Kernel parameters read in place on CUDA (`__grid_constant__`). Warp 1.19 passes structs and
arrays to `wp.func`s by non-const reference, so NVRTC copies each such kernel parameter into every
thread's local memory before the first call: about 1 KB a thread for the tally of a hazard run,
read back through the L1 cache at each use (bench/RESULTS.md "Kernel parameters held in each
thread's local memory"). Declared `__grid_constant__ const`, a parameter is read from the constant
bank in place and the reference the functions take aliases it.

A kernel opts in by the module options of `module_options()`: a marker in the CUDA preamble, which
also keys Warp's module hash, so a rewritten module never shares a cache entry with a plain one.
`install()` wraps Warp's kernel code generator once; it rewrites only CUDA kernels whose module
carries the marker, and leaves a kernel as Warp wrote it where its body assigns to a parameter's
field (a `__grid_constant__` parameter must not be written) or where Warp's code does not have
the expected shape. CPU code is never touched. Assumes CUDA 11.7+ and sm_70+ (Warp's own floor)."""

import functools
import re

MARK = "#define WARP_RICOCHET_GRID_CONSTANT_PARAMS 1\n"  # the CUDA preamble line that opts a module in
_SUFFIX = "__gc"


def module_options() -> dict:
    """`module_options` entries (for a `module="unique"` kernel) that opt its CUDA code in."""
    import warp as wp

    return {"extra_build_options": wp.ModuleBuildOptions(extra_cuda_preamble=MARK)}


def _writes_param(body: str, name: str) -> bool:
    """Whether the generated `body` assigns to parameter `name` or a field of it."""
    return re.search(rf"\b{re.escape(name)}(?:\.\w+)*\s*(?:<<|>>|[-+*/%&|^])?=(?!=)", body) is not None


def rewrite(source: str, params: list[tuple[str, str]]) -> str:
    """`source` (one CUDA kernel's code from Warp's template) with each of `params` ((C type,
    name) pairs, as in its signature) declared `__grid_constant__ const` and aliased by a reference
    of its old name at the top of the body. Returns `source` unchanged where a parameter is written,
    the signature lacks one, or the body has no opening brace after the signature."""
    start = source.find("__global__")
    head_end = source.find(")\n{\n", start)
    if start < 0 or head_end < 0:
        return source
    head, body = source[:head_end], source[head_end + 3 :]
    aliases = []
    for ctype, name in params:
        if _writes_param(body, name):
            return source
        declared = rf"{re.escape(ctype)} {re.escape(name)}(?=,|\n|$)"
        head, found = re.subn(declared, f"__grid_constant__ const {ctype} {name}{_SUFFIX}", head)
        if found != 1:
            return source
        aliases.append(f"    {ctype}& {name} = const_cast<{ctype}&>({name}{_SUFFIX});\n")
    return head + ")\n{\n" + "".join(aliases) + body


def _rewrite_kernel(codegen_kernel):
    @functools.wraps(codegen_kernel)
    def wrapped(kernel, device, options):
        source = codegen_kernel(kernel, device=device, options=options)
        merged = options | kernel.options
        if (
            device != "cuda"
            or MARK not in merged.get("extra_cuda_preamble", "")
            or merged.get("enable_backward")
            or kernel.options.get("entry_point_abi", "warp") != "warp"
        ):
            return source
        return rewrite(source, [(arg.ctype(), "var_" + arg.label) for arg in kernel.adj.args])

    wrapped.grid_constant = True
    return wrapped


def install() -> None:
    """Wrap `warp._src.codegen.codegen_kernel` (once) so opted-in CUDA kernels read their
    parameters in place. Where Warp lacks that hook, nothing changes."""
    import warp._src.codegen as codegen

    current = getattr(codegen, "codegen_kernel", None)
    if current is None or getattr(current, "grid_constant", False):
        return
    codegen.codegen_kernel = _rewrite_kernel(current)
