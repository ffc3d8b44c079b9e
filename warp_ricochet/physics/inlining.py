"""Inlining hints for `wp.func`s in CUDA code. NVRTC inlines every call: a large function called
from several sites of the core kernel is copied at each, and the kernel's code outgrows the GPU's
instruction caches (bench/RESULTS.md "The watch as one call", "Functions out of line in air").
The CPU's compiler keeps its own choice."""

import functools

CUDA_NOINLINE = "noinline_cuda"  # the inline hint of `out_of_line_on_cuda`
_CUDA_NOINLINE_ATTR = "\n#if defined(__CUDA_ARCH__) || defined(__CUDACC_RTC__)\nWP_NOINLINE\n#endif\n"


def out_of_line_on_cuda(func, when: bool = True):
    """Declare `func` (a `wp.func`) not inlined in CUDA code where `when`, and leave the CPU's
    compiler its choice: one call instead of a copy at each of the core kernel's call sites shrinks
    its code and local memory on the GPU, while on the CPU the calls cost a few percent. Warp 1.19's
    `inline=False` applies to both; this hint is a preprocessor test in the slot warp fills from
    `warp._src.codegen._INLINE_ATTRS` (where warp lacks it: plain noinline). Returns func."""
    import warp._src.codegen as codegen

    if not when:
        return func
    attrs = getattr(codegen, "_INLINE_ATTRS", None)
    if isinstance(attrs, dict) and "noinline" in attrs:
        attrs.setdefault(CUDA_NOINLINE, _CUDA_NOINLINE_ATTR)
        func.inline_hint = CUDA_NOINLINE
    else:
        func.inline_hint = "noinline"
    return func


def out_of_line_if(when: bool):
    """A decorator: `out_of_line_on_cuda(func, when)`."""
    return functools.partial(out_of_line_on_cuda, when=when)
