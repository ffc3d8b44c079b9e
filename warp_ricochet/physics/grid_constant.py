"""Kernel parameters read in place on CUDA (`__grid_constant__`). In CUDA code the package's
read-only structs (the tally, surfaces, physics, source) go to `wp.func`s by reference
(`struct_refs`); a reference to a plain kernel parameter makes NVRTC copy the parameter into each
thread's local memory first (about 1 KB a thread for the tally of a hazard run, read back through
the L1 cache at each use: bench/RESULTS.md "Kernel parameters held in each thread's local memory").
Declared `__grid_constant__ const`, a parameter is read from the constant bank in place, and the
reference the functions take aliases it.

A kernel opts in by the module options of `module_options()`: a marker in the CUDA preamble, which
keys Warp's module hash (a rewritten module and a plain one never share a cache entry; the marker's
number changes with the rewrite). `install()` wraps Warp's kernel code generator once; it rewrites
only CUDA kernels whose module carries the marker, and leaves a kernel as Warp wrote it where its
body may write a parameter (`_writes_param`: a `__grid_constant__` parameter must never be written)
or where Warp's code does not have the expected shape. Functions never write the structs they take
by reference (`struct_refs`' rule; tests/test_struct_refs.py, tests/test_grid_constant.py). CPU code
is never touched. `__grid_constant__` needs CUDA 11.7+ and sm_70+."""

import functools
import re

MARK = "#define WARP_RICOCHET_GRID_CONSTANT_PARAMS 2\n"  # the CUDA preamble line that opts a module in
_SUFFIX = "__gc"


def module_options() -> dict:
    """`module_options` entries (for a `module="unique"` kernel) that opt its CUDA code in (and
    the rewrite installed, so that a module hashed as rewritten is built so)."""
    import warp as wp

    install()
    return {"extra_build_options": wp.ModuleBuildOptions(extra_cuda_preamble=MARK)}


_ARRAYS = ("wp::array_t<", "wp::indexedarray_t<", "wp::fabricarray_t<", "wp::indexedfabricarray_t<")
_COMPOUND = r"(?:<<|>>|[-+*/%&|^])?=(?!=)"  # `=` or a compound assignment, not `==`
_LINE = re.compile(r"^\s*(var_\w+)\s*=\s*(.*);\s*$", re.M)


def _writes_param(body: str, name: str, array: bool = False) -> bool:
    """Whether the generated `body` may write parameter `name`: an assignment to it or a field of
    it; a store, in-place operation or atomic through a pointer taken into it (`&(...)`,
    `wp::indexref`), followed from variable to variable; and, unless it is an array (whose
    elements are its data, not the parameter), an in-place operation or atomic on it. Errs on the
    side of a write."""
    pointers = {name}
    for _ in range(2):  # (a pointer's definition may follow its first use in a loop's code)
        for target, value in _LINE.findall(body):
            if ("&" in value or "wp::indexref(" in value) and re.search(rf"\b(?:{'|'.join(pointers)})\b", value):
                pointers.add(target)
    taken = pointers - {name} if array else pointers
    stored = re.search(rf"^\s*{re.escape(name)}\b(?:\.\w+|\[[^\]]*\])*\s*{_COMPOUND}", body, re.M)
    operated = taken and re.search(rf"wp::(?:store|\w+_inplace|atomic_\w+)\(\s*\(?\s*(?:{'|'.join(taken)})\b", body)
    return bool(stored or operated)


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
        if _writes_param(body, name, ctype.startswith(_ARRAYS)):
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
