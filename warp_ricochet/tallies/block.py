"""Block-level aggregation of the hazard map's landings on CUDA, in shared memory.

Each CUDA thread block of the core kernel adds its map landings into a hash table in shared memory
(`SLOTS` slots, open addressing with `PROBES` linear probes): a landing's key is the flat index of
its (hazard level, map column) (`tallies.landing`), a slot holds a count and an energy in quanta
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
def make_block_table(slots: int = SLOTS, probes: int = PROBES):
    """block_table(op, a, b) -> int64, one native function over one shared table (its operations):
    BEGIN clears the table (every thread of the block: a barrier); ADD adds one landing of key a
    (>= 0) and energy b (quanta), returning 1, or 0 when no slot was free or b >= 2^31; END waits for the
    block's adds (every thread: a barrier) and returns the number of slots to flush; KEY, COUNT,
    ENERGY read slot a; LANE, STRIDE: the thread's slots to flush are LANE, LANE + STRIDE, ...
    On the CPU, or with no slots or probes, nothing is aggregated: ADD returns 0, END 0 slots,
    LANE 0, STRIDE 1 (and no barrier)."""
    if slots & (slots - 1) or not 0 <= probes <= slots or slots * SLOT_BYTES > MAX_STATIC_SHARED:
        raise ValueError(f"slots must be 0 or a power of two of at most {MAX_STATIC_SHARED} bytes, probes in "
                         f"[0, slots]: {slots}, {probes}")
    shift = 32 - max(slots.bit_length() - 1, 0)
    snippet = f"""
#if defined(__CUDA_ARCH__) && {int(slots > 0 and probes > 0)}
    __shared__ int table_keys[{slots}];
    __shared__ int table_counts[{slots}];
    __shared__ unsigned int table_energy_low[{slots}];  // a slot's energy: high * 2^16 + low
    __shared__ unsigned int table_energy_high[{slots}];
    if (op == {ADD}) {{
        if ((unsigned long long)b >= 0x80000000ull) return 0;  // (past 31 bits: added at once)
        unsigned int h = {"0u" if shift == 32 else f"((unsigned int)a * 2654435761u) >> {shift}"};
        for (int p = 0; p < {probes}; ++p) {{
            int s = (int)((h + (unsigned int)p) & {slots - 1}u);
            int old = atomicCAS(&table_keys[s], {EMPTY}, (int)a);
            if (old == {EMPTY} || old == (int)a) {{
                atomicAdd(&table_counts[s], 1);
                // the energy's 16-bit halves summed in 32-bit words (no carries for up to
                // MAX_BLOCK_LANDINGS landings a block): atomics whose result nobody waits for
                atomicAdd(&table_energy_low[s], (unsigned int)b & 0xffffu);
                atomicAdd(&table_energy_high[s], (unsigned int)b >> 16);
                return 1;
            }}
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
    def block_table(op: wp.int32, a: wp.int32, b: wp.int64) -> wp.int64: ...

    return block_table
