"""The example scenes installed with the package (`warp-ricochet example [NAME]`).

The TOML files of this folder are the checkout's `examples/*.toml` (links to them: one copy), shipped
as package data, so an installed package can list them, print them and write them out. Standard
library only (never warp).
"""

from __future__ import annotations

import os
from importlib import resources

from ..errors import OutputError, SceneError
from ..io.atomic import replaced

__all__ = ["examples", "example_text", "write_example"]


def _files() -> dict:
    root = resources.files(__name__)
    return {entry.name[:-5]: entry for entry in root.iterdir() if entry.name.endswith(".toml")}


def _summary(text: str) -> str:
    """The first sentence of the scene's leading comment."""
    lines = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        words = line.lstrip("#").strip()
        if words.startswith("warp-ricochet "):
            break
        lines.append(words)
    sentence = " ".join(lines).split(". ")[0].strip()
    return sentence if sentence.endswith(".") else sentence + "."


def examples() -> list[tuple[str, str]]:
    """[(name, one-sentence summary)] of every example scene, by name."""
    files = _files()
    return [(name, _summary(files[name].read_text())) for name in sorted(files)]


def example_text(name: str) -> str:
    """The TOML text of example `name` (with or without .toml); a one-line SceneError if there is none."""
    files = _files()
    key = name[:-5] if name.endswith(".toml") else name
    if key not in files:
        raise SceneError("example", name, "is not an example scene; choose one of " + ", ".join(sorted(files)))
    return files[key].read_text()


def write_example(text: str, path, overwrite: bool = False) -> None:
    """Write `text` to `path` (refused in one line if it exists and not `overwrite`, or cannot be written)."""
    path = os.fspath(path)
    if os.path.isdir(path):
        raise OutputError(f"output path = {path!r}: is a folder; give a file name such as {path}/scene.toml")
    if os.path.lexists(path) and not overwrite:
        raise OutputError(f"output path = {path!r}: exists; give --overwrite to replace it")
    try:
        with replaced(path) as tmp, open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
    except OSError as exc:
        raise OutputError(f"output path = {path!r}: cannot be written ({exc.strerror or exc})") from None
