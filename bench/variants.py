"""Kernel-only timings of the ricochet kernel variants on one device (CUDA events), to choose
the register cap, and the end-to-end time of `run` at the same N. CUDA only.
Run: python -m bench.variants --device cuda:0 [--air] [--rest turf] [--mesh] [--caps none,80,64] [--no-run]"""

import argparse
import dataclasses
import statistics


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--n", type=float, default=1e8)
    ap.add_argument("--caps", default="none,128,96,80,64")
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--air", action="store_true", help="the paper's scene in sea-level air (mu_s 0.5, as bench.air)")
    ap.add_argument("--precisions", default="float32,float64")
    ap.add_argument("--block-dims", default="256", help="CUDA block sizes to try for the ricochet kernel")
    ap.add_argument("--rest", default="", help="with --air: follow the pellets to rest on this ground material")
    ap.add_argument("--no-run", action="store_true", help="the kernel variants only, not run() end to end")
    ap.add_argument("--mesh", action="store_true", help="the paper's plane as a two-triangle mesh (mu_s 0.5, as bench.meshes)")
    args = ap.parse_args(argv)
    import tempfile

    folder = tempfile.TemporaryDirectory()
    mesh = []
    if args.mesh:  # (as bench.kernel_size's "mesh")
        from bench.meshes import plane_mesh

        mesh = plane_mesh(folder.name)
    from bench.__main__ import _wr, scene_for
    from bench.air import paper_scene
    from warp_ricochet.core.kernel import ricochet_kernel_for
    from warp_ricochet.model import Model
    from warp_ricochet.pipeline import CoreStage
    from warp_ricochet.spec import RunSpec
    from warp_ricochet.tallies.reduce import launch_reduce, threads_for

    wr, wp = _wr()
    n = int(args.n)
    dev = wp.get_device(args.device)
    if not dev.is_cuda:
        raise SystemExit("bench.variants times kernels with CUDA events: it needs a CUDA device")

    def scene_of(n, precision="float32"):
        rest = ['physics.until="rest"', f'surfaces.0.material="{args.rest}"'] if args.rest else []
        if args.air or args.mesh:
            return paper_scene(n, precision, air=args.air, mu_s=0.5, extra=rest + mesh)
        return scene_for(n, precision)

    for precision in args.precisions.split(","):
        scene = scene_of(n, precision)
        model = Model.from_scene(scene, dev)
        spec = RunSpec.of(scene, with_output=False, device=dev)
        stage = CoreStage(scene, model, spec, None, n)  # its buffers and source, statistics only
        rows, state = min(stage.capacity, n), stage.state
        threads = threads_for(rows, state.lanes)
        for cap_text, block_dim in [(c, int(b)) for c in args.caps.split(",") for b in args.block_dims.split(",")]:
            fast = cap_text.endswith("+fast")
            cap_text = cap_text.removesuffix("+fast")
            cap = {"none": None, "default": "default"}[cap_text] if cap_text in ("none", "default") else int(cap_text)
            kernel = ricochet_kernel_for(dataclasses.replace(spec, fast_math=fast), cap)
            cap_text = cap_text + ("+fast" if fast else "")
            launch = lambda: wp.launch(
                kernel,
                dim=threads,
                inputs=[
                    0,
                    rows,
                    stage.source.struct,
                    model.surfaces,
                    model.physics,
                    state.outputs,
                    stage.release,
                    stage.tally.struct,
                ],
                outputs=[state.partial_sums, state.partial_min, state.partial_max],
                device=dev,
                block_dim=block_dim,
            )
            reduce = lambda: launch_reduce(state, rows, dev, state.lanes)
            launch()
            reduce()
            wp.synchronize_device(dev)
            times, rtimes = [], []
            for _ in range(args.repeats):
                e0, e1, e2 = (wp.Event(dev, enable_timing=True) for _ in range(3))
                wp.record_event(e0)
                launch()
                wp.record_event(e1)
                reduce()
                wp.record_event(e2)
                wp.synchronize_event(e2)
                times.append(wp.get_event_elapsed_time(e0, e1))
                rtimes.append(wp.get_event_elapsed_time(e1, e2))
            t = statistics.median(times)
            print(
                f"{precision} cap={cap_text:>4} block={block_dim:3d}: ricochet kernel {t:8.3f} ms = {rows / t * 1e3:.3e} pellets/s; "
                f"reduce {statistics.median(rtimes):.3f} ms",
                flush=True,
            )
    # end-to-end
    for m in () if args.no_run else (1e4, 1e6, n):
        sc = scene_of(int(m))
        wr.run(sc, device=args.device)
        ts = []
        import time

        for _ in range(args.repeats):
            t0 = time.perf_counter()
            wr.run(sc, device=args.device)
            wp.synchronize_device(dev)
            ts.append(time.perf_counter() - t0)
        t = statistics.median(ts)
        print(f"run() end to end N={int(m):,d}: {t * 1e3:.3f} ms = {m / t:.3e} pellets/s", flush=True)


if __name__ == "__main__":
    main()
