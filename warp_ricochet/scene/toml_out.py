"""Scenes back to TOML text (what run files record)."""

from __future__ import annotations

import dataclasses
import math

from .keys import join, quote


def plain(obj):
    if dataclasses.is_dataclass(obj):
        return {f.name: plain(getattr(obj, f.name)) for f in dataclasses.fields(obj) if getattr(obj, f.name) is not None}
    return [plain(x) for x in obj] if isinstance(obj, (list, tuple)) else obj


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("nan" if v != v else "inf" if v > 0 else "-inf")
    if isinstance(v, str):
        return quote(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(map(toml_value, v)) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{join('', k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def toml_lines(d: dict, prefix: str) -> list[str]:
    def is_aot(v):
        return isinstance(v, list) and v and all(isinstance(x, dict) for x in v)

    lines = [f"{join('', k)} = {toml_value(v)}" for k, v in d.items() if not isinstance(v, dict) and not is_aot(v)]
    for k, v in d.items():
        name = join(prefix, k)
        if isinstance(v, dict):
            lines += ["", f"[{name}]", *toml_lines(v, name)]
        elif is_aot(v):
            for item in v:
                lines += ["", f"[[{name}]]", *toml_lines(item, name)]
    return lines
