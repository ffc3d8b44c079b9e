"""What a scene's solids compile into its kernels (`spec._plates`, `physics.geometry`'s NO_POSTS,
SMALL, NO_EDGES and FLAT): only the code they need, and all of it whenever they need it."""

from pathlib import Path

from warp_ricochet.physics.geometry import FLAT, MESHES, NO_EDGES, NO_POSTS, SMALL, solid_needs
from warp_ricochet.scene import scene_from_dict
from warp_ricochet.spec import RunSpec

EXAMPLES = Path(__file__).resolve().parent.parent / "warp_ricochet" / "examples"
GROUND = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "restitution": 0.5, "mu_s": 0.2}
BOX = {"kind": "box", "point": [5.0, 0.0, 0.5], "normal": [0.0, 0.0, 1.0], "axis_u": [1.0, 0.0, 0.0], "size": [1.0, 1.0, 1.0]}
POST = {"kind": "cylinder", "point": [10.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "radius": 0.1, "length": 2.0}
PLATE = {"kind": "rectangle", "point": [5.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "axis_u": [1.0, 0.0, 0.0], "size": [2.0, 2.0]}


def _strip(folder: Path, triangles: int) -> str:
    """An OBJ file of a strip of `triangles` triangles in the plane z = 0 (normals +z)."""
    columns = triangles // 2 + 1
    lines = [f"v {i} {j} 0" for i in range(columns) for j in (0, 1)]
    lines += [f"f {2 * i + 1} {2 * i + 3} {2 * i + 4}\nf {2 * i + 1} {2 * i + 4} {2 * i + 2}" for i in range(columns - 1)]
    path = folder / f"strip{triangles}.obj"
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def _plates(surfaces):
    shot = {"count": 4, "diameter": 0.0025, "density": 7000.0, "speed": 300.0, "direction": [1.0, 0.0, 0.0]}
    shot |= {"envelope_radius": 0.01, "envelope_center": [0.0, 0.0, 1.0]}
    raw = {"shot": shot, "surfaces": surfaces, "physics": {"until": "landing", "gravity": [0, 0, -9.81]}}
    return RunSpec.of(scene_from_dict(raw), with_output=False).plates


def test_each_scene_compiles_the_solids_it_has(tmp_path):
    small, large = _strip(tmp_path, 2), _strip(tmp_path, 40)
    mesh = {**GROUND, "kind": "mesh", "point": [0.0, 0.0, 0.0]}
    assert not _plates([GROUND])
    assert _plates([GROUND, {**PLATE, **{k: GROUND[k] for k in ("restitution", "mu_s")}}]) is True
    cases = [
        ([GROUND, {**BOX, "restitution": 0.5, "mu_s": 0.2}], MESHES | NO_POSTS | SMALL),
        ([GROUND, {**mesh, "file": small}], MESHES | NO_POSTS | SMALL | FLAT),  # (a flat strip)
        ([GROUND, {**mesh, "file": small}, {**BOX, "restitution": 0.5, "mu_s": 0.2}], MESHES | NO_POSTS | SMALL),
        ([GROUND, {**mesh, "file": large}], MESHES | NO_POSTS),
        ([GROUND, {**POST, "restitution": 0.5, "mu_s": 0.2}], MESHES | SMALL | NO_EDGES),
        ([GROUND, {**POST, "restitution": 0.5, "mu_s": 0.2}, {**mesh, "file": large}], MESHES),
    ]
    for surfaces, expected in cases:
        assert _plates(surfaces) == expected, surfaces
    terrain = {**GROUND, "kind": "terrain", "file": str(EXAMPLES / "terrain" / "trap_field.asc"), "normal": [0.0, 0.0, 1.0]}
    assert _plates([terrain, GROUND]) == MESHES | NO_POSTS | NO_EDGES
    assert solid_needs(MESHES) == (True, True, True, False)  # MESHES alone: everything, as before the flags
    assert solid_needs(MESHES | NO_POSTS | SMALL | FLAT) == (False, False, True, True)


def test_only_a_leaning_post_followed_to_rest_compiles_the_side_motion():
    """LEANING (`physics.side_follow` compiled in) for a post leaning from gravity in a run to rest;
    not for a vertical post (either way up), nor for a leaning one followed to its landing."""
    from warp_ricochet.physics.geometry import LEANING

    def plates(normal, until):
        shot = {"count": 4, "diameter": 0.0025, "density": 7000.0, "speed": 300.0, "direction": [1.0, 0.0, 0.0]}
        shot |= {"envelope_radius": 0.01, "envelope_center": [0.0, 0.0, 1.0]}
        post = {**POST, "normal": normal, "point": [10.0, 0.0, -0.5], "restitution": 0.5, "mu_s": 0.2}
        raw = {"shot": shot, "surfaces": [GROUND, post], "physics": {"until": until, "gravity": [0, 0, -9.81]}}
        return RunSpec.of(scene_from_dict(raw), with_output=False).plates

    assert plates([0.0, 0.5, 0.866], "rest") & LEANING
    assert not plates([0.0, 0.0, 1.0], "rest") & LEANING
    assert not plates([0.0, 0.0, -1.0], "rest") & LEANING
    assert not plates([0.0, 0.5, 0.866], "landing") & LEANING


def test_landing_kernels_among_solids_take_their_register_caps_and_block_sizes(tmp_path):
    """`core.kernel.kernel_options` and `block_dim_for`: AIR_SOLIDS_MAX_REGISTERS where a float32
    kernel with fast maths flies in air among meshes or posts to the landing; SMALL_SOLIDS_MAX_REGISTERS
    and SMALL_SOLIDS_BLOCK_DIM threads a block where it flies in vacuum among small solids only (a
    box, a post) to the landing without a hazard map; the plain cap and CUDA_BLOCK_DIM elsewhere
    (over planes only, a large mesh, to rest, with a map, float64)."""
    from warp_ricochet.core.kernel import (
        AIR_SOLIDS_MAX_REGISTERS,
        CUDA_BLOCK_DIM,
        CUDA_MAX_REGISTERS,
        SMALL_SOLIDS_BLOCK_DIM,
        SMALL_SOLIDS_MAX_REGISTERS,
        block_dim_for,
        kernel_options,
    )

    def spec(surfaces, air, until="landing", precision="float32", hazard=False):
        shot = {"count": 4, "diameter": 0.0025, "density": 7000.0, "speed": 300.0, "direction": [1.0, 0.0, 0.0]}
        shot |= {"envelope_radius": 0.01, "envelope_center": [0.0, 0.0, 1.0]}
        raw = {"shot": shot, "surfaces": surfaces, "physics": {"until": until, "gravity": [0, 0, -9.81]}}
        raw["numerics"] = {"precision": precision}
        if air:
            raw["air"] = {}
        if hazard:
            raw["hazard"] = {"speed": {"skin_perforation": 101.0}, "map_cell": 1.0, "map_extent": [0.0, 20.0, -5.0, 5.0]}
        return RunSpec.of(scene_from_dict(raw), with_output=False)

    def cap_and_block(*args, **kwargs):
        s = spec(*args, **kwargs)
        return kernel_options(s).get("cuda_max_registers"), block_dim_for(s)

    box, post = {**BOX, "restitution": 0.5, "mu_s": 0.2}, {**POST, "restitution": 0.5, "mu_s": 0.2}
    large = {"kind": "mesh", "file": _strip(tmp_path, 40), "restitution": 0.5, "mu_s": 0.2}
    air_cap, small_cap = AIR_SOLIDS_MAX_REGISTERS["float32", True], SMALL_SOLIDS_MAX_REGISTERS["float32", True]
    plain = CUDA_MAX_REGISTERS["float32", True], CUDA_BLOCK_DIM
    assert len({air_cap, small_cap, plain[0]}) == 3 and SMALL_SOLIDS_BLOCK_DIM != CUDA_BLOCK_DIM
    assert cap_and_block([GROUND, box], air=True) == (air_cap, CUDA_BLOCK_DIM)
    assert cap_and_block([GROUND, box], air=False) == (small_cap, SMALL_SOLIDS_BLOCK_DIM)
    assert cap_and_block([GROUND, post], air=False) == (small_cap, SMALL_SOLIDS_BLOCK_DIM)
    assert cap_and_block([GROUND], air=True) == plain
    assert cap_and_block([GROUND], air=False) == plain
    assert cap_and_block([GROUND, large], air=False) == plain
    assert cap_and_block([GROUND, box], air=True, until="rest") == plain
    assert cap_and_block([GROUND, box], air=False, until="rest") == plain
    assert cap_and_block([GROUND, box], air=False, precision="float64")[1] == CUDA_BLOCK_DIM
    assert spec([GROUND, box], air=False, hazard=True).hazard_map
    assert cap_and_block([GROUND, box], air=False, hazard=True) == plain
