"""Benchmark of the motion along a surface (`physics.surface_follow.follow`, docs/ground.md 9):
pellets/s and integration steps per pellet of the paper's pellet from its second contact in air
(about 196 m/s, grazing, nearly rolling), on a rigid plane and on a ploughed one, in vacuum and in air.

    python -m bench.surface [--device cpu] [--n 10000] [--precision float32] [--repeats 3]

`follow_pellets` (one test kernel per precision, planes, model and air laws) is also the tests'
way to run `follow` (tests/test_surface_follow.py). Figures: bench/RESULTS.md.
"""

import argparse
import functools
import math
import platform
import time

import numpy as np
import warp as wp

from warp_ricochet.model import air_struct
from warp_ricochet.physics.surface_follow import ENDS, make_surface_follow
from warp_ricochet.physics.types import surfaces_of, types_for

DENSITY = 7000.0
INERTIA_FACTOR = 0.4


def laws_of(air):
    """The (drag, lift, spin_decay) laws of a `scene.schema.Air`, as the runs choose them."""
    return (air.drag, air.lift if air.magnus else None, air.spin_decay_law if air.spin_decay else None)


@functools.cache
def kernel(precision, planes, model, laws, rough=True, plates=False):
    t = types_for(precision)
    scalar, vec3 = t.scalar, t.vec3
    fns = make_surface_follow(precision, planes, model, laws, rough=rough, plates=plates)
    follow, start, Tally = fns.follow, fns.start, fns.Tally  # (the hazard's watch: none here)

    @wp.kernel(enable_backward=False, module="unique")
    def run(
        x: wp.array(dtype=vec3),
        v: wp.array(dtype=vec3),
        w: wp.array(dtype=vec3),
        k: wp.array(dtype=wp.int32),
        p: wp.array2d(dtype=scalar),  # mu_s, mu_d, c, b, rest_speed
        max_steps: wp.array(dtype=wp.int32),
        surfaces: t.Surfaces,
        physics: t.Physics,
        out_x: wp.array(dtype=vec3),
        out_v: wp.array(dtype=vec3),
        out_w: wp.array(dtype=vec3),
        out_s: wp.array2d(dtype=scalar),  # elapsed, path
        out_i: wp.array2d(dtype=wp.int32),  # end, steps, k_next
    ):
        i = wp.tid()
        xe, ve, we, elapsed, path, end, steps, k_next, _track, _normal = follow(
            x[i], v[i], w[i], k[i], surfaces, physics, p[i, 0], p[i, 1], p[i, 2], p[i, 3], p[i, 4], max_steps[i], start(), Tally()
        )
        out_x[i] = xe
        out_v[i] = ve
        out_w[i] = we
        out_s[i, 0] = elapsed
        out_s[i, 1] = path
        out_i[i, 0] = end
        out_i[i, 1] = steps
        out_i[i, 2] = k_next

    return run


def setup(precision, planes, *, radius, gravity=(0.0, -9.81, 0.0), air=None, tolerance=1e-6, device="cpu", plates=None):
    """(Surfaces, Physics) of planes [(point, normal), ...] for a pellet of `radius` (steel, DENSITY);
    `plates`: per plane None or `types.plate_arrays`'s (kind, axis_u, half_u, half_v, two_sided)."""
    t = types_for(precision)
    points = [p for p, _n in planes]
    normals = [np.asarray(n, float) / np.linalg.norm(n) for _p, n in planes]
    surfaces = surfaces_of(precision, points, normals, [(0.5, 0.5, 0.5)] * len(planes), device, plates=plates)
    physics = t.Physics()
    physics.radius = t.scalar(radius)
    physics.inertia_factor = t.scalar(INERTIA_FACTOR)
    physics.gravity = t.vec3(*gravity)
    physics.impact_duration = t.scalar(0.0)
    mass = DENSITY * 4.0 / 3.0 * math.pi * radius**3
    physics.air = air_struct(air, precision, wp.get_device(device), radius, mass, gravity, tolerance)
    physics.surface_tolerance = t.scalar(tolerance)
    return surfaces, physics


def follow_pellets(
    precision, planes, x, v, w, *, radius, k=0, mu_s=0.5, mu_d=0.4, c=0.0, b=0.0, rest=0.0, max_steps=100000,
    gravity=(0.0, -9.81, 0.0), air=None, tolerance=1e-6, static=False, device="cpu", setup_cache=None, rough=True,
    plates=None, compiled=False,
):  # fmt: skip
    """`follow` of m pellets (x, v, w broadcast to (m, 3); k, mu_s, ... to (m,)): a dict of float64
    arrays x, v, w, elapsed, path and int arrays end, steps, k_next; `rough`: `make_surface_follow`'s;
    `plates`: `setup`'s, `compiled` the kernels' `plates` (`physics.geometry`: MESHES for posts)."""
    model, laws = ("ballistic", None) if air is None else ("air", laws_of(air))
    t = types_for(precision)
    m = max([len(np.atleast_2d(q)) for q in (x, v, w)] + [np.size(q) for q in (k, mu_s, mu_d, c, b, rest, max_steps)])

    def rows(q):
        return np.broadcast_to(np.asarray(q, float), (m, 3)).astype(precision)

    surfaces, physics = setup_cache or setup(
        precision, planes, radius=radius, gravity=gravity, air=air, tolerance=tolerance, device=device, plates=plates
    )
    params = np.stack([np.broadcast_to(np.asarray(q, float), (m,)) for q in (mu_s, mu_d, c, b, rest)], axis=1)
    out_x, out_v, out_w = (wp.zeros(m, dtype=t.vec3, device=device) for _ in range(3))
    out_s = wp.zeros((m, 2), dtype=t.scalar, device=device)
    out_i = wp.zeros((m, 3), dtype=wp.int32, device=device)
    inputs = [wp.array(rows(q), dtype=t.vec3, device=device) for q in (x, v, w)]
    inputs += [wp.array(np.broadcast_to(np.asarray(k, np.int32), (m,)).copy(), dtype=wp.int32, device=device)]
    steps = wp.array(np.broadcast_to(np.asarray(max_steps, np.int32), (m,)).copy(), dtype=wp.int32, device=device)
    inputs += [wp.array(params.astype(precision), device=device), steps, surfaces, physics]
    run = kernel(precision, len(planes) if static else None, model, laws, rough, compiled)
    wp.launch(run, dim=m, inputs=inputs, outputs=[out_x, out_v, out_w, out_s, out_i], device=device)
    s, ints = out_s.numpy().astype(float), out_i.numpy()
    return dict(
        x=out_x.numpy().astype(float), v=out_v.numpy().astype(float), w=out_w.numpy().astype(float),
        elapsed=s[:, 0], path=s[:, 1], end=ints[:, 0], steps=ints[:, 1], k_next=ints[:, 2],
    )  # fmt: skip


R = 0.00125  # m, the paper's pellet (d = 2.5 mm, 7000 kg/m^3)
# its state at the second contact in air (examples/paper.toml, mu_s = 0.5, [air] defaults, bounces =
# 2, float64, pellet 0: impact/position, velocity and angular_velocity), the rebound's 0.025 m/s
# normal speed (below sqrt(2 R g) = 0.157 m/s: it stays on) dropped
SECOND_CONTACT = ((2.4595, R, 0.1802), (196.232, 0.0, 12.876), (10439.6, 0.0, -159097.7))
GROUNDS = {  # (mu_s, mu_d, c, b): illustrative until the ground materials land
    "rigid": (0.5, 0.45, 0.01, 0.0),
    "ploughed": (0.5, 0.45, 0.05, 1.0),
}
REST_SPEED = math.sqrt(10.0 * 9.81 * R / 7.0)  # docs/ground.md 4


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.surface", description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--n", type=int, default=10000)
    parser.add_argument("--precision", default="float32", choices=("float32", "float64"))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--max-steps", type=int, default=100000)
    parser.add_argument("--tolerance", type=float, default=1e-6, help="the integrator's relative tolerance in air")
    args = parser.parse_args(argv)
    from warp_ricochet.scene.schema import Air

    wp.config.quiet = True
    device = wp.get_device(args.device)
    print(
        f"device {device.name} ({platform.processor() or platform.machine()}), {args.precision}, N = {args.n}, "
        f"tolerance {args.tolerance:g} in air"
    )
    rng = np.random.default_rng(25)
    x, v, w = (np.asarray(q, float) for q in SECOND_CONTACT)
    jitter = 1.0 + 0.01 * rng.uniform(-1.0, 1.0, (args.n, 1))  # 1% spread in speed and spin
    planes = [((0.0, 0.0, 0.0), (0.0, 1.0, 0.0))]
    print(f"{'ground':>9} {'medium':>7} {'pellets/s':>10} {'steps mean':>10} {'max':>6} {'rest x mean (m)':>15}  ends")
    for air in (None, Air()):
        medium = "vacuum" if air is None else "air"
        for name, (mu_s, mu_d, c, b) in GROUNDS.items():
            cache = setup(args.precision, planes, radius=R, air=air, tolerance=args.tolerance, device=args.device)
            kwargs = dict(radius=R, mu_s=mu_s, mu_d=mu_d, c=c, b=b, rest=REST_SPEED, air=air, device=args.device)
            kwargs.update(max_steps=args.max_steps, setup_cache=cache)
            follow_pellets(args.precision, planes, x, v * jitter, w * jitter, **kwargs)  # compile, warm up
            times = []
            for _ in range(args.repeats):
                start = time.perf_counter()
                out = follow_pellets(args.precision, planes, x, v * jitter, w * jitter, **kwargs)
                wp.synchronize_device(device)
                times.append(time.perf_counter() - start)
            ends = np.bincount(out["end"], minlength=7)
            summary = ", ".join(f"{ENDS[e]} {n}" for e, n in enumerate(ends) if n)
            print(
                f"{name:>9} {medium:>7} {args.n / np.median(times):10.3g} {out['steps'].mean():10.1f} "
                f"{out['steps'].max():6d} {out['x'][:, 0].mean():15.2f}  {summary}"
            )


if __name__ == "__main__":
    main()
