"""Read-only structs passed to `@wp.func`s by reference in the generated C++/CUDA.

Warp 1.19 declares a struct argument of a `@wp.func` by value (NVIDIA/warp issue 878), so every
call of a function that takes the landing `Tally` (about 800 bytes), `Surfaces`, `Physics` or
`Source` copies the whole struct, on CUDA through local memory. `read_only(struct)` registers
such a struct and `install()` rewrites the one line of warp's `codegen_func` that declares a
function's arguments, so that in CUDA code an argument of a registered type is declared `T& var`:
the same values, read in place (CPU code keeps the copies: `by_reference`). This is only sound for structs that no function writes:
tests/test_struct_refs.py checks every `@wp.func` of the package for an assignment to a field of
such an argument. Kernels' arguments are not affected (they are declared elsewhere:
`physics.grid_constant` reads them in place, so that these references need no per-thread copy).

If warp's line is not the expected one (another warp version), nothing is changed and the code
runs as before, slower; `WARP_RICOCHET_STRUCT_REFS=0` in the environment turns it off (benchmarks
compare both, bench/RESULTS.md "Structs by reference"). The choice is made when a module is first
compiled; the kernel cache does not tell the two apart (both give the same results).
"""

from __future__ import annotations

import inspect
import logging
import os

log = logging.getLogger(__name__)

_REGISTERED: set[int] = set()  # id() of registered warp Struct types
_STATE = {"installed": None}  # None: not tried; True/False: patched or not
_LINE = '            s = f"{arg.ctype()} {arg.emit()}"\n'
_PATCH = _LINE + "            if _struct_by_reference(arg.type):\n" + '                s = f"{arg.ctype()}& {arg.emit()}"\n'


def enabled() -> bool:
    """Whether the environment allows the rewrite (`WARP_RICOCHET_STRUCT_REFS`, default on)."""
    return os.environ.get("WARP_RICOCHET_STRUCT_REFS", "1") != "0"


def by_reference(struct_type, device: str = "cuda") -> bool:
    """Whether a function argument of `struct_type` is declared by reference in code for `device`
    ("cpu" or "cuda"): registered structs in CUDA code only. On the CPU the references made clang
    compile the core kernel about 35% slower (11.8 -> 16.4 s) for no measured gain (bench/RESULTS.md)."""
    return device == "cuda" and id(struct_type) in _REGISTERED


def read_only(struct_type):
    """Register a warp struct that no `@wp.func` writes (its arguments then go by reference), and
    install the rewrite; return the struct."""
    _REGISTERED.add(id(struct_type))
    install()
    return struct_type


def install() -> bool:
    """Rewrite warp's `codegen_func` once (idempotent); True if it is in place."""
    if _STATE["installed"] is not None:
        return _STATE["installed"]
    _STATE["installed"] = False
    if not enabled():
        return False
    import warp._src.codegen as codegen

    source = inspect.getsource(codegen.codegen_func)
    if source.count(_LINE) != 1:
        log.debug("struct_refs: warp's codegen_func differs from 1.19's; structs stay by value")
        return False
    codegen._struct_by_reference = by_reference
    exec(compile(source.replace(_LINE, _PATCH), inspect.getsourcefile(codegen), "exec"), vars(codegen))  # noqa: S102
    _STATE["installed"] = True
    return True
