"""The air's search of a mesh passes a triangle whose edge the step's curve stays beyond
(`physics.air_screen`, `clear_of`), on the whole step or on its part from where the triangle's
plane or its offset can first be met (`first_met`) to the contact found so far (`off_step`'s
bound), before root finding: never one whose face contact (`face_theta`: `face_thetas` kept where
`inside` holds, as `triangle_theta` finds it unscreened) lies before that bound. Checked on random steps by
triangles far from the origin, on steps moved to pass within 1e-9 to 1e-2 m of an edge, and on
centres starting within R of the plane and leaving it (waiting for the turn), with bounds of 2,
uniform on [0, 1] and within 1e-7 to 1e-2 of the face contact: an edge's clearance against the
interpolant sampled in the kernel's own arithmetic and in float64 (NumPy)."""

import functools

import numpy as np
import pytest
import warp as wp

from warp_ricochet.physics.air_flight import make_face_thetas, make_solid_search
from warp_ricochet.physics.air_screen import make_step_screen
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
        bounds: wp.array(dtype=scalar),
        radius: scalar,
        clear: wp.array2d(dtype=wp.int32),
        inner: wp.array(dtype=wp.int32),
        met: wp.array(dtype=scalar),
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
        clear[i, 3] = wp.where(screens.off_step(n, a, b, c, radius, h, x0, v0, a0, x1, v1, a1, low, high, bounds[i]), 1, 0)
        theta = solids.face_theta(n, a, b, c, h, x0, v0, a0, x1, v1, a1, radius)  # (unscreened)
        met[i] = theta
        count = wp.int32(0)
        for j in range(SAMPLES):
            x, _slope = dense.hermite_vec(scalar(j) / scalar(SAMPLES - 1), x0, h * v0, h * h * a0, x1, h * v1, h * h * a1)
            if inside(n, a, b, c, x):
                count += 1
        inner[i] = count

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


def _waiting_cases(rng, count, origin):
    """Centres starting within R of the triangle's plane (at R less 1e-9 R to R, a tenth at R),
    leaving it at 0.05-10 m/s along its normal while moving 10-400 m/s along it, turned back by
    50-5e3 m/s^2: the steps after a ricochet off a terrain's nearly coplanar triangles."""
    corners, _steps, _h = _cases(rng, count, origin)
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    along = np.cross(n, rng.normal(size=(count, 3)))
    along /= np.linalg.norm(along, axis=1, keepdims=True)
    speed = rng.uniform(10.0, 400.0, (count, 1))
    v0 = speed * along + 10.0 ** rng.uniform(-1.3, 1.0, (count, 1)) * n
    a0 = -(10.0 ** rng.uniform(1.7, 3.7, (count, 1))) * n + rng.normal(0.0, 50.0, (count, 3))
    a1 = a0 + rng.normal(0.0, 20.0, (count, 3))
    h = rng.uniform(0.2, 2.0, count) / speed[:, 0]
    inset = RADIUS * 10.0 ** rng.uniform(-9.0, 0.0, (count, 1)) * rng.choice([0.0, 1.0], (count, 1), p=[0.1, 0.9])
    x0 = corners.mean(axis=1) + rng.uniform(-0.6, 0.6, (count, 1)) * along + (RADIUS - inset) * n
    v1 = v0 + 0.5 * (a0 + a1) * h[:, None]
    x1 = x0 + v0 * h[:, None] + (a0 / 3 + a1 / 6) * h[:, None] ** 2
    return corners, np.stack([x0, v0, a0, x1, v1, a1], 1), h


def _screen(precision, corners, steps, h, bounds):
    """The kernel's (clear by each edge and off_step, inside samples, face contact)."""
    count = len(h)
    t = types_for(precision)
    dtype = np.float32 if precision == "float32" else np.float64
    clear = wp.zeros((count, 4), dtype=wp.int32, device="cpu")
    inner = wp.zeros(count, dtype=wp.int32, device="cpu")
    met = wp.zeros(count, dtype=t.scalar, device="cpu")
    arrays = [wp.array(a.astype(dtype), dtype=t.vec3, device="cpu") for a in (corners, steps)]
    scalars = [wp.array(a.astype(dtype), device="cpu") for a in (h, bounds)]
    wp.launch(_kernel(precision), dim=count, inputs=[*arrays, *scalars, t.scalar(RADIUS), clear, inner, met], device="cpu")
    return clear.numpy().astype(bool), inner.numpy(), met.numpy().astype(np.float64)


CASES = [("float32", 0.0), ("float32", 300.0), ("float64", 300.0)]
IDS = ["float32", "float32-far", "float64"]


@pytest.mark.parametrize("precision, origin", CASES, ids=IDS)
def test_a_triangle_screened_off_a_step_is_never_under_its_curve(precision, origin):
    rng = np.random.default_rng(44)
    count = 4000
    corners, steps, h = _cases(rng, count, np.array([origin, -0.5 * origin, 0.1 * origin]))
    dtype = np.float32 if precision == "float32" else np.float64
    clear, inner, met = _screen(precision, corners, steps, h, np.full(count, 2.0))
    beyond = clear[:, :3].any(axis=1)
    assert not (beyond & (inner > 0)).any()  # never a sample of the kernel's interpolant inside
    assert not (clear[:, 3] & (met <= 1.0)).any()  # nor a face contact on the step
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
    # faces met
    assert 0.2 < beyond.mean() < clear[:, 3].mean() < 0.99
    assert (met <= 1.0).sum() >= 15


@pytest.mark.parametrize("waiting", [False, True], ids=["random", "waiting"])
@pytest.mark.parametrize("precision, origin", CASES, ids=IDS)
def test_a_triangle_screened_before_a_bound_is_not_met_before_it(precision, origin, waiting):
    rng = np.random.default_rng(45)
    count = 4000 if waiting else 20000
    maker = _waiting_cases if waiting else _cases
    corners, steps, h = maker(rng, count, np.array([origin, -0.5 * origin, 0.1 * origin]))
    _clear, _inner, met = _screen(precision, corners, steps, h, np.full(count, 2.0))
    near = met * (1.0 + rng.choice([-1.0, 1.0], count) * 10.0 ** rng.uniform(-7.0, -2.0, count))
    bounds = np.where(met <= 1.0, near, rng.uniform(0.0, 1.0, count))
    dtype = np.float32 if precision == "float32" else np.float64
    screened = []
    for bound in (np.full(count, 2.0), rng.uniform(0.0, 1.0, count), bounds):
        clear, _inner, again = _screen(precision, corners, steps, h, bound)
        assert (again == met).all()
        assert not (clear[:, 3] & (met < bound.astype(dtype))).any()
        screened.append(clear[:, 3].mean())
    # not vacuous: faces met, and more screened with a bound below 1 than without
    assert (met <= 1.0).sum() >= (800 if waiting else 80)
    assert screened[0] < min(screened[1:])


@functools.cache
def _planes_kernel(precision):
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    faces = make_face_thetas(precision)

    @wp.kernel
    def planes(
        corners: wp.array2d(dtype=vec3),
        steps: wp.array2d(dtype=vec3),
        hs: wp.array(dtype=scalar),
        radius: scalar,
        met: wp.array2d(dtype=scalar),
    ):
        i = wp.tid()
        a, b, c = corners[i, 0], corners[i, 1], corners[i, 2]
        n = wp.normalize(wp.cross(b - a, c - a))
        x0, v0, a0, x1, v1, a1 = steps[i, 0], steps[i, 1], steps[i, 2], steps[i, 3], steps[i, 4], steps[i, 5]
        level = wp.dot(a, n)
        met[i, 0] = faces.offset_theta(n, level, hs[i], x0, v0, a0, x1, v1, a1, radius)
        met[i, 1] = faces.through_theta(n, level, hs[i], x0, v0, a0, x1, v1, a1)

    return planes


@pytest.mark.parametrize("radius", [RADIUS, 1e-5], ids=["R", "small"])
@pytest.mark.parametrize("waiting", [False, True], ids=["random", "waiting"])
@pytest.mark.parametrize("precision, origin", CASES, ids=IDS)
def test_the_centre_reaches_a_plane_no_earlier_than_its_offset(precision, origin, waiting, radius):
    """A flat mesh's search keeps its plane's offset contact over a triangle without finding where
    the centre itself reaches the plane (`air_flight.flat_theta`): on the interpolant, from in
    front of the plane or waiting within R of it, that is never earlier (also for a radius of
    1e-5 m, where the two come within 2e-6 of theta)."""
    rng = np.random.default_rng(46)
    count = 4000 if waiting else 20000
    maker = _waiting_cases if waiting else _cases
    corners, steps, h = maker(rng, count, np.array([origin, -0.5 * origin, 0.1 * origin]))
    t = types_for(precision)
    dtype = np.float32 if precision == "float32" else np.float64
    met = wp.zeros((count, 2), dtype=t.scalar, device="cpu")
    arrays = [wp.array(a.astype(dtype), dtype=t.vec3, device="cpu") for a in (corners, steps)]
    wp.launch(
        _planes_kernel(precision),
        dim=count,
        inputs=[*arrays, wp.array(h.astype(dtype), device="cpu"), t.scalar(radius), met],
        device="cpu",
    )
    offset, through = met.numpy().astype(np.float64).T
    assert not ((offset <= 1.0) & (through < offset)).any()
    # not vacuous: offsets met, and the centre reaching the plane on many of those steps
    both = (offset <= 1.0) & (through <= 1.0)
    assert (offset <= 1.0).sum() >= 900
    assert both.sum() >= (1000 if waiting else 500)
