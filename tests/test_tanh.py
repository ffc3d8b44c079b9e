"""`physics.air.make_tanh`: float32's tanh from one exp against float64's on random and special
arguments; float64's is wp.tanh."""

import numpy as np
import pytest
import warp as wp

from warp_ricochet.physics.air import make_tanh


def _kernel(precision, dtype):
    tanh = make_tanh(precision)

    @wp.kernel(module="unique")
    def apply(x: wp.array(dtype=dtype), y: wp.array(dtype=dtype)):
        i = wp.tid()
        y[i] = tanh(x[i])

    return apply


@pytest.fixture(scope="module")
def kernels():
    return {"float32": _kernel("float32", wp.float32), "float64": _kernel("float64", wp.float64)}


def _tanh(kernels, precision, x, device):
    dtype = np.float32 if precision == "float32" else np.float64
    xs = wp.array(np.asarray(x, dtype=dtype), device=device)
    ys = wp.empty_like(xs)
    wp.launch(kernels[precision], dim=len(x), inputs=[xs], outputs=[ys], device=device)
    return ys.numpy()


def test_float32_tanh_is_within_a_few_ulp_of_the_float64_one(kernels, device):
    rng = np.random.default_rng(11)
    x = np.concatenate(
        [
            rng.uniform(-20.0, 20.0, 20_000),
            rng.uniform(-0.2, 0.2, 20_000),  # about the series' end (1/8)
            np.sign(rng.uniform(-1, 1, 5_000)) * 10.0 ** rng.uniform(-30, 1, 5_000),
            [0.125, -0.125, np.nextafter(np.float32(0.125), np.float32(0))],
        ]
    ).astype(np.float32)
    got = _tanh(kernels, "float32", x, device).astype(np.float64)
    want = np.tanh(x.astype(np.float64))
    ulp = np.spacing(np.abs(want).astype(np.float32)).astype(np.float64)
    assert np.max(np.abs(got - want) / ulp) <= 4.0
    assert np.all(np.abs(got) <= 1.0)
    assert np.all(np.sign(got) == np.sign(x))  # odd, and 0 at 0


def test_float32_tanh_at_its_limits(kernels, device):
    x = np.array([0.0, -0.0, 1e-38, 40.0, -40.0, np.inf, -np.inf, np.nan], dtype=np.float32)
    got = _tanh(kernels, "float32", x, device)
    np.testing.assert_array_equal(got[:7], np.array([0.0, 0.0, 1e-38, 1.0, -1.0, 1.0, -1.0], dtype=np.float32))
    assert np.isnan(got[7])


def test_float32_tanh_saturates_as_its_formula_does(kernels, device):
    # from |x| = 9 the formula is not evaluated: 1 - e and 1 + e (e = exp(-2|x|) < 2^-25) round to 1
    # there, so +-1 exactly is the formula's own result; float64's tanh rounds to +-1 from |x| = 9.01
    rng = np.random.default_rng(9)
    x = np.concatenate([rng.uniform(8.0, 100.0, 5_000), 10.0 ** rng.uniform(1, 38, 1_000), [9.0, np.inf]])
    x = np.concatenate([x, -x, np.nextafter(np.float32([9.0, -9.0]), np.float32(0))]).astype(np.float32)
    got = _tanh(kernels, "float32", x, device)
    e = np.exp(-2.0 * np.abs(x.astype(np.float64))).astype(np.float32)  # the formula, each operation in float32
    np.testing.assert_array_equal(got, np.sign(x) * ((np.float32(1) - e) / (np.float32(1) + e)))
    saturated = np.abs(x) >= 9.0
    np.testing.assert_array_equal(got[saturated], np.sign(x[saturated]))
    beyond = np.abs(x) >= 9.02
    np.testing.assert_array_equal(got[beyond], np.tanh(x[beyond].astype(np.float64)).astype(np.float32))


def test_float64_tanh_is_warps(kernels, device):
    x = np.random.default_rng(2).uniform(-5, 5, 1000)
    np.testing.assert_allclose(_tanh(kernels, "float64", x, device), np.tanh(x), rtol=5e-16, atol=0)  # (libm's against NumPy's)
