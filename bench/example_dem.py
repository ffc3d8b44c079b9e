"""Warp's own DEM example as a headless benchmark, so that it can be timed on the same GPU in the same run as
our kernels (the GPU machine's warp install has no `warp/examples` folder).

    python -m bench.example_dem [--device cuda:0] [--sizes 65536,524288] [--frames 20]

Source: `warp/examples/core/example_dem.py` of warp-lang 1.19.0 (NVIDIA/warp, Apache-2.0), taken from the
installed 1.19.0 wheel (file sha256 211f86a36d5dc743ce0c75a71dc1c5ad3536663776aa87bf0b2105600c2176bf; the wheel
records no git commit). Cross-checked against NVIDIA/warp commit 5495dc762dae2f09b648588d0f979e03ea3ef88b, an
earlier 1.x version of the same file: kernels and parameters are identical there; it differs only in writing
`wp.array(dtype=wp.vec3)` for `wp.array[wp.vec3]` and in capturing a graph on CUDA devices only.

Kept verbatim: `contact_force`, `apply_forces` (HashGrid query, radius * 5), `integrate`, every parameter
(frame_dt = 1/60, sim_substeps = 64, point_radius = 0.1, k_contact = 8000, k_damp = 2, k_friction = 1,
k_mu = 1e5, inv_mass = 64, HashGrid(128, 128, 128), grid cell size = 5 * radius, gravity, the initial
velocity (0, 0, 15)), `particle_grid` (lattice, jitter 0.1, seed 42, lower corner (0, 0.5, 0)), and the frame
structure: grid.build once, then sim_substeps x (apply_forces, integrate), the substeps captured once as a
graph and replayed each frame (1.19 captures on every device, the CPU included).

Changed: no rendering and no USD (no `warp.render`, no stage); the per-step `wp.ScopedTimer`s that print every
frame are gone; the lattice dims are a parameter (the example's 32 x 64 x 32 = 65,536 particles; other counts
keep its 1 : 2 : 1 shape, e.g. 64 x 128 x 64 = 524,288); `run()` and `main()` time it instead of the example's
`__main__`.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import warp as wp

# ---------------------------------------------------------------------------------------------------------------
# Verbatim from warp/examples/core/example_dem.py (warp-lang 1.19.0)
# ---------------------------------------------------------------------------------------------------------------


@wp.func
def contact_force(n: wp.vec3, v: wp.vec3, c: float, k_n: float, k_d: float, k_f: float, k_mu: float):
    vn = wp.dot(n, v)
    jn = c * k_n
    jd = min(vn, 0.0) * k_d

    # contact force
    fn = jn + jd

    # friction force
    vt = v - n * vn
    vs = wp.length(vt)

    if vs > 0.0:
        vt = vt / vs

    # Coulomb condition
    ft = wp.min(vs * k_f, k_mu * wp.abs(fn))

    # total force
    return -n * fn - vt * ft


@wp.kernel
def apply_forces(
    grid: wp.uint64,
    particle_x: wp.array[wp.vec3],
    particle_v: wp.array[wp.vec3],
    particle_f: wp.array[wp.vec3],
    radius: float,
    k_contact: float,
    k_damp: float,
    k_friction: float,
    k_mu: float,
):
    tid = wp.tid()

    # order threads by cell
    i = wp.hash_grid_point_id(grid, tid)

    x = particle_x[i]
    v = particle_v[i]

    f = wp.vec3()

    # ground contact
    n = wp.vec3(0.0, 1.0, 0.0)
    c = wp.dot(n, x)

    cohesion_ground = 0.02
    cohesion_particle = 0.0075

    if c < cohesion_ground:
        f = f + contact_force(n, v, c, k_contact, k_damp, 100.0, 0.5)

    # particle contact
    neighbors = wp.hash_grid_query(grid, x, radius * 5.0)

    for index in neighbors:
        if index != i:
            # compute distance to point
            n = x - particle_x[index]
            d = wp.length(n)
            err = d - radius * 2.0

            if err <= cohesion_particle:
                n = n / d
                vrel = v - particle_v[index]

                f = f + contact_force(n, vrel, err, k_contact, k_damp, k_friction, k_mu)

    particle_f[i] = f


@wp.kernel
def integrate(
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    f: wp.array[wp.vec3],
    gravity: wp.vec3,
    dt: float,
    inv_mass: float,
):
    tid = wp.tid()

    v_new = v[tid] + f[tid] * inv_mass * dt + gravity * dt
    x_new = x[tid] + v_new * dt

    v[tid] = v_new
    x[tid] = x_new


class Example:
    # Changed: `stage_path` (USD renderer) replaced by `dims`, the lattice size; the example's is (32, 64, 32).
    def __init__(self, dims=(32, 64, 32)):
        fps = 60
        self.frame_dt = 1.0 / fps

        self.sim_substeps = 64
        self.sim_dt = self.frame_dt / self.sim_substeps
        self.sim_time = 0.0

        self.point_radius = 0.1

        self.k_contact = 8000.0
        self.k_damp = 2.0
        self.k_friction = 1.0
        self.k_mu = 100000.0  # for cohesive materials

        self.inv_mass = 64.0

        self.grid = wp.HashGrid(128, 128, 128)
        self.grid_cell_size = self.point_radius * 5.0

        self.points = self.particle_grid(*dims, (0.0, 0.5, 0.0), self.point_radius, 0.1)

        self.x = wp.array(self.points, dtype=wp.vec3)
        self.v = wp.array(np.ones([len(self.x), 3]) * np.array([0.0, 0.0, 15.0]), dtype=wp.vec3)
        self.f = wp.zeros_like(self.v)

        self.use_graph_capture = True
        if self.use_graph_capture:
            with wp.ScopedCapture() as capture:
                self.simulate()
            self.graph = capture.graph

    def simulate(self):
        for _ in range(self.sim_substeps):
            wp.launch(
                kernel=apply_forces,
                dim=len(self.x),
                inputs=[
                    self.grid.id,
                    self.x,
                    self.v,
                    self.f,
                    self.point_radius,
                    self.k_contact,
                    self.k_damp,
                    self.k_friction,
                    self.k_mu,
                ],
            )
            wp.launch(
                kernel=integrate,
                dim=len(self.x),
                inputs=[self.x, self.v, self.f, (0.0, -9.8, 0.0), self.sim_dt, self.inv_mass],
            )

    def step(self):
        # Changed: the example's wp.ScopedTimer("step") / ScopedTimer("grid build") wrappers removed.
        self.grid.build(self.x, self.grid_cell_size)

        if self.use_graph_capture:
            wp.capture_launch(self.graph)
        else:
            self.simulate()

        self.sim_time += self.frame_dt

    # creates a grid of particles
    def particle_grid(self, dim_x, dim_y, dim_z, lower, radius, jitter):
        rng = np.random.default_rng(42)
        points = np.meshgrid(np.linspace(0, dim_x, dim_x), np.linspace(0, dim_y, dim_y), np.linspace(0, dim_z, dim_z))
        points_t = np.array((points[0], points[1], points[2])).T * radius * 2.0 + np.array(lower)
        points_t = points_t + rng.random(size=points_t.shape) * radius * jitter

        return points_t.reshape((-1, 3))


# ---------------------------------------------------------------------------------------------------------------
# Benchmark harness (not in the example)
# ---------------------------------------------------------------------------------------------------------------


def lattice_dims(n: int) -> tuple[int, int, int]:
    """(dim_x, dim_y, dim_z) with dim_x * dim_y * dim_z == n, as close as possible to the example's 1 : 2 : 1
    shape (32 x 64 x 32): 65,536 -> (32, 64, 32), 524,288 -> (64, 128, 64)."""
    if n < 1:
        raise ValueError(f"particle count must be positive, got {n}")
    s = (n / 2.0) ** (1.0 / 3.0)
    target = (math.log(s), math.log(2.0 * s), math.log(s))
    best, best_err = None, math.inf
    for dx in range(1, n + 1):
        if n % dx:
            continue
        rest = n // dx
        for dz in range(1, rest + 1):
            if rest % dz:
                continue
            dims = (dx, rest // dz, dz)
            err = sum((math.log(d) - t) ** 2 for d, t in zip(dims, target))
            if err < best_err - 1e-12:
                best, best_err = dims, err
    return best


def run(num_particles: int, frames: int, device: str) -> dict:
    """Time `frames` frames of the DEM example with `num_particles` particles on `device`, after one untimed
    warm-up frame (kernel compilation happens while capturing, before it)."""
    dims = lattice_dims(num_particles)
    with wp.ScopedDevice(device):
        example = Example(dims=dims)
        n = len(example.x)
        assert n == num_particles, (n, num_particles, dims)

        example.step()  # warm-up frame
        wp.synchronize_device(device)

        start = time.perf_counter()
        for _ in range(frames):
            example.step()
        wp.synchronize_device(device)
        seconds = time.perf_counter() - start

    substeps = frames * example.sim_substeps
    return {
        "particles": n,
        "substeps": substeps,
        "seconds": seconds,
        "particle_substeps_per_s": n * substeps / seconds,
    }


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default="cuda:0", help="Warp device (default cuda:0)")
    parser.add_argument("--sizes", default="65536,524288", help="comma-separated particle counts")
    parser.add_argument("--frames", type=int, default=20, help="timed frames per size (64 substeps each)")
    args = parser.parse_args(argv)

    wp.init()
    for size in (int(s) for s in args.sizes.split(",") if s.strip()):
        r = run(size, args.frames, args.device)
        print(
            f"example_dem N={r['particles']} substeps={r['substeps']} time={r['seconds']:.3f}s "
            f"rate={r['particle_substeps_per_s']:.2e} particle-substeps/s",
            flush=True,
        )


if __name__ == "__main__":
    main()
