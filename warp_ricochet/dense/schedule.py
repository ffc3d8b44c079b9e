"""How shots map onto chunks and onto the core kernel's threads in runs with pair collisions.

A chunk holds whole shots; the core kernel continues them from the release in a shot-padded
layout of `shot_stride` slots per shot, so a statistics segment (a power of two) holds whole shots
or a shot whole segments, every chunk starts on a segment boundary, and the statistics do not
depend on the chunk size.
"""

from ..tallies.reduce import SEGMENT

HASH_GRID_BYTES = 48  # wp.HashGrid per point: cell, id (4 B each) and grouped key (8 B), each x2 (sort scratch) x1.5 (headroom)


def shot_stride(count: int) -> int:
    """Slots per shot: the next power of two >= count."""
    return 1 << max(0, (count - 1).bit_length())


def shot_granule(count: int) -> int:
    """The fewest shots a chunk (all but the last) is a multiple of: whole statistics segments of slots."""
    return max(1, SEGMENT // shot_stride(count))


def segments_of_shots(shots: int, count: int) -> int:
    """Statistics segments holding the slots of the first `shots` shots of `count` pellets."""
    return -(-shots * shot_stride(count) // SEGMENT)


def separation_table(count: int) -> int:
    """Cell buckets a shot of `count` pellets is separated with (`dense.separation`): a power of
    two, at least twice the pellets."""
    return 1 << max(3, (2 * count - 1).bit_length())


def dense_bytes_per_pellet(precision: str, max_neighbours: int) -> int:
    """Bytes per pellet of the dense phase's CUDA arrays (the chunk plan on a GPU), release
    outputs included: 19 vectors, 10 scalars, 12 integers (the grid's group among them), the
    neighbour list, the launch separation's chain and cell buckets (5 integers at most), and
    wp.HashGrid's per-point buffers."""
    size = 4 if precision == "float32" else 8
    return 3 * size * 19 + size * 10 + 4 * (12 + 5 + max_neighbours) + HASH_GRID_BYTES
