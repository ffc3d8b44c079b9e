"""One-line scene errors, and the dotted keys they name."""

from __future__ import annotations

import difflib
import itertools

from ..errors import SceneError


class _Missing:
    def __repr__(self):
        return "(missing)"


class _Shown:
    """A value shown by a given one-line text (for values whose repr spans lines or fails)."""

    def __init__(self, text):
        self.text = text

    def __repr__(self):
        return self.text


MISSING = _Missing()
MAX_SHOWN_ITEMS = 8  # items of a long list or table shown in a message


def err(key: str, value, allowed: str) -> SceneError:
    """SceneError whose message is guaranteed to be one line."""
    key = key if key.isprintable() else repr(key)[1:-1]
    if isinstance(value, (list, tuple, dict)) and len(value) > MAX_SHOWN_ITEMS:  # shown cut short: no repr of it all
        items = (
            list(itertools.islice(value.items(), MAX_SHOWN_ITEMS)) if isinstance(value, dict) else list(value[:MAX_SHOWN_ITEMS])
        )
        kind = "table" if isinstance(value, dict) else "list"
        value = _Shown(f"{kind} of {len(value):,} items: {repr(items)[1:-1]}, ...")
    try:
        text = repr(value)
        ok = text.isprintable()
    except Exception:  # noqa: BLE001 - any user value must give a SceneError, even one whose repr fails
        text, ok = f"<{type(value).__name__}>", False
    if not ok:
        text = " ".join(text.split())
        value = _Shown(text if text.isprintable() else repr(text)[1:-1])
    return SceneError(key, value, " ".join(str(allowed).split()))


def quote(text: str) -> str:
    """TOML basic string."""
    esc = {'"': '\\"', "\\": "\\\\", "\n": "\\n", "\t": "\\t", "\r": "\\r", "\b": "\\b", "\f": "\\f"}
    return '"' + "".join(esc.get(c) or (f"\\u{ord(c):04x}" if ord(c) < 0x20 or ord(c) == 0x7F else c) for c in text) + '"'


def _bare(key) -> bool:
    return isinstance(key, str) and key != "" and all(c.isascii() and (c.isalnum() or c in "_-") for c in key)


def join(path: str, key) -> str:
    name = key if _bare(key) else quote(str(key))
    return f"{path}.{name}" if path else name


def suggest(key, allowed, path: str = "") -> str:
    """ "did you mean KEY? " for the allowed key closest to an unknown `key` (difflib's ratio >= 0.6), or ""."""
    if not isinstance(key, str) or len(key) > 100:  # (a long key is no typo, and the ratio costs len^2)
        return ""
    close = difflib.get_close_matches(key, [str(a) for a in allowed], n=1)
    return f"did you mean {join(path, close[0])}? " if close else ""


def check_keys(raw: dict, path: str, allowed) -> None:
    for key in raw:
        if key not in allowed:
            raise err(join(path, key), raw[key], f"unknown key; {suggest(key, allowed, path)}allowed keys: " + ", ".join(allowed))


def table(raw, path: str, schema: dict, required=()) -> dict:
    """Validated values of the keys given in table `raw` by `schema` ({key: converter}; None counts
    as absent; defaults are the dataclass's)."""
    raw = {} if raw is None else raw
    if not isinstance(raw, dict):
        raise err(path, raw, "must be a table")
    check_keys(raw, path, schema)
    out = {}
    for key, conv in schema.items():
        if raw.get(key) is not None:
            out[key] = conv(raw[key], join(path, key))
        elif key in required:
            raise err(join(path, key), MISSING, f"is required; it {conv.rule}")
    return out
