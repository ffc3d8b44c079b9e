"""Warp and its devices: Warp started quietly (its native CUDA-driver warning kept out of one-line
errors), and a device named by the user resolved or refused in one line."""

from __future__ import annotations

import logging

from .errors import RicochetError

_INIT_NOTE = ""  # what Warp's native library said while starting (e.g. why CUDA is unavailable)
_INITIALISED = False
_CUDA_MISSING = "Could not find or load the NVIDIA CUDA driver"


def warp():
    import warp as wp

    global _INIT_NOTE, _INITIALISED
    if not _INITIALISED:
        if wp.config.log_level < wp.LOG_WARNING:
            wp.config.log_level = wp.LOG_WARNING  # no banner, no per-module load lines
        _INIT_NOTE = _init_capturing_native_stderr(wp)  # a no-op init if Warp already started
        _INITIALISED = True
    return wp


def _init_capturing_native_stderr(wp) -> str:
    """wp.init(), keeping what the native library writes to stderr (on a machine without a GPU:
    a CUDA-driver warning, which would make a one-line error two lines). Anything else it says
    is passed on; the CUDA note is given with a device error when CUDA was asked for."""
    import ctypes
    import os
    import sys
    import tempfile

    try:
        libc = ctypes.CDLL(None)  # the C library's stdio, to flush its buffered warnings
        saved = os.dup(2)
    except Exception:  # e.g. Windows (no CDLL(None)): let Warp print as it likes
        wp.init()
        return ""
    text = ""
    try:
        with tempfile.TemporaryFile() as captured:
            sys.stderr.flush()
            os.dup2(captured.fileno(), 2)
            try:
                wp.init()
            finally:
                libc.fflush(None)
                os.dup2(saved, 2)
                os.close(saved)
                captured.seek(0)
                text = captured.read().decode(errors="replace").strip()
    finally:
        kept = [line for line in text.splitlines() if _CUDA_MISSING not in line]
        for line in kept:  # Warp's own notes, as warnings of this package's logger (`warp-ricochet -q` hides them)
            logging.getLogger(__name__).warning("%s", line)
    return " ".join(text.split())


def resolve_device(name=None):
    """A Warp device from "cpu", "cuda", "cuda:N" or None (CUDA if present, else CPU)."""
    wp = warp()
    if name is None:
        return wp.get_preferred_device()
    try:
        if str(name).startswith("cuda") and wp.get_cuda_device_count() == 0:
            raise LookupError  # asking Warp would print native errors first
        return wp.get_device(str(name))
    except Exception:
        allowed = ", ".join(d.alias for d in wp.get_devices())
        why = (
            f" ({_INIT_NOTE.removeprefix('Warp CUDA warning: ')})" if "cuda" in str(name) and _CUDA_MISSING in _INIT_NOTE else ""
        )
        raise RicochetError(f"device = {str(name)!r}: not available here{why}; available: {allowed}") from None
