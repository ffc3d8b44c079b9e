"""Rules for the package's Warp code that Warp itself does not enforce (read with `ast`, nothing
imported from the package).

Warp 1.19 binds the targets of a tuple assignment to the right-hand side's own symbols: after
`at, n = lo, 0` the names `at` and `lo` are one C++ variable. Where both are then carried by a
loop, each iteration's write-back of one overwrites the other, silently (bench/RESULTS.md, session
57: an Illinois iteration that never moved its bracket). `x if FLAG else y` with a condition known
at code generation is that branch's own symbol in the same way. A plain `at = lo` copies. So Warp
code never tuple-assigns a bare name, nor writes a conditional expression with a bare name as a
branch."""

import ast
from pathlib import Path

import numpy as np
import warp as wp

PACKAGE = Path(__file__).resolve().parents[1] / "warp_ricochet"


def _warp_functions(tree):
    """The functions decorated as Warp code (`wp.func`, `wp.kernel`, with or without arguments)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef):
            names = [ast.unparse(d.func if isinstance(d, ast.Call) else d) for d in node.decorator_list]
            if any(name in ("wp.func", "wp.kernel", "wp.func_native") for name in names):
                yield node


def _aliasing_assignments(source):
    """(line, text) of each tuple assignment in Warp code with a bare name on its right, and of each
    conditional expression with a bare name as a branch."""
    found = []
    for fn in _warp_functions(ast.parse(source)):
        for node in ast.walk(fn):
            if isinstance(node, ast.Assign) and any(isinstance(t, ast.Tuple) for t in node.targets):
                if isinstance(node.value, ast.Tuple) and any(isinstance(e, ast.Name) for e in node.value.elts):
                    found.append((node.lineno, ast.unparse(node)))
            elif isinstance(node, ast.IfExp) and (isinstance(node.body, ast.Name) or isinstance(node.orelse, ast.Name)):
                found.append((node.lineno, ast.unparse(node)))
    return found


def test_warp_code_never_tuple_assigns_a_bare_name():
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        found += [f"{path.relative_to(PACKAGE.parent)}:{line}: {text}" for line, text in _aliasing_assignments(path.read_text())]
    assert not found, found


def test_the_rule_sees_the_hazards_and_passes_their_remedies():
    hazard = "@wp.func\ndef f(lo: float):\n    at, n = lo, 0\n    x = lo if FLAG else 0.0\n    return at\n"
    remedy = "@wp.func\ndef f(lo: float):\n    at = lo\n    n = 0\n    x, y = lo + 0.0, 1\n    z = wp.where(FLAG, lo, 0.0)\n    return at\n"
    assert [line for line, _text in _aliasing_assignments(hazard)] == [3, 4]
    assert _aliasing_assignments(remedy) == []


@wp.kernel
def _carried(out: wp.array(dtype=wp.float32)):
    lo = wp.float32(0.0)
    at = lo  # (a copy: the remedy)
    n = wp.int32(0)
    while n < 3:
        lo = lo + wp.float32(1.0)
        at = at + wp.float32(10.0)
        n += 1
    out[0] = lo
    out[1] = at


def test_a_plainly_assigned_copy_is_carried_by_a_loop_apart_from_its_source(device):
    out = wp.zeros(2, dtype=wp.float32, device=device)
    wp.launch(_carried, 1, outputs=[out], device=device)
    assert np.array_equal(out.numpy(), [3.0, 30.0])
