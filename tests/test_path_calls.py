"""The watch's shape in the core kernel (bench/RESULTS.md "The watch as one call"): `segment` and
`line` kept out of line in CUDA code only (`physics.inlining.out_of_line_on_cuda`), and a `Track` of
only the members a scene uses."""

import numpy as np
import pytest
import warp as wp

from warp_ricochet.physics.inlining import CUDA_NOINLINE, out_of_line_on_cuda
from warp_ricochet.tallies.path_cells import make_path_cells
from warp_ricochet.tallies.path_chord import make_path_watch


@wp.func
def _twice(x: wp.float32):
    return x + x


out_of_line_on_cuda(_twice)


@wp.kernel
def _twice_kernel(values: wp.array(dtype=wp.float32)):
    i = wp.tid()
    values[i] = _twice(values[i])


def test_an_out_of_line_function_is_a_call_in_ptx_and_runs_on_the_cpu(tmp_path):
    values = wp.array(np.array([1.5, -2.0], dtype=np.float32), device="cpu")
    wp.launch(_twice_kernel, dim=2, inputs=[values], device="cpu")
    np.testing.assert_array_equal(values.numpy(), [3.0, -4.0])  # the hint's text compiles for the CPU
    try:
        (ptx,) = wp.compile_aot_module(_twice_kernel.module, arch=90, module_dir=tmp_path, use_ptx=True)
    except Exception as error:  # (no NVRTC in this installation)
        pytest.skip(f"no PTX: {error}")
    text = ptx.read_text()
    assert any(line.startswith(".func") and "_twice" in line for line in text.splitlines()), "inlined in CUDA code"
    source = next(tmp_path.glob("*.cu")).read_text()
    assert "#if defined(__CUDA_ARCH__) || defined(__CUDACC_RTC__)\nWP_NOINLINE\n#endif" in source


@pytest.mark.parametrize(
    ("thresholds", "points", "with_map", "members"),
    [
        (0, 0, False, {"cell"}),
        (0, 2, True, {"cell"}),
        (4, 0, False, {"cell", "reach", "log_slot"}),
        (4, 0, True, {"cell", "reach", "log_slot", "run_row", "run_lo", "run_hi", "run_level"}),
        (3, 2, False, {"cell", "reach", "log_slot", "places"}),
    ],
)
def test_a_track_holds_only_the_members_its_watch_uses(thresholds, points, with_map, members):
    track = make_path_cells("float32", thresholds, points, with_map).Track
    assert set(track.vars) == members
    watch = make_path_watch("float32", thresholds, points, with_map)
    hints = {watch.segment.inline_hint, watch.line.inline_hint}
    assert hints == ({CUDA_NOINLINE} if thresholds > 0 else {None})


def test_a_hint_with_when_false_leaves_the_function_inlined():
    @wp.func
    def _thrice(x: wp.float32):
        return x + x + x

    assert out_of_line_on_cuda(_thrice, when=False).inline_hint is None
    assert out_of_line_on_cuda(_thrice).inline_hint == CUDA_NOINLINE


def test_kernels_to_rest_in_air_keep_their_large_functions_out_of_line():
    """In kernels to rest in air the flight's loop, the root finder, the air's rates and the surface
    line's step and laws are one function each in CUDA code (bench/RESULTS.md "Functions out of line
    in air"); kernels to the landing keep the flight inline (out of line it cost them 6%), and in
    vacuum the surface line's are inlined (out of line they cost the vacuum run 9-14%)."""
    from warp_ricochet.physics.air_flight import make_air_flight, make_roots
    from warp_ricochet.physics.integrate import make_stepper
    from warp_ricochet.physics.line_laws import make_line_laws, make_line_steps
    from warp_ricochet.physics.surface_rates import make_surface_rates

    laws = ("loth2021", "loth2008", "dennis1980")  # any air laws: the hints do not depend on them
    to_rest = (
        make_air_flight("float32", 1, laws, out_of_line=True).watched_loop,
        make_roots("float32", out_of_line=True).root,
        make_stepper("float32", laws, out_of_line=True).rates,
        make_line_laws("float32", "air", laws).along,
        make_line_steps("float32", "air", laws).state_at,
        make_line_steps("float32", "air", laws).six,
        make_surface_rates("float32", "air", laws).rates,
    )
    assert {f.inline_hint for f in to_rest} == {CUDA_NOINLINE}
    inline = (
        make_air_flight("float32", 1, laws).watched_loop,
        make_roots("float32").root,
        make_stepper("float32", laws).rates,
        make_line_laws("float32", "ballistic").along,
        make_line_steps("float32", "ballistic").state_at,
        make_line_steps("float32", "ballistic").six,
        make_surface_rates("float32", "ballistic").rates,
    )
    assert {f.inline_hint for f in inline} == {None}


def test_a_small_meshs_edge_search_is_one_function_in_cuda_code():
    """A small mesh's edges and corners are searched only where no covering face rules them out
    (rarely): their search is one call in CUDA code, in every kernel (bench/RESULTS.md "A small
    mesh's edge search out of line"; the same outputs on the H200, landing and to rest)."""
    from warp_ricochet.physics.edge_contact import make_edge_contact

    for precision in ("float32", "float64"):
        assert make_edge_contact(precision).features_time.inline_hint == CUDA_NOINLINE
