"""Landing quantiles and tail fractions from the on-device histograms (issue 15, section 1): against
NumPy's exact sample quantiles of the per-pellet data, counts summing to the pellets landed, and
bitwise invariance to the chunk size and to --resume."""

import dataclasses

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import warp_ricochet as wr
from tests.helpers import assert_same_run, interrupt_after, make_scene, paper_raw
from warp_ricochet.tallies import bins
from warp_ricochet.tallies.quantiles import LEVELS, quantiles, rank, tail

SLACK = 2.0**-22  # float64 values are binned as float32: a value may round across an edge


def _within(true, value, lower, name):
    ok = (true >= lower * (1 - SLACK)) & (true <= value * (1 + SLACK))
    assert ok.all(), (name, true[~ok], lower[~ok], value[~ok])


def _reference(f, shooter, half_mass):
    """{quantity: per-pellet values of the landed pellets} from a run file's pellets."""
    r = f["pellets/landing/range"][()].astype(np.float64)
    landed = np.isfinite(r)
    p = f["pellets/landing/position"][()].astype(np.float64)[landed]
    v = f["pellets/landing/velocity"][()].astype(np.float64)[landed]
    delta = p - np.asarray(shooter)
    up = np.array([0.0, 1.0, 0.0])
    horizontal = delta - (delta @ up)[:, None] * up
    speed = np.linalg.norm(v, axis=1)
    return {"range": r[landed], "distance": np.linalg.norm(horizontal, axis=1), "speed": speed, "energy": half_mass * speed**2}


def test_bins_are_log_spaced_with_the_stated_resolution():
    e = bins.edges()
    inner = e[1:-1]
    assert len(e) == bins.BINS + 1 and e[0] == 0 and np.isinf(e[-1])
    assert np.all(np.diff(inner) > 0)
    assert np.max(inner[1:] / inner[:-1] - 1) <= bins.RELATIVE_WIDTH * (1 + 1e-12)
    rng = np.random.default_rng(1)
    x = np.exp(rng.uniform(-25, 25, 10_000)).astype(np.float32)
    b = bins.bin_index(x)
    assert np.all((e[b] <= x) & (x < e[b + 1]))
    negative_nan = np.array([0xFFC00000], dtype=np.uint32).view(np.float32)[0]  # (x86's inf * 0)
    assert list(bins.bin_index([0.0, -1.0, 1e-30, 1e30, np.inf, np.nan, negative_nan])) == [
        0,
        0,
        0,
        bins.BINS - 1,
        bins.BINS - 1,
        bins.BINS - 1,
        bins.BINS - 1,
    ]


def test_the_kernels_bin_as_numpy_does(device):
    import warp as wp

    bin_of = bins.make_bin_of()

    @wp.kernel(module="unique", enable_backward=False)
    def bin_all(x: wp.array(dtype=wp.float32), b: wp.array(dtype=wp.int32)):
        i = wp.tid()
        b[i] = bin_of(x[i])

    rng = np.random.default_rng(2)
    specials = np.array([0xFFC00000, 0x7FC00000, 0x80000000, 0x7F800000, 0xFF800000, 0x00000001], dtype=np.uint32)
    x = np.concatenate([(10.0 ** rng.uniform(-15, 15, 5000)) * rng.choice([-1, 1], 5000), [0.0]]).astype(np.float32)
    x = np.concatenate([x, specials.view(np.float32)])
    b = wp.zeros(len(x), dtype=wp.int32, device=device)
    wp.launch(bin_all, dim=len(x), inputs=[wp.array(x, dtype=wp.float32, device=device)], outputs=[b], device=device)
    np.testing.assert_array_equal(b.numpy(), bins.bin_index(x))


@given(n=st.integers(1, 3000), seed=st.integers(0, 10_000))
@settings(max_examples=30, deadline=None)
def test_histogram_quantiles_hold_numpys_exact_quantiles(n, seed):
    x = np.random.default_rng(seed).lognormal(3.0, 1.5, n).astype(np.float32)
    counts = np.bincount(bins.bin_index(x), minlength=bins.BINS)
    value, lower = quantiles(counts, LEVELS)
    true = np.quantile(x.astype(np.float64), LEVELS, method="inverted_cdf")
    _within(true, value, lower, "lognormal")
    assert rank(0.999999, 10**9) == 999_999_000 and rank(0.5, 3) == 2


scenes = st.fixed_dictionaries(
    {
        "count": st.integers(50, 2500),
        "seed": st.integers(0, 2**31 - 1),
        "mu_s": st.floats(0.0, 0.6),
        "jitter": st.floats(0.0, 0.3),
        "speed": st.floats(20.0, 450.0),
        "precision": st.sampled_from(["float32", "float64"]),
    }
)


@given(case=scenes)
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_run_quantiles_hold_the_exact_quantiles_of_its_pellets(case, tmp_path_factory):
    raw = paper_raw()
    raw["shot"].update(count=case["count"], seed=case["seed"], speed=case["speed"], direction_jitter=case["jitter"])
    raw["surfaces"][0].update(mu_s=case["mu_s"], mu_d=0.9 * case["mu_s"])
    scene = make_scene(raw, case["precision"], output={"fields": ["landing"]})
    path = tmp_path_factory.mktemp("q") / "run.h5"
    stats = wr.run(scene, path, device="cpu")
    with h5py.File(path, "r") as f:
        assert f["stats/histograms/counts"][()].sum(axis=1).tolist() == [stats["landed"]] * 3
        reference = _reference(f, scene.shot.envelope_center, 0.5 * f["constants/mass"][()])
        assert list(f["stats/quantiles"].attrs["levels"]) == list(LEVELS)
        for name, values in reference.items():
            if not len(values):
                assert np.isnan(f[f"stats/quantiles/{name}"][()]).all()
                continue
            true = np.quantile(values, LEVELS, method="inverted_cdf")
            _within(true, f[f"stats/quantiles/{name}"][()], f[f"stats/quantiles/lower/{name}"][()], name)
        used = f["stats/tail/distance"][()]
        assert np.all(
            (used >= scene.output.tail_distances) & (used <= np.asarray(scene.output.tail_distances) * (1 + bins.RELATIVE_WIDTH))
        )
        d = reference["distance"].astype(np.float32)  # binned as float32
        np.testing.assert_array_equal(f["stats/tail/count"][()], [(d >= e).sum() for e in used])


def _chunked(scene, chunk):
    return scene.replace(numerics=dataclasses.replace(scene.numerics, chunk_size=chunk))


def _tally_of(scene, chunk, device="cpu"):
    stats = wr.run(_chunked(scene, chunk), device=device)
    return stats, stats.tally


@pytest.fixture(scope="module")
def big_scene():
    raw = paper_raw()
    raw["shot"]["count"] = 140_000
    return make_scene(raw, hazard={"map_cell": 1.0, "map_extent": [0.0, 200.0, -20.0, 20.0]})


def test_counts_are_bitwise_the_same_for_any_chunk_size(big_scene, device):
    runs = [_tally_of(big_scene, chunk, device) for chunk in (65_536, 131_072, None)]
    (stats, first), *rest = runs
    assert first.hist[:2].sum(axis=1).tolist() == [stats["landed"]] * 2
    assert first.map_counts.sum() == stats["landed"]
    for _stats, other in rest:
        np.testing.assert_array_equal(other.flat(), first.flat())


def test_tail_counts_are_exact_at_bin_edges():
    x = np.array([1.0, 2.0, 2.0, 3.0, 10.0], dtype=np.float32)
    counts = np.bincount(bins.bin_index(x), minlength=bins.BINS)
    used, beyond = tail(counts, [2.0, 2.5, 10.0, 11.0])
    assert used[0] == 2.0 and used[2] == 10.0 and beyond.tolist()[:1] == [4]
    assert beyond.tolist() == [(x >= u).sum() for u in used]


def test_resumed_counts_and_quantiles_are_bitwise_those_of_an_uninterrupted_run(tmp_path, big_scene):
    scene = _chunked(big_scene, 65_536)
    scene = scene.replace(output=dataclasses.replace(scene.output, fields=("landing.range",)))
    ref, out = tmp_path / "ref.h5", tmp_path / "out.h5"
    wr.run(scene, ref, device="cpu")
    interrupt_after(1, scene, out)
    wr.run(scene, out, device="cpu", resume=True)
    assert_same_run(out, ref, ["landing/range"], progress=("segment_results",))
    with h5py.File(out, "r") as a, h5py.File(ref, "r") as b:
        np.testing.assert_array_equal(a["stats/histograms/counts"][()], b["stats/histograms/counts"][()])
        np.testing.assert_array_equal(a["hazard/map/energy"][()], b["hazard/map/energy"][()])


def test_quantiles_can_be_turned_off():
    scene = make_scene(paper_raw(), output={"quantiles": False})
    stats = wr.run(scene, device="cpu")
    assert stats.tally is None


def test_counting_into_several_copies_gives_the_same_counts(monkeypatch):
    """The CUDA path's copies (`tallies.counts.copies_for`), forced on the CPU: the same counts."""
    from warp_ricochet.tallies import counts

    raw = paper_raw()
    raw["shot"]["count"] = 3000
    scene = make_scene(raw, hazard={"map_cell": 1.0, "map_extent": [100.0, 140.0, -20.0, 20.0]})
    one = wr.run(scene, device="cpu").tally
    monkeypatch.setattr(counts, "copies_for", lambda device, nbytes: 8)
    several = wr.run(scene, device="cpu").tally
    assert one.hist.sum() > 0 and one.map_counts.sum() > 0
    np.testing.assert_array_equal(several.flat(), one.flat())
