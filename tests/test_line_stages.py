"""`make_line_steps`' `stages_at` (physics/surface_line.py, docs/ground.md 9): the step's end taken
from its last Dormand-Prince stage is, to the bit, the step of `stages` and `state_at` evaluated
again there (with the grip left at mu_s), on random lines in sea-level air, rolling and sliding,
straight and rough."""

import functools

import numpy as np
import pytest
import warp as wp

from bench.surface import R, setup
from warp_ricochet.physics.line_laws import make_line_laws, make_line_steps
from warp_ricochet.physics.types import types_for
from warp_ricochet.scene.schema import Air

LAWS = ("loth2021", "loth2008", "dennis1980")  # (Air()'s defaults)
POINT = 12  # E, v, omega (3), D, dv/dt along l, domega/dt (3), N/m, the grip left


@functools.cache
def _kernel(precision, rough):
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    ll = make_line_laws(precision, "air", LAWS, (0.0, 0.0), rough)
    st = make_line_steps(precision, "air", LAWS, (0.0, 0.0), rough)
    n_state = len(st.state())
    values = wp.types.vector(length=POINT, dtype=scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def run(
        v: wp.array(dtype=vec3),
        w: wp.array(dtype=vec3),
        p: wp.array2d(dtype=scalar),  # mu_d, c, b, B, rolling, mu_s, h
        physics: t.Physics,
        at: wp.array2d(dtype=scalar),  # the point of stages_at, then state_at's values
        unequal: wp.array(dtype=wp.int32),  # components of y', f' and the error that differ
    ):
        i = wp.tid()
        normal = vec3(scalar(0.0), scalar(1.0), scalar(0.0))
        mu_s = p[i, 5]
        _ok, line = ll.line_of(v[i], w[i], normal, wp.int32(p[i, 4]), physics, p[i, 0], p[i, 1], p[i, 2], scalar(1e-6))
        speed = wp.length(v[i])
        dv, _dl, _dw, _load, _grip = ll.along(speed, scalar(0.0), w[i], physics, line, mu_s)
        line = ll.freeze(line, speed * speed, -dv, p[i, 3], scalar(0.0))
        y0 = st.start(w[i])
        f0 = st.rates(y0, physics, line)
        y1, f1, error, point = st.stages_at(y0, f0, p[i, 6], physics, line)
        y2, f2, error2 = st.stages(y0, f0, p[i, 6], physics, line)
        count = wp.int32(0)
        for j in range(wp.static(n_state)):
            if y1[j] != y2[j] or f1[j] != f2[j] or error[j] != error2[j]:
                count += 1
        unequal[i] = count
        e1, v1, w1, d1, l1, dw1, load1, grip1 = st.state_at(y2, physics, line, mu_s)
        got = values()
        got[0] = point.energy
        got[1] = point.v
        got[2] = point.spin[0]
        got[3] = point.spin[1]
        got[4] = point.spin[2]
        got[5] = point.decel
        got[6] = point.lateral
        got[7] = point.dw[0]
        got[8] = point.dw[1]
        got[9] = point.dw[2]
        got[10] = point.load
        got[11] = st.grip_at(point, line, mu_s)
        want = values(e1, v1, w1[0], w1[1], w1[2], d1, l1, dw1[0], dw1[1], dw1[2], load1, grip1)
        for j in range(wp.static(POINT)):
            at[i, j] = got[j]
            at[i, POINT + j] = want[j]

    return run


def _cases(m, seed):
    """Random motions along +x on a level plane: 0.3-60 m/s, rolling (omega = v / R about -z, plus
    a spin about n and a slip across) or sliding (any spin to 3 v / R), the ground's coefficients,
    a frozen slope B, mu_s and a step of 1e-3 to 0.3 of the distance to stop under friction,
    rolling resistance and ploughing (v^2 / (2 (mu_d + c) g + 2 b v^2)): steps the integrator may take."""
    rng = np.random.default_rng(seed)
    speed = 10.0 ** rng.uniform(np.log10(0.3), np.log10(60.0), m)
    rolling = rng.random(m) < 0.5
    v = np.stack([speed, np.zeros(m), np.zeros(m)], axis=1)
    w = rng.normal(size=(m, 3)) * (speed / R)[:, None]
    w[rolling] = np.stack([np.zeros(m), rng.normal(0, 50, m), -speed / R], axis=1)[rolling]
    p = np.stack(
        [
            rng.uniform(0.2, 0.6, m),  # mu_d
            rng.uniform(0.0, 0.3, m),  # c
            rng.uniform(0.0, 3.0, m),  # b (1/m)
            rng.uniform(0.0, 0.5, m),  # B (1/m)
            rolling.astype(float),
            rng.uniform(0.3, 0.8, m),  # mu_s
            np.zeros(m),  # h (m), below
        ],
        axis=1,
    )
    p[:, 6] = 10.0 ** rng.uniform(-3, np.log10(0.3), m) * speed**2 / (2 * 9.81 * (p[:, 0] + p[:, 1]) + 2 * p[:, 2] * speed**2)
    return v, w, p


@pytest.mark.parametrize("rough", [False, True])
@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_the_last_stage_is_the_steps_end_to_the_bit(precision, rough):
    t = types_for(precision)
    _surfaces, physics = setup(precision, [((0.0, 0.0, 0.0), (0.0, 1.0, 0.0))], radius=R, air=Air())
    v, w, p = _cases(2000, 43)
    at = wp.zeros((len(v), 2 * POINT), dtype=t.scalar, device="cpu")
    unequal = wp.zeros(len(v), dtype=wp.int32, device="cpu")
    inputs = [wp.array(q.astype(precision), dtype=t.vec3, device="cpu") for q in (v, w)]
    inputs += [wp.array(p.astype(precision), dtype=t.scalar, device="cpu"), physics]
    wp.launch(_kernel(precision, rough), dim=len(v), inputs=inputs, outputs=[at, unequal], device="cpu")
    got, want = at.numpy()[:, :POINT], at.numpy()[:, POINT:]
    assert np.isfinite(want).all() and (want[:, 1] > 0).all()
    assert (p[:, 4] == 1).sum() > 500 and (np.abs(want[:, 11] - want[:, 10]) > 0).sum() > 500  # grip != N/m: rolling
    np.testing.assert_array_equal(unequal.numpy(), 0)
    np.testing.assert_array_equal(got.view(np.uint8), want.view(np.uint8))  # to the bit (signed zeros too)
