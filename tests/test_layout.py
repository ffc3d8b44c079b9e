"""The package's shape (issue 11): no import cycle between its modules (imports inside functions
count), no function or class over 200 lines (a factory's nested functions count), no module over
800 lines. Read from the source with `ast` and `tokenize`, so nothing is imported. A function's
lines are counted as written before the formatter (ruff) spreads a long call or signature over
several: a line that continues an open bracket counts with the line that opened it."""

import ast
import io
import tokenize
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "warp_ricochet"
MAX_DEF_LINES, MAX_MODULE_LINES = 200, 800


def _modules():
    """{dotted module name: path} of every module of the package (a package by its __init__)."""
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def _imports(name, path, modules):
    """The package modules that module `name` imports, anywhere in it. `from P import X` imports
    module P.X when X is a module, else P (whose __init__ then counts as imported)."""
    is_package = path.name == "__init__.py"
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = name.split(".") if is_package else name.split(".")[:-1]
                anchor = anchor[: len(anchor) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            for alias in node.names:
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base)
    return {m for m in found if m in modules and m != name}


def test_no_import_cycles():
    modules = _modules()
    graph = {name: _imports(name, path, modules) for name, path in modules.items()}
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                cycle = stack[stack.index(nxt) :] + [nxt]
                raise AssertionError("import cycle: " + " -> ".join(cycle))
            if nxt not in state:
                visit(nxt)
        stack.pop()
        state[node] = "done"

    for name in sorted(graph):
        if name not in state:
            visit(name)
    assert len(graph) > 30  # (the walk saw the package)


def _bracket_continuations(text):
    """The line numbers that begin inside an open bracket (a spread call, signature or literal)."""
    inside, depth = set(), 0
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type == tokenize.OP and tok.string in "([{":
            depth += 1
        elif tok.type == tokenize.OP and tok.string in ")]}":
            depth -= 1
        elif tok.type == tokenize.NL and depth > 0:
            inside.add(tok.start[0] + 1)
    return inside


def test_bracket_continuations_count_with_their_opening_line():
    text = "def f(\n    a,\n    b,\n):\n    return g(\n        a, b\n    )\n"
    assert _bracket_continuations(text) == {2, 3, 4, 6, 7}


def test_no_function_class_or_module_too_long():
    long = []
    for path in sorted(PACKAGE.rglob("*.py")):
        text = path.read_text()
        where = path.relative_to(PACKAGE.parent)
        if text.count("\n") > MAX_MODULE_LINES:
            long.append(f"{where}: {text.count(chr(10))} lines")
        continued = _bracket_continuations(text)
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                start = min([node.lineno] + [d.lineno for d in node.decorator_list])
                lines = sum(1 for n in range(start, node.end_lineno + 1) if n not in continued)
                if lines > MAX_DEF_LINES:
                    long.append(f"{where}:{node.lineno} {node.name}: {lines} lines")
    assert not long, long
