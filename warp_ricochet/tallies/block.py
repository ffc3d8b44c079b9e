"""Block-level aggregation of the hazard map's landings on CUDA, in shared memory.

Each CUDA thread block of the core kernel adds its map landings into a hash table in shared memory
(`SLOTS` slots, open addressing with up to `PROBES` probes): a landing's key is the flat index of
its (hazard level, map column) (`tallies.landing`). Its first slot is its cell's place on a lattice
(`lattice_multiplier`: cells closer than about sqrt(SLOTS) cells apart never share one, so a compact
cloud finds its slots at the first probe), its next ones a step set by a hash of the key (double
hashing: no clusters of probes). A slot holds a count and an energy in quanta
(the sums of its low and high 16 bits, in two uint32 words: 32-bit shared-memory atomics that no
thread waits for). At the end of the block its threads add the table's slots to the maps, one atomic per key and block
instead of one per landing: a cloud lands in a few hundred cells. A landing whose key finds no slot
in its probes, or whose energy is 2^31 quanta or more, is added to the maps at once.

Every sum is an integer sum, so the totals are the same bits however the landings are grouped:
as on the CPU, where `block_table` aggregates nothing (one thread a block) and every landing is
added directly. Assumes that every thread of a block reaches the kernel's BEGIN and END calls
(they hold `__syncthreads`): the core kernel's launch covers whole blocks.
"""

import functools

import warp as wp

SLOTS = 2048  # slots of a block's table (16 bytes each: 32 KiB of shared memory)
PROBES = 8  # slots tried for a key before its landing is added to the device arrays directly
EMPTY = -1  # the key of a free slot
SLOT_BYTES = 16  # key, count (int32) and energy (two uint32)
MAX_STATIC_SHARED = 48 * 1024  # bytes of static shared memory a CUDA block may declare
MAX_BLOCK_LANDINGS = 1 << 16  # landings a block may add: each half of an energy word then stays in 32 bits

BEGIN, ADD, END, KEY, COUNT, ENERGY, LANE, STRIDE = range(8)  # the operations of `block_table`


@functools.cache
def lattice_multiplier(slots: int = SLOTS) -> int:
    """The B of the first slot (u + B v) mod `slots` of the map cell (u, v) whose lattice of
    colliding cell offsets {(du, dv): du + B dv = 0 mod slots} has the longest shortest vector
    (Lagrange-Gauss reduction of its basis; ties: the smallest B): for SLOTS = 2048, B = 592 and no
    two cells less than 47.7 cells apart share a first slot (a cloud of ~1,800 cells in a disc)."""

    def shortest2(b: int) -> int:
        x, y = (slots, 0), (-b, 1)  # a basis of the lattice
        while True:
            if x[0] ** 2 + x[1] ** 2 > y[0] ** 2 + y[1] ** 2:
                x, y = y, x
            n = x[0] ** 2 + x[1] ** 2
            m = round((x[0] * y[0] + x[1] * y[1]) / n)
            if m == 0:
                return n
            y = (y[0] - m * x[0], y[1] - m * x[1])

    return max(range(slots), key=lambda b: (shortest2(b), -b)) if slots > 1 else 0


def first_slot_steps(slots: int = SLOTS) -> tuple[int, int]:
    """(B, L): a landing's first slot is u + B v + L level (mod `slots`), for its cell (u, v) and
    hazard level; a cell's levels lie a golden-ratio fraction of the table apart."""
    return (lattice_multiplier(slots), int(slots * 0.6180339887) | 1) if slots else (0, 0)


@functools.cache
def make_block_table(slots: int = SLOTS, probes: int = PROBES):
    """block_table(op, a, b, home) -> int64, one native function over one shared table (its operations):
    BEGIN clears the table (every thread of the block: a barrier); ADD adds one landing of key a
    (>= 0) and energy b (quanta), its first slot `home` modulo `slots`, returning 1, or 0 when no
    slot was free in `probes` or b >= 2^31; END waits for the
    block's adds (every thread: a barrier) and returns the number of slots to flush; KEY, COUNT,
    ENERGY read slot a; LANE, STRIDE: the thread's slots to flush are LANE, LANE + STRIDE, ...
    On the CPU, or with no slots or probes, nothing is aggregated: ADD returns 0, END 0 slots,
    LANE 0, STRIDE 1 (and no barrier)."""
    if slots & (slots - 1) or not 0 <= probes <= slots or slots * SLOT_BYTES > MAX_STATIC_SHARED:
        raise ValueError(
            f"slots must be 0 or a power of two of at most {MAX_STATIC_SHARED} bytes, probes in [0, slots]: {slots}, {probes}"
        )
    shift = 32 - max(slots.bit_length() - 1, 0)
    snippet = f"""
#if defined(__CUDA_ARCH__) && {int(slots > 0 and probes > 0)}
    __shared__ int table_keys[{slots}];
    __shared__ int table_counts[{slots}];
    __shared__ unsigned int table_energy_low[{slots}];  // a slot's energy: high * 2^16 + low
    __shared__ unsigned int table_energy_high[{slots}];
    if (op == {ADD}) {{
        if ((unsigned long long)b >= 0x80000000ull) return 0;  // (past 31 bits: added at once)
        unsigned int s = (unsigned int)home & {slots - 1}u, step = 0u;
        for (int p = 0; p < {probes}; ++p) {{
            int old = atomicCAS(&table_keys[s], {EMPTY}, (int)a);
            if (old == {EMPTY} || old == (int)a) {{
                atomicAdd(&table_counts[s], 1);
                // the energy's 16-bit halves summed in 32-bit words (no carries for up to
                // MAX_BLOCK_LANDINGS landings a block): atomics whose result nobody waits for
                atomicAdd(&table_energy_low[s], (unsigned int)b & 0xffffu);
                atomicAdd(&table_energy_high[s], (unsigned int)b >> 16);
                return 1;
            }}
            if (p == 0)  // the step of the next probes: odd, so they visit every slot
                step = {"1u" if shift == 32 else f"(((unsigned int)a * 2654435761u) >> {shift}) | 1u"};
            s = (s + step) & {slots - 1}u;
        }}
        return 0;
    }}
    if (op == {BEGIN}) {{
        for (int s = threadIdx.x; s < {slots}; s += blockDim.x) {{
            table_keys[s] = {EMPTY};
            table_counts[s] = 0;
            table_energy_low[s] = 0u;
            table_energy_high[s] = 0u;
        }}
        __syncthreads();
        return 0;
    }}
    if (op == {END}) {{
        __syncthreads();
        return {slots};
    }}
    if (op == {KEY}) return table_keys[a];
    if (op == {COUNT}) return table_counts[a];
    if (op == {ENERGY}) return (wp::int64)(((unsigned long long)table_energy_high[a] << 16) + table_energy_low[a]);
    if (op == {LANE}) return threadIdx.x;
    if (op == {STRIDE}) return blockDim.x;
    return 0;
#else
    return op == {STRIDE} ? 1 : 0;
#endif
"""

    @wp.func_native(snippet)
    def block_table(op: wp.int32, a: wp.int32, b: wp.int64, home: wp.int32) -> wp.int64: ...

    return block_table
