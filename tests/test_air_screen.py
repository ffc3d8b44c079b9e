"""The air's search of a mesh passes a triangle whose edge the step's curve stays beyond
(`physics.air_flight`, `clear_of`), on the whole step or on its part from where the triangle's
offset plane can first be reached (`off_step`), before root finding: never one where `inside`
could hold at a point of the step's interpolant (where the offset plane is reached). Checked on random steps by triangles far from the origin, and on
steps moved to pass within 1e-9 to 1e-2 m of an edge: against the interpolant sampled in the
kernel's own arithmetic (what the contact's `inside` test sees) and in float64 (NumPy)."""

import functools

import numpy as np
import pytest
import warp as wp

from warp_ricochet.physics.air_flight import make_solid_search, make_step_screen
from warp_ricochet.physics.integrate import make_dense_output
from warp_ricochet.physics.mesh_contact import make_mesh_contact
from warp_ricochet.physics.types import types_for

SAMPLES = 513  # thetas sampled on [0, 1] a step
RADIUS = 1.25e-3  # m


@functools.cache
def _kernel(precision):
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    solids, screens = make_solid_search(precision), make_step_screen(precision)
    inside, l1 = make_mesh_contact(precision).inside, make_mesh_contact(precision).l1
    dense = make_dense_output(precision)

    @wp.kernel
    def screen(
        corners: wp.array2d(dtype=vec3),
        steps: wp.array2d(dtype=vec3),
        hs: wp.array(dtype=scalar),
        radius: scalar,
        clear: wp.array2d(dtype=wp.int32),
        inner: wp.array2d(dtype=wp.int32),
    ):
        i = wp.tid()
        a, b, c = corners[i, 0], corners[i, 1], corners[i, 2]
        n = wp.normalize(wp.cross(b - a, c - a))
        x0, v0, a0, x1, v1, a1 = steps[i, 0], steps[i, 1], steps[i, 2], steps[i, 3], steps[i, 4], steps[i, 5]
        h = hs[i]
        low, high = solids.bezier_box(h, x0, v0, a0, x1, v1, a1)
        c0, c1, c2, c3, c4, c5 = screens.controls(h, x0, v0, a0, x1, v1, a1)
        size = l1(x0) + l1(x1) + l1(h * v0) + l1(h * h * a0) + l1(h * v1) + l1(h * h * a1)
        clear[i, 0] = wp.where(screens.clear_of(n, a, b, c0, c1, c2, c3, c4, c5, low, high, size), 1, 0)
        clear[i, 1] = wp.where(screens.clear_of(n, b, c, c0, c1, c2, c3, c4, c5, low, high, size), 1, 0)
        clear[i, 2] = wp.where(screens.clear_of(n, c, a, c0, c1, c2, c3, c4, c5, low, high, size), 1, 0)
        clear[i, 3] = wp.where(screens.off_step(n, a, b, c, radius, h, x0, v0, a0, x1, v1, a1, low, high), 1, 0)
        level = wp.dot(a, n)  # as face_thetas: the offset plane's gap at the step's ends
        g0, s0, q0 = wp.dot(x0, n) - level - radius, h * wp.dot(v0, n), h * h * wp.dot(a0, n)
        g1, s1, q1 = wp.dot(x1, n) - level - radius, h * wp.dot(v1, n), h * h * wp.dot(a1, n)
        count = wp.int32(0)
        met = wp.int32(0)
        for j in range(SAMPLES):
            theta = scalar(j) / scalar(SAMPLES - 1)
            x, _slope = dense.hermite_vec(theta, x0, h * v0, h * h * a0, x1, h * v1, h * h * a1)
            gap, _rate = dense.hermite(theta, g0, s0, q0, g1, s1, q1)
            if inside(n, a, b, c, x):
                count += 1
                if gap <= scalar(0.0):
                    met += 1
        inner[i, 0] = count
        inner[i, 1] = met

    return screen


def _hermite(theta, x0, d0, dd0, x1, d1, dd1):
    """The quintic Hermite interpolant (float64) at thetas (..., samples, 3)."""
    s = theta[None, :, None]
    h0 = 1 - 10 * s**3 + 15 * s**4 - 6 * s**5
    h1 = s - 6 * s**3 + 8 * s**4 - 3 * s**5
    h2 = 0.5 * s**2 - 1.5 * s**3 + 1.5 * s**4 - 0.5 * s**5
    h4 = -4 * s**3 + 7 * s**4 - 3 * s**5
    h5 = 0.5 * s**3 - s**4 + 0.5 * s**5
    e = [q[:, None, :] for q in (x0, d0, dd0, x1, d1, dd1)]
    return h0 * e[0] + h1 * e[1] + h2 * e[2] + (1 - h0) * e[3] + h4 * e[4] + h5 * e[5]


def _cases(rng, count, origin):
    """Triangles of 0.2-1 m, tilted up to 0.5 rad, at `origin`; steps of 0.1-1.5 m at 10-400 m/s
    starting within 1 m of them, accelerations to 2e3 m/s^2; half moved in the triangle's plane to
    pass an edge at 1e-9 to 1e-2 m (in or out), and of the rest 60% moved along the normal to
    graze the triangle's plane offset by RADIUS at 1e-9 to 1e-3 m (above or below)."""
    up = np.array([0.0, 0.0, 1.0]) + rng.uniform(-0.5, 0.5, (count, 3)) * [1, 1, 0]
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    side = np.cross(up, rng.normal(size=(count, 3)))
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    other = np.cross(up, side)
    size = rng.uniform(0.2, 1.0, (count, 1))
    corners = origin + np.stack([np.zeros((count, 3)), size * side, size * (0.3 * side + other)], 1)
    speed = rng.uniform(10.0, 400.0, (count, 1))
    way = rng.normal(size=(count, 3)) * [1.0, 1.0, 0.3]
    v0 = speed * way / np.linalg.norm(way, axis=1, keepdims=True)
    h = rng.uniform(0.1, 1.5, count) / speed[:, 0]
    a0 = rng.normal(0.0, 700.0, (count, 3))
    a1 = a0 + rng.normal(0.0, 100.0, (count, 3))
    x0 = corners.mean(axis=1) + rng.uniform(-1.0, 1.0, (count, 3)) - 0.5 * v0 * h[:, None]
    v1 = v0 + 0.5 * (a0 + a1) * h[:, None]
    x1 = x0 + v0 * h[:, None] + (a0 / 3 + a1 / 6) * h[:, None] ** 2
    steps = np.stack([x0, v0, a0, x1, v1, a1], 1)
    moved = rng.random(count) < 0.5  # the curve's farthest point beyond edge 0 put at +-1e-9..1e-2 m
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    e = corners[:, 1] - corners[:, 0]
    w = np.cross(n, e) / np.linalg.norm(e, axis=1, keepdims=True)  # unit, in the plane, into the triangle
    curve = _hermite(
        np.linspace(0.0, 1.0, 257), x0, v0 * h[:, None], a0 * h[:, None] ** 2, x1, v1 * h[:, None], a1 * h[:, None] ** 2
    )
    reach = np.einsum("ksj,kj->ks", curve - corners[:, None, 0], w).max(axis=1)
    target = rng.choice([-1.0, 1.0], count) * 10.0 ** rng.uniform(-9.0, -2.0, count)
    shift = np.where(moved, target - reach, 0.0)[:, None] * w
    steps[:, 0] += shift
    steps[:, 3] += shift
    grazing = ~moved & (rng.random(count) < 0.6)  # the offset plane's least gap on the curve at +-1e-9..1e-3 m
    curve = curve + shift[:, None, :]
    gap = np.einsum("ksj,kj->ks", curve - corners[:, None, 0], n).min(axis=1) - RADIUS
    target = rng.choice([-1.0, 1.0], count) * 10.0 ** rng.uniform(-9.0, -3.0, count)
    lift = np.where(grazing, target - gap, 0.0)[:, None] * n
    steps[:, 0] += lift
    steps[:, 3] += lift
    return corners, steps, h


@pytest.mark.parametrize(
    "precision, origin", [("float32", 0.0), ("float32", 300.0), ("float64", 300.0)], ids=["float32", "float32-far", "float64"]
)
def test_a_triangle_screened_off_a_step_is_never_under_its_curve(precision, origin):
    rng = np.random.default_rng(44)
    count = 4000
    corners, steps, h = _cases(rng, count, np.array([origin, -0.5 * origin, 0.1 * origin]))
    t = types_for(precision)
    dtype = np.float32 if precision == "float32" else np.float64
    clear = wp.zeros((count, 4), dtype=wp.int32, device="cpu")
    inner = wp.zeros((count, 2), dtype=wp.int32, device="cpu")
    arrays = [wp.array(a.astype(dtype), dtype=t.vec3, device="cpu") for a in (corners, steps)]
    hs = wp.array(h.astype(dtype), device="cpu")
    wp.launch(_kernel(precision), dim=count, inputs=[*arrays, hs, t.scalar(RADIUS), clear, inner], device="cpu")
    clear, inner = clear.numpy().astype(bool), inner.numpy()
    beyond = clear[:, :3].any(axis=1)
    assert not (beyond & (inner[:, 0] > 0)).any()  # never a sample of the kernel's interpolant inside
    assert not (clear[:, 3] & (inner[:, 1] > 0)).any()  # nor inside where the offset plane is reached
    x = steps.astype(dtype).astype(np.float64)  # the float64 reference: every sample beyond a cleared edge
    hh = h.astype(dtype).astype(np.float64)[:, None]
    curve = _hermite(
        np.linspace(0.0, 1.0, SAMPLES), x[:, 0], hh * x[:, 1], hh**2 * x[:, 2], x[:, 3], hh * x[:, 4], hh**2 * x[:, 5]
    )
    p = corners.astype(dtype).astype(np.float64)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    for j in range(3):
        e = p[:, (j + 1) % 3] - p[:, j]
        edge = np.einsum("kj,ksj->ks", np.cross(n, e), curve - p[:, None, j])
        assert (edge[clear[:, j]] < 0.0).all()
    # not vacuous: many screened by an edge, more by the part of the step near the plane, and
    # faces met under the curve among those kept
    assert 0.2 < beyond.mean() < clear[:, 3].mean() < 0.95
    assert (inner[:, 1] > 0).mean() > 0.03
