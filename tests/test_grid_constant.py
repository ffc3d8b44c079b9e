"""physics.grid_constant: CUDA kernel parameters declared `__grid_constant__` and read in place,
for the kernels that opt in, and nothing else changed (CPU code, other kernels, a kernel that
writes a parameter)."""

import re
import tempfile
from pathlib import Path
from types import SimpleNamespace

import pytest
import warp as wp
import warp._src.codegen as codegen
from warp._src.context import ModuleBuilder

from warp_ricochet import struct_refs
from warp_ricochet.physics import grid_constant as gc
from warp_ricochet.physics.inlining import out_of_line_on_cuda
from warp_ricochet.spec import RunSpec

gc.install()

# A kernel as Warp 1.19's CUDA template writes it (abridged).
KERNEL = """
extern "C" __global__ void k_cuda_kernel_forward(
    wp::launch_bounds_t<1> dim,
    S_1 var_s,
    wp::array_t<wp::float32> var_out)
{
    wp::tile_shared_storage_t tile_mem;
    BODY
}
"""


def test_a_kernel_signature_is_rewritten_and_its_parameters_aliased():
    out = gc.rewrite(KERNEL.replace("BODY", "var_2 = &((var_s).a);"), [("S_1", "var_s"), ("wp::array_t<wp::float32>", "var_out")])
    assert "__grid_constant__ const S_1 var_s__gc," in out
    assert "__grid_constant__ const wp::array_t<wp::float32> var_out__gc)" in out
    assert "wp::launch_bounds_t<1> dim," in out  # (Warp's own first parameter is left as it is)
    assert "{\n    S_1& var_s = const_cast<S_1&>(var_s__gc);\n    wp::array_t<wp::float32>& var_out" in out
    assert out.count("__grid_constant__") == 2


@pytest.mark.parametrize("store", ["var_s.a = var_1;", "var_s.b.c = var_1;", "var_s = var_3;", "var_s.n += var_1;"])
def test_a_kernel_that_writes_a_parameter_is_left_as_warp_wrote_it(store):
    source = KERNEL.replace("BODY", store)
    assert gc.rewrite(source, [("S_1", "var_s"), ("wp::array_t<wp::float32>", "var_out")]) == source


def test_reads_and_comparisons_of_a_parameter_are_not_writes():
    body = "var_4 = (var_s.a == var_1);\nvar_5 = (var_s.a <= var_1);\nvar_6 = (var_s.a != var_1);\nvar_7 = var_s.a;"
    assert "__grid_constant__" in gc.rewrite(KERNEL.replace("BODY", body), [("S_1", "var_s")])


def test_a_source_of_another_shape_is_left_unchanged():
    source = KERNEL.replace("BODY", "")
    assert gc.rewrite(source, [("S_2", "var_s")]) == source  # a parameter the signature lacks
    assert gc.rewrite(source.replace("__global__", "__device__"), [("S_1", "var_s")]) == source.replace(
        "__global__", "__device__"
    )


@wp.struct
class Pack:
    a: wp.float32
    b: wp.types.vector(length=32, dtype=wp.float32)
    x: wp.array(dtype=wp.float32)


@wp.func
def total(p: Pack, i: wp.int32):
    s = p.a + p.x[i]
    for j in range(32):
        s += p.b[j]
    return s


out_of_line_on_cuda(total)  # (one call, not inlined)
struct_refs.read_only(Pack)  # (taken by reference in CUDA code, as the package's read-only structs are)


@wp.struct
class Inner:
    c: wp.float32


@wp.struct
class Fields:
    a: wp.float32
    v: wp.vec3
    inner: Inner
    x: wp.array(dtype=wp.float32)


def _set_a(s: Fields, v: wp.vec3, m: wp.mat22, out: wp.array(dtype=wp.float32)):
    s.a = 1.0


def _add_a(s: Fields, v: wp.vec3, m: wp.mat22, out: wp.array(dtype=wp.float32)):
    s.a += 1.0


def _set_inner(s: Fields, v: wp.vec3, m: wp.mat22, out: wp.array(dtype=wp.float32)):
    s.inner.c = 1.0


def _set_component(s: Fields, v: wp.vec3, m: wp.mat22, out: wp.array(dtype=wp.float32)):
    s.v[0] = 1.0


def _set_vector(s: Fields, v: wp.vec3, m: wp.mat22, out: wp.array(dtype=wp.float32)):
    v[1] = 1.0


def _add_matrix(s: Fields, v: wp.vec3, m: wp.mat22, out: wp.array(dtype=wp.float32)):
    m[0, 1] += 1.0


def _reads_and_array_writes(s: Fields, v: wp.vec3, m: wp.mat22, out: wp.array(dtype=wp.float32)):
    s.x[0] = s.a + s.v[0] + s.inner.c + v[1] + m[0, 1]
    out[0] += 1.0
    wp.atomic_add(out, 0, 1.0)
    wp.atomic_add(s.x, 0, 1.0)


@pytest.mark.parametrize(
    ("body", "rewritten"),
    [
        (_set_a, False),
        (_add_a, False),
        (_set_inner, False),
        (_set_component, False),  # (a pointer into the struct, then a store through it)
        (_set_vector, False),  # (an in-place operation on the parameter)
        (_add_matrix, False),
        (_reads_and_array_writes, True),  # (an array's elements are its data, not the parameter)
    ],
)
def test_only_a_kernel_that_cannot_write_its_parameters_is_rewritten(body, rewritten):
    """Warp's code for each way a kernel can write a parameter (a field, a nested field, a vector's
    component through a pointer, an in-place operation) keeps the kernel as Warp wrote it."""
    kernel = wp.kernel(body, module="unique", enable_backward=False, module_options=gc.module_options())
    assert ("__grid_constant__" in _source(kernel, "cuda")) == rewritten


def _kernel(opted_in: bool):
    options = gc.module_options() if opted_in else None

    @wp.kernel(module="unique", enable_backward=False, module_options=options)
    def pack_total(p: Pack, n: wp.int32, out: wp.array(dtype=wp.float32)):
        i = wp.tid()
        out[i] = total(p, i) + wp.float32(n)

    return pack_total


def _source(kernel, device):
    module = kernel.module
    return ModuleBuilder(module, module.resolve_options(wp.config)).codegen(device)


def test_an_opted_in_kernel_reads_its_parameters_in_place_on_cuda_only():
    kernel = _kernel(True)
    cuda = _source(kernel, "cuda")
    head = cuda[cuda.index("__global__") : cuda.index("{", cuda.index("__global__"))]
    assert re.findall(r"__grid_constant__ const (\S+) var_(\w+)__gc", head) == [
        (kernel.adj.args[0].ctype(), "p"),
        ("wp::int32", "n"),
        ("wp::array_t<wp::float32>", "out"),
    ]
    assert "__grid_constant__" not in _source(kernel, "cpu")
    assert "__grid_constant__" not in _source(_kernel(False), "cuda")


def test_opting_in_keys_the_module_hash():
    """The rewritten module never shares a kernel cache entry with the plain one."""
    hashes = {k.module.hash_module() for k in (_kernel(True), _kernel(False))}
    assert len(hashes) == 2


def test_an_opted_in_kernel_runs_the_same(device):
    """The same values with the parameters in place as without, on each device (CUDA runs the rewrite)."""
    values = wp.array(range(8), dtype=wp.float32, device=device)
    pack = Pack()
    pack.a, pack.b, pack.x = 1.5, wp.types.vector(length=32, dtype=wp.float32)(*range(32)), values
    outs = []
    for opted_in in (True, False):
        out = wp.zeros(8, dtype=wp.float32, device=device)
        wp.launch(_kernel(opted_in), dim=8, inputs=[pack, 2], outputs=[out], device=device)
        outs.append(out.numpy())
    assert (outs[0] == outs[1]).all() and outs[0][3] == 1.5 + 3 + sum(range(32)) + 2


def _ptx(kernel, folder):
    """sm_90 PTX of `kernel`'s module by Warp's NVRTC (skipped where this Warp build has none:
    a plain module fails to compile too)."""
    try:
        (ptx,) = wp.compile_aot_module(kernel.module, arch=90, module_dir=folder, use_ptx=True)
    except Exception as error:  # noqa: BLE001 (Warp raises a plain Exception for a failed build)
        try:
            wp.compile_aot_module(_kernel(False).module, arch=90, module_dir=Path(folder) / "plain-check", use_ptx=True)
        except Exception:  # noqa: BLE001
            pytest.skip(f"no CUDA compiler in this Warp build: {error}")
        raise
    return Path(ptx).read_text()


def test_the_rewritten_code_compiles_for_cuda():
    """NVRTC compiles the rewritten module to sm_90 PTX (no GPU needed)."""
    with tempfile.TemporaryDirectory() as folder:
        assert ".entry" in _ptx(_kernel(True), Path(folder))


def _specs():
    """RunSpecs of bench.path's reach and map scenes as a GPU builds them (the core records, the replay follows)."""
    from bench.air import paper_scene
    from bench.path import LOG_CASES

    gpu = SimpleNamespace(is_cuda=True)
    return [
        RunSpec.of(paper_scene(1000, air=True, mu_s=0.5, extra=list(LOG_CASES[case][0])), with_output=False, device=gpu)
        for case in ("rough, reach", "map")
    ]


def test_the_reach_replay_no_longer_copies_its_parameters_to_local_memory(monkeypatch):
    """The reach's replay kernel in sm_90 PTX: its local depot (the per-thread copies of its
    parameters, mostly) shrinks from over 900 bytes to a few dozen when read in place."""
    from warp_ricochet.core.replay import replay_kernel_for

    kernel = replay_kernel_for(_specs()[0])

    def depot(folder):
        return sum(int(n) for n in re.findall(r"__local_depot\d+\[(\d+)\]", _ptx(kernel, folder)))

    with tempfile.TemporaryDirectory() as folder:
        in_place = depot(Path(folder) / "in_place")
        monkeypatch.setattr(codegen, "codegen_kernel", codegen.codegen_kernel.__wrapped__)
        plain = depot(Path(folder) / "plain")
    assert plain > 512 and in_place < 128, (plain, in_place)


def test_the_core_and_replay_kernels_read_their_parameters_in_place():
    """Every parameter of the core, shots and reach's replay kernels is read in place on CUDA (the
    rewrite did not fall back); the map's replay kernel's are not (slower so)."""
    from warp_ricochet.core.kernel import ricochet_kernel_for
    from warp_ricochet.core.replay import replay_kernel_for
    from warp_ricochet.core.shots import shot_kernel_for

    reach, mapped = _specs()
    assert reach.replay and not reach.hazard_map and mapped.hazard_map
    for kernel in (ricochet_kernel_for(reach), replay_kernel_for(reach), ricochet_kernel_for(mapped), shot_kernel_for(reach)):
        cuda = _source(kernel, "cuda")
        head = cuda[cuda.index("__global__") : cuda.index("{", cuda.index("__global__"))]
        assert head.count("__grid_constant__") == len(kernel.adj.args)
    assert "__grid_constant__" not in _source(replay_kernel_for(mapped), "cuda")


# a function of Warp's CUDA code: its parameters and its body
FUNCTION = re.compile(r"CUDA_CALLABLE [^\n(]*\(\n(.*?)\)\n\{\n(.*?)^\}$", re.M | re.S)


def _references(kernel):
    """(parameter, it may be written) of every struct that a function of `kernel`'s CUDA code takes
    by reference, of a type among the kernel's parameters'."""
    source, types = _source(kernel, "cuda"), {a.ctype() for a in kernel.adj.args}
    return [
        (name, gc._writes_param(body, name))
        for args, body in FUNCTION.findall(source)
        for ctype, name in re.findall(r"([\w:<>]+)& (var_\w+)", args)
        if ctype in types
    ]


@pytest.mark.parametrize("case", ["turf", "hazard", "box", "terrain"])
def test_no_function_writes_a_kernel_parameter_it_takes_by_reference(case, tmp_path):
    """A `__grid_constant__` parameter must never be written. In CUDA code the functions take the
    read-only structs by reference (`struct_refs`); in the generated code of `bench.kernel_size`'s
    scenes no function body may write one (`grid_constant._writes_param`: a field assigned, a store
    or in-place operation through a pointer into it)."""
    from bench.kernel_size import scene_of
    from warp_ricochet.core.kernel import ricochet_kernel_for
    from warp_ricochet.core.replay import replay_kernel_for
    from warp_ricochet.core.shots import shot_kernel_for

    spec = RunSpec.of(scene_of(case, tmp_path), with_output=False, device=SimpleNamespace(is_cuda=True))
    kernels = [ricochet_kernel_for(spec), shot_kernel_for(spec)] + ([replay_kernel_for(spec)] if spec.replay else [])
    for kernel in kernels:
        taken = _references(kernel)
        assert taken  # (the functions do take the kernel's structs by reference)
        assert [name for name, written in taken if written] == []


@wp.func
def _spoil(p: Pack):
    p.b[0] = 1.0  # (a write through the reference: what the package's functions never do)


def test_the_scan_finds_a_function_that_writes_a_struct_it_takes_by_reference():
    """The check above can fail: a function that writes a component of a struct it takes by
    reference is found in Warp's CUDA code (the kernel's own body does not show it)."""

    @wp.kernel(module="unique", enable_backward=False, module_options=gc.module_options())
    def spoils(p: Pack, out: wp.array(dtype=wp.float32)):
        _spoil(p)

    assert [name for name, written in _references(spoils) if written] == ["var_p"]
