"""The structs passed to `@wp.func`s by reference (`warp_ricochet.struct_refs`) are never written by
a function, so by reference and by value give the same results."""

import ast
import re
from pathlib import Path

import numpy as np
import pytest

import warp_ricochet
from warp_ricochet import struct_refs

PACKAGE = Path(warp_ricochet.__file__).parent
READ_ONLY = {"Surfaces", "Physics", "Tally", "Source"}  # the names the registered structs go by


def _is_wp_func(decorator) -> bool:
    target = decorator.func if isinstance(decorator, ast.Call) else decorator
    return isinstance(target, ast.Attribute) and target.attr == "func"


def _value_fields() -> set[str]:
    """The fields of the registered structs that are not arrays (a vector, a matrix, a nested struct,
    a number): an element of one of them is part of the struct."""
    import warp as wp

    from warp_ricochet.launch.source import make_source
    from warp_ricochet.physics.types import types_for
    from warp_ricochet.tallies.landing import make_landing_tally

    t = types_for("float32")
    structs = (t.Surfaces, t.Physics, make_landing_tally("float32").Tally, make_source("float32", False).Source)
    return {name for s in structs for name, var in s.vars.items() if not wp.types.is_array(var.type)}


VALUE_FIELDS = _value_fields()


def _root(node):
    """The name a target like `a.b.c` or `a.b[i]` hangs from, and whether it passes a subscript of
    an array (whose element is not the struct's: `a.arr[i]`, not `a.vec[i]`)."""
    subscripted = False
    while isinstance(node, ast.Attribute | ast.Subscript):
        if isinstance(node, ast.Subscript):
            subscripted |= not (isinstance(node.value, ast.Attribute) and node.value.attr in VALUE_FIELDS)
        node = node.value
    return (node.id if isinstance(node, ast.Name) else None), subscripted


def writes_to_read_only(source: str):
    """(function, line) of every assignment to a field of a read-only struct argument in a @wp.func
    (an element of one of its arrays may be written: that is not the struct)."""
    found = []
    for fn in ast.walk(ast.parse(source)):
        if not isinstance(fn, ast.FunctionDef) or not any(_is_wp_func(d) for d in fn.decorator_list):
            continue
        names = {a.arg for a in fn.args.args if isinstance(a.annotation, ast.Name) and a.annotation.id in READ_ONLY}
        for node in ast.walk(fn):
            targets = (
                node.targets
                if isinstance(node, ast.Assign)
                else [node.target]
                if isinstance(node, ast.AugAssign | ast.AnnAssign)
                else []
            )
            for target in targets:
                for leaf in ast.walk(target) if isinstance(target, ast.Tuple) else [target]:
                    if isinstance(leaf, ast.Attribute | ast.Subscript):
                        root, subscripted = _root(leaf)
                        if root in names and not subscripted:
                            found.append((fn.name, leaf.lineno))
    return found


def test_no_function_writes_a_read_only_struct():
    found = {str(p.relative_to(PACKAGE)): w for p in sorted(PACKAGE.rglob("*.py")) if (w := writes_to_read_only(p.read_text()))}
    assert found == {}


def test_the_check_finds_a_write():
    source = (
        "@wp.func\ndef f(tally: Tally, x: float):\n    tally.hist[0] = 1\n    tally.shooter = x\n"
        "@wp.func\ndef g(s: Surfaces):\n    a, s.count = 1, 2\n"
        "@wp.func\ndef h(tally: Tally):\n    tally.shooter[0] = 1.0\n    tally.steps[0] = 1\n"
    )
    assert writes_to_read_only(source) == [("f", 4), ("g", 7), ("h", 10)]  # (not an element of an array)


def test_registered_structs_are_passed_by_reference():
    from warp_ricochet.launch.source import make_source
    from warp_ricochet.physics.types import types_for
    from warp_ricochet.tallies.landing import make_landing_tally

    t = types_for("float32")
    structs = (t.Surfaces, t.Physics, make_landing_tally("float32").Tally, make_source("float32", False).Source)
    assert all(struct_refs.by_reference(s, "cuda") for s in structs)
    assert not struct_refs.by_reference(t.Air, "cuda")
    assert not any(struct_refs.by_reference(s, "cpu") for s in structs)
    if not struct_refs.enabled():
        pytest.skip("WARP_RICOCHET_STRUCT_REFS=0")
    assert struct_refs.install()  # warp 1.19's line is found


def test_a_function_reads_a_struct_by_reference_and_changes_nothing():
    import warp as wp

    from warp_ricochet.physics.types import types_for
    from warp_ricochet.tallies.landing import make_landing_tally

    t = types_for("float64")
    Tally, horizontal_distance = make_landing_tally("float64").Tally, make_landing_tally("float64").horizontal_distance
    tally = Tally()
    tally.shooter = t.vec3(1.0, 2.0, 3.0)
    tally.up = t.vec3(0.0, 1.0, 0.0)

    @wp.kernel
    def distances(tally: Tally, x: wp.array(dtype=wp.vec3d), out: wp.array(dtype=wp.float64)):
        i = wp.tid()
        out[i] = horizontal_distance(tally, x[i])

    x = np.array([[4.0, 7.0, 7.0], [1.0, -5.0, 3.0]])
    out = wp.zeros(2, dtype=wp.float64, device="cpu")
    wp.launch(distances, dim=2, inputs=[tally, wp.array(x, dtype=wp.vec3d, device="cpu"), out], device="cpu")
    assert out.numpy().tolist() == [5.0, 0.0]
    if struct_refs.install():  # CUDA code takes its Tally by reference, CPU code by value
        from warp._src.context import ModuleBuilder

        module = distances.module
        assert re.search(r"Tally_\w+& var_tally", ModuleBuilder(module, module.options).codegen("cuda"))
        assert re.search(r"Tally_\w+ var_tally", ModuleBuilder(module, module.options).codegen("cpu"))
