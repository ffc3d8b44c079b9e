"""Where the statistics kernel's time goes: the current kernel against variants with one part
swapped for its earlier form (Warp's 32-bit PCG sampling; flight without the overlap branch).
An experiment for bench/RESULTS.md, not a feature. Run: python -m bench.attribution"""

import statistics

import warp as wp

from bench.__main__ import _wr, scene_for


def old_sampler(scalar):
    vec3 = wp.types.vector(3, scalar)

    @wp.func
    def sample_pellet(seed: wp.int32, index: wp.int32, speed: scalar, direction: vec3, jitter: vec3,
                      envelope_center: vec3, envelope_radius: scalar, spin: vec3):
        state = wp.rand_init(seed, index)
        one = scalar(1.0)
        two = scalar(2.0)
        z = two * scalar(wp.randf(state)) - one
        azimuth = scalar(6.283185307179586) * scalar(wp.randf(state))
        r = wp.cbrt(scalar(wp.randf(state)))
        ring = r * wp.sqrt(wp.max(one - z * z, scalar(0.0)))
        offset = vec3(ring * wp.cos(azimuth), ring * wp.sin(azimuth), r * z)
        jx = two * scalar(wp.randf(state)) - one
        jy = two * scalar(wp.randf(state)) - one
        jz = two * scalar(wp.randf(state)) - one
        d = direction + wp.cw_mul(jitter, vec3(jx, jy, jz))
        length = wp.length(d)
        velocity = vec3(scalar(0.0), scalar(0.0), scalar(0.0))
        if length > scalar(0.0):
            velocity = d * (speed / length)
        return envelope_center + envelope_radius * offset, velocity, spin

    return sample_pellet


def main():
    wr, wp_ = _wr()
    from warp_ricochet import kernels
    from warp_ricochet.api import plan_chunk, source_struct
    from warp_ricochet.model import Model, State, threads_for

    dev = wp.get_device("cuda:0")
    n = 100_000_000
    scene = scene_for(n)
    model = Model.from_scene(scene, dev)
    rows = plan_chunk(scene, model, n, ())
    state = State(model, rows, ())
    src = source_struct(scene, model)
    threads = threads_for(rows)
    results = {}
    original = kernels.make_sampler
    for label, patch, cap in (("current", None, "default"), ("PCG sampling", old_sampler, 81),
                              ("current, cap 96", None, 96), ("PCG sampling, cap 96", old_sampler, 97)):
        kernels.make_sampler = patch or original
        kernel = kernels.ricochet_kernel_for.__wrapped__("float32", False, False, 1, 1, cap)
        kernels.make_sampler = original
        launch = lambda: wp.launch(kernel, dim=threads, inputs=[0, rows, src, model.surfaces, model.physics, state.outputs, state.cloud],
                                   outputs=[state.partial_sums, state.partial_min, state.partial_max], device=dev)
        launch(); wp.synchronize_device(dev)
        times = []
        for _ in range(10):
            e0, e1 = wp.Event(dev, enable_timing=True), wp.Event(dev, enable_timing=True)
            wp.record_event(e0); launch(); wp.record_event(e1); wp.synchronize_event(e1)
            times.append(wp.get_event_elapsed_time(e0, e1))
        results[label] = statistics.median(times)
        print(f"{label:24s} {results[label]:.3f} ms = {rows / results[label] * 1e3:.3e} pellets/s", flush=True)


if __name__ == "__main__":
    main()
