"""Tests of warp_ricochet.scene: loading, validation, overrides, sweeps, ties and pellet files (no warp)."""

import copy
import dataclasses
import math
import os
import tomllib

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warp_ricochet.errors import SceneError
from warp_ricochet.scene import (
    CORE_FIELDS,
    MAX_SWEEP_POINTS,
    Numerics,
    Output,
    Physics,
    Scene,
    Shot,
    Surface,
    apply_override,
    load_pellet_file,
    load_scene,
    parse_sweep,
    parse_tie,
    scene_from_dict,
    set_dotted,
)

PAPER_TOML = """
[shot]
count = 450
diameter = 0.0025
density = 7000.0
speed = 411.48
direction = [1.0, -1.0, 0.0]
direction_jitter = [0.1, 0.1, 0.1]
envelope_radius = 0.025
envelope_center = [0.0, 1.0, 0.0]
spin = [0.0, 0.0, 0.0]
seed = 2021

[[surfaces]]
name = "ground"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
restitution = 0.01
mu_s = 0.5
mu_d = 0.45

[physics]
gravity = [0.0, -9.81, 0.0]
impact_duration = 1e-5
bounces = 1

[output]
fields = ["initial", "impact", "landing"]
"""
PAPER = tomllib.loads(PAPER_TOML)
ALL = tuple(
    f for f in CORE_FIELDS if not f.startswith("hazard.")
)  # the default: no hazard group (until = "rest": the rest group)


def paper():
    return copy.deepcopy(PAPER)


def minimal():
    return {"shot": {"count": 10, "diameter": 0.002, "density": 7000, "speed": 300}}


def write_pellets(path, n=4, **changes):
    rng = np.random.default_rng(1)
    arrays = {"position": rng.normal(size=(n, 3)), "velocity": rng.normal(size=(n, 3))}
    arrays.update(changes)
    arrays = {k: v for k, v in arrays.items() if v is not None}
    if str(path).endswith(".npz"):
        np.savez(path, **arrays)
    else:
        with h5py.File(path, "w") as f:
            for k, v in arrays.items():
                f[k] = v
    return arrays


# ------------------------------------------------------------------------------------------------ loading


def test_load_paper_scene(tmp_path):
    path = tmp_path / "paper.toml"
    path.write_text(PAPER_TOML)
    s = load_scene(path)
    assert s.source == str(path)
    assert s.shot == Shot(
        diameter=0.0025,
        density=7000.0,
        count=450,
        speed=411.48,
        direction=(1.0, -1.0, 0.0),
        direction_jitter=(0.1, 0.1, 0.1),
        envelope_radius=0.025,
        envelope_center=(0.0, 1.0, 0.0),
        spin=(0.0, 0.0, 0.0),
        seed=2021,
    )
    assert s.surfaces == (Surface((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 0.01, 0.5, 0.45, "ground"),)
    assert s.physics == Physics((0.0, -9.81, 0.0), 1e-5, 1)
    assert s.numerics == Numerics()
    assert s.output == Output(None, tuple(f for f in ALL if not f.startswith("rest.")))  # (the fields it names)


def test_defaults():
    s = scene_from_dict(minimal())
    assert s.surfaces == () and s.physics == Physics() and s.numerics == Numerics() and s.output == Output()
    assert s.physics.gravity == (0.0, -9.81, 0.0) and s.physics.bounces == 1
    assert s.shot.direction == (1.0, -1.0, 0.0) and s.shot.seed == 0 and s.shot.file is None
    assert isinstance(s.shot.speed, float) and isinstance(s.shot.density, float)
    assert s.output.fields == ALL and s.numerics.chunk_size is None and s.source == ""


def test_normal_normalised_and_mu_d_default():
    raw = paper()
    raw["surfaces"][0].update(normal=[3, 4, 0], mu_s=0.3)
    del raw["surfaces"][0]["mu_d"]
    surf = scene_from_dict(raw).surfaces[0]
    assert surf.normal == pytest.approx((0.6, 0.8, 0.0))
    assert surf.mu_d == 0.3 and surf.mu_d is not None


def test_jitter_scalar_and_fields_expansion():
    raw = paper()
    raw["shot"]["direction_jitter"] = 0.2
    raw["output"] = {"fields": ["landing.range", "initial", "landing.range"], "path": "out.h5"}
    s = scene_from_dict(raw)
    assert s.shot.direction_jitter == (0.2, 0.2, 0.2)
    assert s.output.fields == ("initial.position", "initial.velocity", "initial.angular_velocity", "landing.range")
    assert s.output.path == "out.h5"
    raw["output"]["fields"] = []
    assert scene_from_dict(raw).output.fields == ()


def test_load_errors(tmp_path):
    with pytest.raises(SceneError, match="cannot be read"):
        load_scene(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[shot\ncount = 1\n")
    with pytest.raises(SceneError, match="is not valid TOML") as e:
        load_scene(bad)
    assert "\n" not in str(e.value)


def test_round_trip(tmp_path):
    s = load_scene(_write(tmp_path, PAPER_TOML))
    assert scene_from_dict(s.to_dict()) == s
    assert tomllib.loads(s.to_toml()) == s.to_dict()
    assert scene_from_dict(tomllib.loads(s.to_toml())) == s
    empty = scene_from_dict(minimal())
    assert tomllib.loads(empty.to_toml()) == empty.to_dict() and empty.to_dict()["surfaces"] == []
    assert "path" not in empty.to_dict()["output"] and "chunk_size" not in empty.to_dict()["numerics"]
    odd = s.replace(surfaces=(dataclasses.replace(s.surfaces[0], name='a "q"\n\\ \x7f'),))
    assert scene_from_dict(tomllib.loads(odd.to_toml())) == odd


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-1e6, 1e6), min_size=3, max_size=3).filter(lambda v: math.hypot(*v) > 1e-9))
def test_normalisation_is_idempotent(normal):
    raw = paper()
    raw["surfaces"][0]["normal"] = normal
    s = scene_from_dict(raw)
    assert math.hypot(*s.surfaces[0].normal) == pytest.approx(1.0, abs=1e-15)
    assert scene_from_dict(s.to_dict()) == s


def _write(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


# ------------------------------------------------------------------------------------------------ overrides


def test_overrides(tmp_path):
    path = _write(tmp_path, PAPER_TOML)
    s = load_scene(
        path,
        [
            "shot.count=1000",
            "surfaces.0.mu_s=0.6",
            "physics.gravity=[0, -1, 0]",
            "output.path=out.h5",
            "numerics.precision=float64",
            "numerics.chunk_size = 64",
        ],
    )
    assert s.shot.count == 1000 and s.surfaces[0].mu_s == 0.6 and s.physics.gravity == (0.0, -1.0, 0.0)
    assert s.output.path == "out.h5" and s.numerics == Numerics("float64", 64)


def test_apply_override_is_a_copy_and_creates_tables():
    raw = minimal()
    new = apply_override(raw, "numerics.precision=float64")
    assert "numerics" not in raw and new["numerics"] == {"precision": "float64"}
    assert apply_override(raw, 'output.path="a b.h5"')["output"]["path"] == "a b.h5"
    assert set_dotted(raw, "a.b.c", [1])["a"] == {"b": {"c": [1]}}


@pytest.mark.parametrize(
    "assignment",
    [
        "surfaces.1.mu_s=0.3",
        "surfaces.x.mu_s=0.3",
        "surfaces.-1.mu_s=1",
        "shot.count.x=1",
        "no_equals_sign",
        "shot..count=1",
        "=3",
    ],
)
def test_bad_overrides(assignment):
    with pytest.raises(SceneError) as e:
        apply_override(paper(), assignment)
    assert "\n" not in str(e.value)
    assert assignment.partition("=")[0] in str(e.value)


def test_override_index_into_missing_list():
    with pytest.raises(SceneError, match="surfaces.0.mu_s"):
        apply_override(minimal(), "surfaces.0.mu_s=0.3")


# ------------------------------------------------------------------------------------------------ sweeps, ties


def test_parse_sweep_range():
    key, values = parse_sweep("surfaces.0.mu_s=0:0.5:0.05")
    assert key == "surfaces.0.mu_s"
    assert values == [0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5]
    assert values[3] == 0.15 and all(isinstance(v, float) for v in values)
    assert parse_sweep("x=0.5:0:-0.1")[1] == [0.5, 0.4, 0.3, 0.2, 0.1, 0.0]
    assert parse_sweep("x=-0.3:0.3:0.05")[1][6] == 0.0
    assert parse_sweep("physics.bounces=1:4:1")[1] == [1, 2, 3, 4]
    assert parse_sweep("x=1:1:0.1")[1] == [1.0]
    assert parse_sweep("x=0:1:0.3")[1] == [0.0, 0.3, 0.6, 0.9]  # never past stop
    assert len(parse_sweep("x=0:9999:1")[1]) == MAX_SWEEP_POINTS == 10_000  # the most a sweep may have


def test_parse_sweep_list():
    assert parse_sweep("shot.count=10,20,30") == ("shot.count", [10, 20, 30])
    key, values = parse_sweep("surfaces.0.mu_s=0.1, 0.2,1")
    assert values == [0.1, 0.2, 1.0] and all(isinstance(v, float) for v in values)
    assert parse_sweep("x=0.3") == ("x", [0.3])


@pytest.mark.parametrize(
    "spec",
    [
        "x=0:1:0",
        "x=0:1:-0.1",
        "x=1:0:0.1",
        "x=0:1",
        "x=0:1:0.1:2",
        "x=a,b",
        "x=0:1e6:0.001",
        "x=0:100000:1",
        "x=0:10000:1",
        "x=" + ",".join(["1"] * 10_001),
        "x=nan,1",
        "x=0:inf:1",
        "nokey",
        "=1,2",
        "x=",
        "x=1,,2",
    ],
)
def test_parse_sweep_errors(spec):
    with pytest.raises(SceneError) as e:
        parse_sweep(spec)
    assert "\n" not in str(e.value)


def test_parse_tie():
    assert parse_tie("surfaces.0.mu_d=0.9*") == ("surfaces.0.mu_d", 0.9, None)
    assert parse_tie("surfaces.0.mu_d=0.9*surfaces.0.mu_s") == ("surfaces.0.mu_d", 0.9, "surfaces.0.mu_s")
    assert parse_tie("surfaces.0.mu_d=*") == ("surfaces.0.mu_d", 1.0, None)
    assert parse_tie("a=2*b") == ("a", 2.0, "b") and isinstance(parse_tie("a=2*")[1], float)
    for bad in ["a=0.9", "a", "=0.9*", "a=x*", "a=nan*", "a=0.9*b..c"]:
        with pytest.raises(SceneError):
            parse_tie(bad)


# ------------------------------------------------------------------------------------------------ pellet files


@pytest.mark.parametrize("suffix", [".npz", ".h5", ".hdf5"])
def test_pellet_file(tmp_path, suffix):
    arrays = write_pellets(tmp_path / f"p{suffix}", n=5, extra=np.zeros(7))
    got = load_pellet_file(tmp_path / f"p{suffix}")
    assert set(got) == {"position", "velocity", "angular_velocity"}
    np.testing.assert_array_equal(got["position"], arrays["position"])
    assert got["angular_velocity"].shape == (5, 3) and not got["angular_velocity"].any()
    assert all(a.dtype == np.float64 for a in got.values())


def test_pellet_file_under_pellets_initial(tmp_path):
    with h5py.File(tmp_path / "out.h5", "w") as f:
        g = f.create_group("pellets/initial")
        g["position"] = np.ones((2, 3), np.float32)
        g["velocity"] = np.zeros((2, 3))
        g["angular_velocity"] = np.full((2, 3), 2.0)
    got = load_pellet_file(tmp_path / "out.h5")
    assert got["position"].dtype == np.float64 and (got["angular_velocity"] == 2).all()


def test_scene_with_pellet_file(tmp_path):
    write_pellets(tmp_path / "p.npz", n=7)
    raw = {"shot": {"diameter": 0.002, "density": 7000, "file": "p.npz"}}
    path = _write(tmp_path, "[shot]\ndiameter = 0.002\ndensity = 7000\nfile = 'p.npz'\ncount = 7\n")
    s = load_scene(path)
    assert s.shot.count == 7 and s.shot.file == os.path.abspath(tmp_path / "p.npz")
    assert scene_from_dict(s.to_dict()) == s and tomllib.loads(s.to_toml()) == s.to_dict()
    assert scene_from_dict(raw, base_dir=tmp_path).shot.count == 7
    with pytest.raises(SceneError, match="shot.count"):
        scene_from_dict(set_dotted(raw, "shot.count", 8), base_dir=tmp_path)
    with pytest.raises(SceneError, match="shot.speed.*not allowed together with shot.file"):
        scene_from_dict(set_dotted(raw, "shot.speed", 100), base_dir=tmp_path)
    with pytest.raises(SceneError, match="shot.file"):
        scene_from_dict(raw, base_dir=tmp_path / "elsewhere")


@pytest.mark.parametrize(
    "name, changes, key",
    [
        ("p.npz", {"velocity": np.zeros((5, 3))}, "shot.file:velocity"),
        ("p.h5", {"position": np.zeros((4, 2))}, "shot.file:position"),
        ("p.npz", {"position": np.zeros(12)}, "shot.file:position"),
        ("p.npz", {"position": np.array([[0, 0, 0], [np.nan, 0, 0], [0, 0, 0], [0, 0, 0]])}, "shot.file:position"),
        ("p.h5", {"velocity": np.full((4, 3), np.inf)}, "shot.file:velocity"),
        ("p.npz", {"velocity": None}, "shot.file:velocity"),
        ("p.h5", {"position": None}, "shot.file:position"),
        ("p.npz", {"position": np.zeros((0, 3)), "velocity": np.zeros((0, 3))}, "shot.file:position"),
        ("p.npz", {"angular_velocity": np.zeros((3, 3))}, "shot.file:angular_velocity"),
        ("p.npz", {"position": np.array([["a", "b", "c"]] * 4)}, "shot.file:position"),
        ("p.txt", {}, "shot.file"),
    ],
)
def test_bad_pellet_files(tmp_path, name, changes, key):
    write_pellets(tmp_path / name, **changes) if not name.endswith(".txt") else (tmp_path / name).write_text("x")
    with pytest.raises(SceneError) as e:
        load_pellet_file(tmp_path / name)
    assert key in str(e.value) and "\n" not in str(e.value)


def test_unreadable_pellet_files(tmp_path):
    for name in ["missing.npz", "garbage.npz", "garbage.h5"]:
        if name.startswith("garbage"):
            (tmp_path / name).write_bytes(b"not a real file\n" * 10)
        with pytest.raises(SceneError, match="shot.file") as e:
            load_pellet_file(tmp_path / name)
        assert "\n" not in str(e.value)


# ------------------------------------------------------------------------------------------------ bad scenes


def _set(key, value):
    return lambda raw: set_dotted(raw, key, value)


def _delete(*keys):
    def change(raw):
        node = raw
        for part in keys[:-1]:
            node = node[int(part)] if isinstance(node, list) else node[part]
        del node[keys[-1]]
        return raw

    return change


BAD = [
    ("surfaces.0.restitution", _set("surfaces.0.restitution", 1.5)),
    ("surfaces.0.restitution", _set("surfaces.0.restitution", -0.1)),
    ("surfaces.0.mu_d", _set("surfaces.0.mu_d", 0.6)),
    ("surfaces.0.mu_s", _set("surfaces.0.mu_s", -0.1)),
    ("shot.diameter", _set("shot.diameter", 0)),
    ("shot.diameter", _set("shot.diameter", -1)),
    ("shot.density", _set("shot.density", 0.0)),
    ("shot.speed", _set("shot.speed", 0)),
    ("shot.count", _set("shot.count", 0)),
    ("shot.count", _set("shot.count", 2**31)),
    ("shot.count", _set("shot.count", 1.5)),
    ("shot.count", _set("shot.count", 2.0**31)),  # integral (450.0 is 450), out of range
    ("shot.count", _set("shot.count", True)),
    ("shot.seed", _set("shot.seed", -1)),
    ("surfaces.0.normal", _set("surfaces.0.normal", [0, 0, 0])),
    ("shot.direction", _set("shot.direction", [0.0, 0.0, 0.0])),
    ("shot.direction_jitter", _set("shot.direction_jitter", [0.1, -0.1, 0.1])),
    ("shot.direction_jitter", _set("shot.direction_jitter", -0.1)),
    ("shot.envelope_radius", _set("shot.envelope_radius", -0.01)),
    ("shot.speed", _set("shot.speed", math.nan)),
    ("shot.speed", _set("shot.speed", math.inf)),
    ("physics.gravity", _set("physics.gravity", [0, -math.inf, 0])),
    ("physics.impact_duration", _set("physics.impact_duration", math.nan)),
    ("physics.impact_duration", _set("physics.impact_duration", 10**400)),
    ("physics.bounces", _set("physics.bounces", 0)),
    ("physics.bounces", _set("physics.bounces", 17)),
    ("numerics.precision", _set("numerics.precision", "float16")),
    ("numerics.chunk_size", _set("numerics.chunk_size", 0)),
    ("output.fields", _set("output.fields", ["landing", "bogus"])),
    ("output.fields", _set("output.fields", "landing")),
    ("output.fields", _set("output.fields", ["landing.speed"])),
    ("output.path", _set("output.path", 3)),
    ("colour", _set("colour", "red")),
    ("shot.colour", _set("shot.colour", 1)),
    ("surfaces.0.colour", _set("surfaces.0.colour", 1)),
    ("physics.colour", _set("physics.colour", 1)),
    ("numerics.colour", _set("numerics.colour", 1)),
    ("output.colour", _set("output.colour", 1)),
    ("shot.speed", _set("shot.speed", "fast")),
    ("shot.speed", _set("shot.speed", True)),
    ("surfaces.0.mu_s", _set("surfaces.0.mu_s", False)),
    ("shot.direction", _set("shot.direction", [1.0, -1.0])),
    ("shot.direction", _set("shot.direction", [1.0, True, 0.0])),
    ("shot.spin", _set("shot.spin", 1.0)),
    ("shot.envelope_center", _set("shot.envelope_center", "origin")),
    ("surfaces.0.name", _set("surfaces.0.name", 5)),
    ("surfaces", _set("surfaces", {"point": [0, 0, 0]})),
    ("surfaces.0", _set("surfaces.0", 3)),
    ("physics", _set("physics", 9.81)),
    ("shot", _set("shot", "pellets")),
    ("shot.diameter", _delete("shot", "diameter")),
    ("shot.count", _delete("shot", "count")),
    ("shot.speed", _delete("shot", "speed")),
    ("surfaces.0.normal", _delete("surfaces", "0", "normal")),
    ("shot", _delete("shot")),
    ('shot."a\\nb"', _set("shot", {**PAPER["shot"], "a\nb": 1})),
]


@pytest.mark.parametrize("key, change", BAD, ids=[f"{i}-{k}" for i, (k, _) in enumerate(BAD)])
def test_bad_scenes(key, change):
    with pytest.raises(SceneError) as e:
        scene_from_dict(change(paper()))
    assert key in str(e.value), str(e.value)
    assert "\n" not in str(e.value)
    assert str(e.value).startswith(e.value.key)


def test_messages():
    with pytest.raises(SceneError) as e:
        scene_from_dict(set_dotted(paper(), "surfaces.0.restitution", 1.5))
    assert str(e.value) == "surfaces.0.restitution = 1.5: must be a number in [0, 1]"
    with pytest.raises(SceneError, match="unknown key; did you mean shot.diameter[?] allowed keys: .*diameter"):
        scene_from_dict(set_dotted(paper(), "shot.diametre", 1))
    with pytest.raises(SceneError, match=r"^surfaces.0.mu = 1: unknown key; did you mean surfaces.0.mu_s\? allowed"):
        scene_from_dict(set_dotted(paper(), "surfaces.0.mu", 1))
    with pytest.raises(SceneError, match=r"^zzz = 1: unknown key; allowed keys: shot, "):  # nothing close: no guess
        scene_from_dict(set_dotted(paper(), "zzz", 1))
    with pytest.raises(SceneError, match="must be finite"):
        scene_from_dict(set_dotted(paper(), "shot.direction", [math.nan, 1, 0]))
    with pytest.raises(SceneError, match="is required"):
        scene_from_dict(_delete("surfaces", "0", "mu_s")(paper()))
    with pytest.raises(
        SceneError, match="allowed: initial, impact, landing, hazard, rest, collisions, release, initial.position"
    ):
        scene_from_dict(set_dotted(paper(), "output.fields", ["x"]))


# ------------------------------------------------------------------------------------------------ fuzz


def _known_keys():
    keys = list(PAPER) + ["numerics", "surfaces.0"]
    for table, cls in [("shot", Shot), ("surfaces.0", Surface), ("physics", Physics), ("numerics", Numerics), ("output", Output)]:
        keys += [f"{table}.{f.name}" for f in dataclasses.fields(cls)]
    return keys


JUNK = st.recursive(
    st.one_of(st.text(max_size=12), st.floats(allow_nan=True, allow_infinity=True), st.booleans(), st.integers()),
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=3)),
    max_leaves=8,
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(key=st.sampled_from(_known_keys()), value=JUNK)
def test_junk_gives_scene_or_scene_error(key, value):
    try:
        result = scene_from_dict(set_dotted(paper(), key, value))
    except SceneError as e:
        assert "\n" not in str(e)
    else:
        assert isinstance(result, Scene)
        assert scene_from_dict(result.to_dict()) == result


@pytest.mark.parametrize(
    "assignment, key",
    [
        ("shot.speed=1e39", "shot.speed"),
        ("shot.diameter=1e-46", "shot.diameter"),
        ("shot.diameter=2.0", "shot.diameter"),
        ("shot.density=1e9", "shot.density"),
        ("shot.direction=[1e308, -1e308, 0]", "shot.direction"),
        ("shot.envelope_radius=1e39", "shot.envelope_radius"),
        ("shot.spin=[0, 0, 1e9]", "shot.spin"),
        ("surfaces.0.point=[0, -1e39, 0]", "surfaces.0.point"),
        ("surfaces.0.mu_s=1e6", "surfaces.0.mu_s"),
        ("physics.gravity=[0, -1e5, 0]", "physics.gravity"),
        ("physics.impact_duration=10.0", "physics.impact_duration"),
    ],
)
def test_values_outside_the_physical_domain_are_rejected(tmp_path, assignment, key):
    """Finite in float64 is not enough: the domain keeps every float32 product finite."""
    path = tmp_path / "s.toml"
    path.write_text(PAPER_TOML)
    with pytest.raises(SceneError) as err:
        load_scene(path, [assignment])
    assert str(err.value).startswith(key) and "\n" not in str(err.value)


def test_pellet_file_values_outside_the_domain_are_rejected(tmp_path):
    path = tmp_path / "p.npz"
    np.savez(path, position=[[0.0, 1e39, 0.0]], velocity=[[1.0, -1.0, 0.0]])
    with pytest.raises(SceneError, match="shot.file:position"):
        load_pellet_file(path)
    np.savez(path, position=[[0.0, 1.0, 0.0]], velocity=[[1.0, -1e6, 0.0]])
    with pytest.raises(SceneError, match="shot.file:velocity"):
        load_pellet_file(path)


def test_every_example_scene_loads_and_the_paper_stays_in_vacuum():
    """examples/*.toml are valid scenes; the paper's has no [air], the realistic ones in air do."""
    from pathlib import Path

    from warp_ricochet.scene import load_scene

    scenes = {p.stem: load_scene(p) for p in sorted((Path(__file__).resolve().parents[1] / "examples").glob("*.toml"))}
    assert scenes["paper"].air is None and scenes["steel_plate"].air is None
    assert scenes["field"].air is not None and scenes["steel_plate_air"].air.drag == "table"


def test_an_integer_written_as_a_float_is_an_integer(tmp_path):
    """TOML reads 1e6 as a float: an integral one is the integer; 1.5 and 1e300 are still refused."""
    path = tmp_path / "s.toml"
    path.write_text(PAPER_TOML)
    scene = load_scene(path, ["shot.count=1e6", "physics.bounces=2.0"])
    assert (scene.shot.count, scene.physics.bounces) == (1_000_000, 2)
    assert type(scene.shot.count) is int and scene.to_dict()["shot"]["count"] == 1_000_000
    for assignment, shown in (("shot.count=1.5", "1.5"), ("shot.count=1e300", "1e+300"), ("shot.seed=-1.0", "-1.0")):
        with pytest.raises(SceneError, match=r"^shot\.\w+ = " + shown.replace("+", r"\+") + ": must be an integer in"):
            load_scene(path, [assignment])


def test_an_unknown_key_given_with_set_gets_a_suggestion(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(PAPER_TOML)
    with pytest.raises(
        SceneError,
        match=r"^numerics\.precisoin = 'float64': unknown key; did you mean "
        r"numerics\.precision\? allowed keys: precision, ",
    ):
        load_scene(path, ['numerics.precisoin="float64"'])


@pytest.mark.parametrize("layout", ["npz", "npz-fortran", "h5"])
def test_pellet_files_are_read_and_checked_in_pieces(tmp_path, monkeypatch, layout):
    """Pieces of 4 rows (PIECE_ROWS): the arrays come back whole, in C or Fortran order, and the first
    bad pellet is named with its values wherever it lies (a later column's earlier row first)."""
    from warp_ricochet.scene import pellets

    monkeypatch.setattr(pellets, "PIECE_ROWS", 4)
    rng = np.random.default_rng(7)
    arrays = {
        "position": rng.normal(size=(11, 3)),
        "velocity": rng.normal(size=(11, 3)).astype(np.float32),
        "angular_velocity": rng.integers(-5, 5, size=(11, 3)),
    }
    order = "F" if layout == "npz-fortran" else "C"
    path = tmp_path / ("p.h5" if layout == "h5" else "p.npz")

    def write(arrays):
        arrays = {k: np.asarray(v, order=order) for k, v in arrays.items()}
        if layout == "h5":
            with h5py.File(path, "w") as f:
                for k, v in arrays.items():
                    f.create_dataset(k, data=v, chunks=(2, 3))
        else:
            np.savez(path, **arrays)

    write(arrays)
    got = load_pellet_file(path)
    for name, values in arrays.items():
        np.testing.assert_array_equal(got[name], values.astype(np.float64))
    bad = {k: v.copy() for k, v in arrays.items()}
    bad["position"][9, 0] = 2e6  # out of the domain, in the first column of a later piece
    bad["position"][6, 2] = np.inf  # not finite, in the last column of an earlier piece: the first bad pellet
    write(bad)
    with pytest.raises(SceneError, match=r"^shot.file:position = \[.*, inf\]: must be finite \(pellet 6\)$"):
        load_pellet_file(path)


@pytest.mark.parametrize(
    ("solid", "inside", "near", "outside"),
    [
        (
            {"kind": "cylinder", "point": [2.0, 0.5, 0.0], "radius": 0.15, "length": 1.0},
            [2.1, 1.4, 0.05],
            [2.1, 1.51, 0.0],  # 0.01 m above the top cap
            [2.1, 1.6, 0.0],
        ),
        (
            {"kind": "box", "point": [2.0, 1.0, 0.0], "axis_u": [0.6, 0.0, 0.8], "size": [1.0, 0.4, 2.0]},
            [2.1, 1.9, 0.3],
            [2.0, 2.01, 0.0],  # 0.01 m above the top
            [2.0, 1.0, 0.6],
        ),
    ],
    ids=["post", "box"],
)
def test_a_launch_envelope_inside_a_solid_is_refused(solid, inside, near, outside):
    """A post or a box is met from outside only: pellets launched inside one fly through it as if it
    were not there (a post placed over the shooter by a typo gave a run with no word of it). A scene
    whose envelope (the paper's, radius 0.025 m) reaches into one is refused in one line naming
    shot.envelope_center, its value, the solid and how deep it reaches; one clear of it is not."""
    raw = tomllib.loads(PAPER_TOML)
    raw["surfaces"].append({**solid, "name": "obstacle", "normal": [0.0, 1.0, 0.0], "restitution": 0.3, "mu_s": 0.2})
    for centre, where, depth in ((inside, "is inside", None), (near, "is 0.01 m from", "0.015 m")):
        raw["shot"]["envelope_center"] = centre
        with pytest.raises(SceneError) as e:
            scene_from_dict(raw)
        message = str(e.value)
        assert message.startswith(f"shot.envelope_center = {centre}: {where} surfaces.1 ('obstacle'"), message
        assert "\n" not in message and solid["kind"] in message and (depth is None or f"reaches {depth} into it" in message)
    raw["shot"]["envelope_center"] = outside
    assert scene_from_dict(raw).shot.envelope_center == tuple(outside)
