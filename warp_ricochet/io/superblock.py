"""The file consistency flags of an HDF5 superblock (version 2 or 3), cleared as `h5clear -s` does.

A file written with libver >= v110 (our run files, which are SWMR-capable) has superblock version 3,
whose flags byte says "open for writing / for SWMR writing" while a writer has it open. A writer that
dies without closing the file (SIGKILL, power loss) leaves the flags set, and HDF5 then refuses every
open but a SWMR read ("file is already open for write (may use <h5clear file> ...)"). The file itself
is consistent: a SWMR writer orders its metadata flushes so that the file on disk is readable at any
moment. `clear_status_flags` sets the byte to 0 and rewrites the superblock checksum (Jenkins'
lookup3, as HDF5 computes it), which is all `h5clear -s` does; `warp-ricochet run --resume` calls it,
under its lock on the file, before reopening the file to continue the run.

Layout (HDF5 file format specification, "Superblock Version 2 and 3"): signature (8 bytes),
version (1), size of offsets (1), size of lengths (1), file consistency flags (1), base address,
superblock extension address, end of file address, root group object header address (one offset
each), checksum (4, little-endian) of everything before it.
"""

from __future__ import annotations

import os

SIGNATURE = b"\x89HDF\r\n\x1a\n"
FLAGS_OFFSET = 11
_MASK = 0xFFFFFFFF


def _rot(x: int, k: int) -> int:
    return ((x << k) | (x >> (32 - k))) & _MASK


def lookup3(data: bytes, initval: int = 0) -> int:
    """Bob Jenkins' lookup3 `hashlittle`, as HDF5's H5_checksum_lookup3 (little-endian byte order)."""
    length = len(data)
    a = b = c = (0xDEADBEEF + length + initval) & _MASK
    k = 0
    while length > 12:
        a = (a + int.from_bytes(data[k : k + 4], "little")) & _MASK
        b = (b + int.from_bytes(data[k + 4 : k + 8], "little")) & _MASK
        c = (c + int.from_bytes(data[k + 8 : k + 12], "little")) & _MASK
        a = (a - c) & _MASK
        a ^= _rot(c, 4)
        c = (c + b) & _MASK
        b = (b - a) & _MASK
        b ^= _rot(a, 6)
        a = (a + c) & _MASK
        c = (c - b) & _MASK
        c ^= _rot(b, 8)
        b = (b + a) & _MASK
        a = (a - c) & _MASK
        a ^= _rot(c, 16)
        c = (c + b) & _MASK
        b = (b - a) & _MASK
        b ^= _rot(a, 19)
        a = (a + c) & _MASK
        c = (c - b) & _MASK
        c ^= _rot(b, 4)
        b = (b + a) & _MASK
        length -= 12
        k += 12
    if length == 0:
        return c
    tail = data[k : k + length] + bytes(12 - length)  # the fall-through cases: missing bytes add nothing
    a = (a + int.from_bytes(tail[0:4], "little")) & _MASK
    b = (b + int.from_bytes(tail[4:8], "little")) & _MASK
    c = (c + int.from_bytes(tail[8:12], "little")) & _MASK
    c ^= b
    c = (c - _rot(b, 14)) & _MASK
    a ^= c
    a = (a - _rot(c, 11)) & _MASK
    b ^= a
    b = (b - _rot(a, 25)) & _MASK
    c ^= b
    c = (c - _rot(b, 16)) & _MASK
    a ^= c
    a = (a - _rot(c, 4)) & _MASK
    b ^= a
    b = (b - _rot(a, 14)) & _MASK
    c ^= b
    c = (c - _rot(b, 24)) & _MASK
    return c


def _read_superblock(f):
    """(bytes of the superblock up to its checksum, stored checksum) or None if not v2/v3 at offset 0."""
    head = f.read(12)
    if len(head) < 12 or head[:8] != SIGNATURE or head[8] not in (2, 3):
        return None
    size_of_offsets = head[9]
    body = head + f.read(4 * size_of_offsets)
    checksum = f.read(4)
    if len(body) != 12 + 4 * size_of_offsets or len(checksum) != 4:
        return None
    return body, int.from_bytes(checksum, "little")


def status_flags(path) -> int | None:
    """The consistency flags byte (0: closed cleanly), or None if the superblock is not v2/v3 or damaged."""
    with open(path, "rb") as f:
        found = _read_superblock(f)
    if found is None or lookup3(found[0]) != found[1]:
        return None
    return found[0][FLAGS_OFFSET]


def clear_status_flags(path) -> bool:
    """Clear the flags left by a writer that died; True if they were set. The caller must make sure no
    process has the file open for writing. Raises ValueError if the superblock is not one we know
    (its checksum is checked before anything is written)."""
    with open(path, "r+b") as f:
        found = _read_superblock(f)
        if found is None or lookup3(found[0]) != found[1]:
            raise ValueError("no HDF5 version 2/3 superblock with a valid checksum at the start of the file")
        body = bytearray(found[0])
        if body[FLAGS_OFFSET] == 0:
            return False
        body[FLAGS_OFFSET] = 0
        f.seek(0)
        f.write(bytes(body) + lookup3(bytes(body)).to_bytes(4, "little"))
        f.flush()
        os.fsync(f.fileno())
    return True
