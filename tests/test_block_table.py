"""The block tables of the landing counts (`tallies.block`): synthetic landings counted through
`add_landing` with the default table, with a table too small for them (most landings fall back
to the device arrays) and with none give the same counts, and those are NumPy's. On the CPU
nothing is aggregated; on CUDA this is the shared-memory path."""

import math

import numpy as np
import pytest
import warp as wp

from warp_ricochet.core.kernel import CUDA_BLOCK_DIM, SMALL_SOLIDS_BLOCK_DIM
from warp_ricochet.tallies import bins, counts
from warp_ricochet.tallies.block import BEGIN, PROBES, SLOTS
from warp_ricochet.tallies.counts import DeviceTally, TallySetup
from warp_ricochet.tallies.landing import make_add_landing, make_landing_tally
from warp_ricochet.tallies.reduce import LANES

PER_THREAD = 4
CELL, NU, NV = 0.5, 64, 8  # the map: cells of 0.5 m, u in [10, 42) m, v in [-2, 2) m
U0, V0 = 10.0, -2.0
HALF_MASS = 0.5 * 2.0e-3
QUANTUM = 1e-6  # J: up to 6e7 quanta a landing (both 16-bit halves in use)
SPEED_THRESHOLDS = (150.0, 200.0)  # m/s


def _setup(quantum=QUANTUM):
    return TallySetup(
        names=("slow", "fast"),
        kinds=("speed", "speed"),
        values=SPEED_THRESHOLDS,
        thresholds2=tuple(v * v for v in SPEED_THRESHOLDS),
        shooter=(0.0, 0.0, 0.0),
        up=(0.0, 0.0, 1.0),
        half_mass=HALF_MASS,
        area=1e-5,
        fractions=(),
        map_surface=0,
        map_origin=(0.0, 0.0, 0.0),
        map_u=(1.0, 0.0, 0.0),
        map_v=(0.0, 0.0, 1.0),
        map_u0=U0,
        map_v0=V0,
        map_cell=CELL,
        map_nu=NU,
        map_nv=NV,
        quantum=quantum,
    )


@pytest.fixture(scope="module")
def landings():
    """A narrow cloud (most landings in a few bins and cells) and a wide one, all float32 values
    whose float32 arithmetic in the kernel is exact (`up` along z: the distance is |x|; cells of 2^-1 m)."""
    rng = np.random.default_rng(15)
    n = 40_000
    x = np.concatenate([rng.normal(25.0, 2.0, n - n // 8), rng.uniform(0.0, 60.0, n // 8)])
    z = np.concatenate([rng.normal(0.0, 0.5, n - n // 8), rng.uniform(-3.0, 3.0, n // 8)])
    position = np.stack([x, np.zeros(n), z], axis=1).astype(np.float32)
    speed = rng.uniform(100.0, 250.0, n).astype(np.float32)
    surface = np.where(rng.random(n) < 0.02, 1, 0).astype(np.int32)  # a few land on another surface
    return {"range": np.abs(x).astype(np.float32), "position": position, "v2": speed * speed, "surface": surface}


def _count(landings, device, slots, probes, totals=True, quantum=QUANTUM):
    setup = _setup(quantum)
    fns = make_add_landing("float32", True, len(SPEED_THRESHOLDS), slots, probes)
    Tally = make_landing_tally("float32").Tally

    @wp.kernel(module="unique", enable_backward=False)
    def count(
        tally: Tally,
        ranges: wp.array(dtype=wp.float32),
        positions: wp.array(dtype=wp.vec3f),
        v2s: wp.array(dtype=wp.float32),
        surfaces: wp.array(dtype=wp.int32),
        n: wp.int32,
    ):
        tid = wp.tid()
        fns.table(BEGIN, 0, wp.int64(0), 0)  # (with a map)
        for j in range(PER_THREAD):
            row = tid * PER_THREAD + j
            if row < n:
                mask = fns.exceeded(tally, v2s[row])
                fns.add_landing(tally, row, surfaces[row], ranges[row], positions[row], v2s[row], mask)
        fns.flush(tally)

    n = len(landings["range"])
    tally = DeviceTally(setup, "float32", wp.get_device(device), active=True)
    tally.start(None)
    threads = -(-n // (PER_THREAD * CUDA_BLOCK_DIM)) * CUDA_BLOCK_DIM  # whole blocks (the tables' barriers)
    arrays = [
        wp.array(landings[k], dtype=t, device=device)
        for k, t in (("range", wp.float32), ("position", wp.vec3f), ("v2", wp.float32), ("surface", wp.int32))
    ]
    for _chunk in range(2):  # two chunks of the same landings: the totals hold twice the counts
        tally.before_chunk()
        wp.launch(count, dim=threads, inputs=[tally.struct, *arrays, n], device=device, block_dim=CUDA_BLOCK_DIM)
        tally.fold(n, last=True)
    assert not any(arr.numpy().any() for arr in tally.counts.values())  # a fold leaves the counts zero
    return {name: arr.numpy() for name, arr in tally.totals.items()} if totals else tally


def _reference(landings, quantum=QUANTUM):
    """The counts by NumPy: bins and cells in float64 from the float32 values (exact for these
    landings), energies in float32 as the kernel's."""
    r, p, v2, surface = (landings[k] for k in ("range", "position", "v2", "surface"))
    level = sum((v2 >= np.float32(t * t)).astype(int) for t in SPEED_THRESHOLDS)
    reach = len(SPEED_THRESHOLDS)  # the rows of the reach along the path (`tallies.path`): none counted here
    hist = np.zeros((bins.ROW_DISTANCE + 3 + reach, bins.BINS), dtype=np.int64)
    np.add.at(hist, (bins.ROW_RANGE, bins.bin_index(r)), 1)
    np.add.at(hist, (bins.ROW_SPEED, bins.bin_index(np.sqrt(v2))), 1)
    np.add.at(hist, (bins.ROW_DISTANCE + level, bins.bin_index(np.abs(p[:, 0]))), 1)
    fu = (p[:, 0].astype(np.float64) - U0) / CELL
    fv = (p[:, 2].astype(np.float64) - V0) / CELL
    inside = (fu >= 0) & (fv >= 0) & (fu < NU) & (fv < NV)
    column = np.where(inside, np.floor(fv).clip(0, NV - 1).astype(int) * NU + np.floor(fu).clip(0, NU - 1).astype(int), NU * NV)
    column = np.where(surface == 0, column, NU * NV + 1)
    counts = np.zeros((3, NU * NV + 2), dtype=np.int64)
    np.add.at(counts, (level, column), 1)
    quanta = np.float32(HALF_MASS / quantum) * v2  # float32, as the kernel (`energy_quanta`)
    energy = np.floor(quanta.astype(np.float64) + 0.5).astype(np.int64)  # (exact: halves away from zero)
    map_energy = np.zeros(NU * NV + 2, dtype=np.int64)
    np.add.at(map_energy, column, energy)
    return {"hist": hist, "map_counts": counts, "map_energy": map_energy}


def test_launches_of_the_core_kernel_cover_whole_blocks():
    from warp_ricochet.tallies.block import MAX_BLOCK_LANDINGS
    from warp_ricochet.tallies.reduce import PER_THREAD as CORE_PER_THREAD

    assert LANES % CUDA_BLOCK_DIM == 0  # threads_for() gives whole LANES groups
    assert LANES % SMALL_SOLIDS_BLOCK_DIM == 0  # (in whole blocks of either size: `core.kernel.block_dim_for`)
    assert CUDA_BLOCK_DIM * CORE_PER_THREAD <= MAX_BLOCK_LANDINGS  # a table's energy words cannot overflow


@pytest.mark.parametrize("quantum", [QUANTUM, 1e-9])  # 1e-9 J: past 2^31 quanta a landing, added at once
def test_block_tables_count_what_numpy_counts(landings, device, quantum):
    expected = _reference(landings, quantum)
    assert expected["map_counts"][:, : NU * NV].sum() > 0.8 * len(landings["range"])
    assert expected["map_counts"][:, NU * NV].sum() > 0 and expected["map_counts"][:, NU * NV + 1].sum() > 0
    for slots, probes in ((SLOTS, PROBES), (16, 2), (0, 0)):  # default, mostly overflowing, none
        got = _count(landings, device, slots, probes, quantum=quantum)
        for name in ("hist", "map_counts", "map_energy"):
            np.testing.assert_array_equal(
                got[name].reshape(expected[name].shape), 2 * expected[name], err_msg=f"{name}, {slots} slots, {probes} probes"
            )


def test_counts_over_the_whole_span_of_the_bins_and_past_it(device):
    """Values over every octave of the bins and past them (zero, inf, NaN, v^2 past float32): the
    kernels' counts are NumPy's, bin by bin."""
    rng = np.random.default_rng(3)
    n = 4096
    wide = np.concatenate([10.0 ** rng.uniform(-14, 14, n - 4), [0.0, np.inf, np.nan, 3e38]]).astype(np.float32)
    speed = np.abs(rng.permutation(wide))
    position = np.stack([rng.permutation(wide), np.zeros(n), np.zeros(n)], axis=1).astype(np.float32)
    with np.errstate(over="ignore"):  # (v^2 past float32: inf, as in the kernel)
        v2 = (speed * speed).astype(np.float32)
    landings = {"range": wide, "position": position, "v2": v2, "surface": np.zeros(n, dtype=np.int32)}
    with np.errstate(invalid="ignore"):  # (cells and energies of inf and NaN: not checked here)
        expected = _reference(landings)["hist"]
    assert len(np.unique(np.nonzero(expected[bins.ROW_RANGE])[0] >> bins.MANTISSA_BITS)) > 40  # octaves
    got = _count(landings, device, SLOTS, PROBES)["hist"]
    np.testing.assert_array_equal(got.reshape(expected.shape), 2 * expected)


def test_histogram_counts_wait_unfolded_until_read_or_near_int32(landings, device, monkeypatch):
    tally = _count(landings, device, SLOTS, PROBES, totals=False)  # (folded: every count zero)
    n = len(landings["range"])
    monkeypatch.setattr(counts, "FOLD_LIMIT", 2 * n)
    tally.start(None)
    hist = tally.counts["hist"]
    for chunk, expect_folded in ((1, False), (2, True), (3, False), (4, True)):  # once one more chunk could pass 2n, and last
        hist.fill_(1)  # (stands for the chunk's counts)
        tally.fold(n, last=chunk == 4)
        assert (not hist.numpy().any()) == expect_folded, chunk
    assert tally.totals["hist"].numpy().tolist() == [2 * tally.copies] * tally.totals["hist"].size


@pytest.mark.parametrize("capacity", [counts.SPARSE_CAPACITY, 7])
def test_the_host_fetches_the_device_totals_sparse_or_dense(landings, device, monkeypatch, capacity):
    monkeypatch.setattr(counts, "SPARSE_CAPACITY", capacity)  # 7: fewer than the nonzero totals, so dense
    tally = _count(landings, device, SLOTS, PROBES, totals=False)
    host = counts.TallyTotals(tally.setup)
    host.map_counts[...] = 1  # (replaced, not added to)
    tally.request()
    tally.receive(host)
    for name, arr in tally.totals.items():
        if name == "rest":  # (the rest distances' histogram: none without physics.until = "rest")
            assert arr.size == 0
            continue
        if name in ("exposure", "places"):  # (the path's passes and places: none counted by this kernel)
            assert not arr.numpy().any()
            continue
        assert np.count_nonzero(arr.numpy()) > 7
        np.testing.assert_array_equal(getattr(host, name).reshape(-1), arr.numpy(), err_msg=name)


def test_a_table_size_must_be_a_power_of_two():
    from warp_ricochet.tallies.block import make_block_table

    for slots, probes in ((12, 2), (16, 17), (16, -1), (4096, 8)):  # 4096 slots: 64 KiB, past static shared memory
        with pytest.raises(ValueError, match="power of two"):
            make_block_table(slots, probes)
    assert math.log2(SLOTS).is_integer()


def test_a_tally_holds_every_threshold_a_scene_may_set():
    from warp_ricochet.scene.schema import MAX_THRESHOLDS
    from warp_ricochet.tallies.landing import MAX_THRESHOLDS as HELD

    assert MAX_THRESHOLDS <= HELD
    with pytest.raises(ValueError, match="thresholds"):
        make_add_landing("float32", False, HELD + 1)


@pytest.mark.parametrize("slots", [16, 256, SLOTS])
def test_the_lattice_of_first_slots_keeps_nearby_cells_apart(slots):
    """Brute force over the cell offsets: no two cells closer than the lattice's shortest vector
    share a first slot, and no multiplier B has a longer shortest vector."""
    from warp_ricochet.tallies.block import first_slot_steps, lattice_multiplier

    reach = int(2 * math.sqrt(slots)) + 2  # (a lattice of covolume `slots` has a vector shorter than this)
    du, dv = np.meshgrid(np.arange(-reach, reach + 1), np.arange(0, reach + 1))
    keep = (dv > 0) | (du > 0)
    du, dv, norm2 = du[keep], dv[keep], (du * du + dv * dv)[keep]

    def shortest2(b):
        return norm2[(du + b * dv) % slots == 0].min()

    b = lattice_multiplier(slots)
    assert first_slot_steps(slots)[0] == b and first_slot_steps(slots)[1] % 2 == 1
    assert shortest2(b) == max(shortest2(c) for c in range(slots))
    assert shortest2(b) >= 0.85 * 2 * slots / math.sqrt(3)  # near the hexagonal lattice's (the densest packing)
    if slots == SLOTS:
        assert math.sqrt(shortest2(b)) > 47.0
