"""Bad input, property-based: every malformed scene value, override, pellet file, output path or
device given to the command line is rejected before any work, in one line on stderr that names the
key (`warp-ricochet: error: KEY = VALUE: what is allowed`), with exit status 2, no traceback, nothing
on stdout, and no file created or touched: an existing output file given with --overwrite keeps its
bytes and its modification time, and no NAME.partial appears.

The allowed domain is restated here (README "Scenes") rather than read from warp_ricochet.scene, so
a validator that stops checking something makes these tests fail. `main()` runs in-process (a few
milliseconds a call) with `api.run_pipeline` replaced by a trap: reaching it means work began.
"""

import contextlib
import io
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from warp_ricochet import api, chunks
from warp_ricochet.cli import main
from warp_ricochet.errors import SceneError
from warp_ricochet.scene import scene_from_dict
from warp_ricochet.scene.toml_out import (
    toml_value,  # TOML text of any value (NaN, inf too)
)

PREFIX = "warp-ricochet: error: "
MATERIALS = {
    f"{m}{end}"
    for m in ("steel_plate", "concrete", "packed_soil", "turf", "sand", "gravel", "water")
    for end in ("", ":far", ":near")
}
SETTINGS = settings(
    max_examples=150,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

# a small valid scene (the paper's, 64 pellets): every test below breaks exactly one thing in it
VALID = {
    "shot": {
        "count": 64,
        "diameter": 0.0025,
        "density": 7000.0,
        "speed": 411.48,
        "direction": [1.0, -1.0, 0.0],
        "direction_jitter": [0.1, 0.1, 0.1],
        "envelope_radius": 0.025,
        "envelope_center": [0.0, 1.0, 0.0],
        "spin": [0.0, 0.0, 0.0],
        "seed": 2021,
        "shots": 1,
    },
    "surfaces": [
        {"name": "ground", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.01, "mu_s": 0.5, "mu_d": 0.45}
    ],
    "physics": {"gravity": [0.0, -9.81, 0.0], "impact_duration": 1e-5, "bounces": 1},
    "numerics": {"precision": "float64", "chunk_size": 65536, "fast_math": True, "flight_tolerance": 1e-6},
    "output": {"fields": ["landing"]},
    "collisions": {
        "enabled": False,
        "restitution": 0.9,
        "mu_s": 0.74,
        "mu_d": 0.57,
        "contact_duration": 1e-6,
        "time_step": 1e-6,
        "step_fraction": 0.25,
        "skin": 2.0,
        "rounds": 4,
        "max_neighbours": 32,
        "max_steps": 1000000,
        "frame_every": 0,
        "air_step_fraction": 0.01,
    },
    "air": {
        "density": 1.225,
        "viscosity": 1.789e-5,
        "sound_speed": 340.3,
        "wind": [0.0, 0.0, 0.0],
        "drag": "loth2021",
        "drag_factor": 1.0,
        "magnus": True,
        "lift": "loth2008",
        "spin_decay": True,
        "spin_decay_law": "dennis1980",
    },
}

# the domain, as documented: key -> (lowest, highest, lowest excluded)
REALS = {
    "shot.diameter": (1e-6, 1.0, False),
    "shot.density": (1.0, 1e5, False),
    "shot.speed": (0.0, 1e5, True),
    "shot.envelope_radius": (0.0, 1e6, False),
    "surfaces.0.restitution": (0.0, 1.0, False),
    "surfaces.0.mu_s": (0.0, 100.0, False),
    "surfaces.0.mu_d": (0.0, 0.5, False),  # mu_d <= mu_s = 0.5
    # the ground materials' keys (docs/ground.md, section 10), allowed on a surface without a material too
    "surfaces.0.rolling_resistance": (0.0, 1.0, False),
    "surfaces.0.ploughing": (0.0, 2e4, False),
    "surfaces.0.ploughing_area": (0.0, 1.0, False),
    "surfaces.0.critical_angle": (0.0, 90.0, False),
    "surfaces.0.critical_angle_rise": (0.0, 90.0, False),
    "surfaces.0.critical_speed": (0.0, 1e5, False),
    "surfaces.0.roughness": (0.0, 15.0, False),
    "surfaces.0.restitution_scatter": (0.0, 1.0, False),
    "surfaces.0.friction_scatter": (0.0, 1.0, False),
    "surfaces.0.skip_loss": (0.0, 10.0, False),
    "physics.impact_duration": (0.0, 1.0, False),
    "collisions.restitution": (0.0, 1.0, False),
    "collisions.mu_s": (0.0, 100.0, False),
    "collisions.mu_d": (0.0, 0.74, False),  # mu_d <= mu_s = 0.74
    "collisions.contact_duration": (0.0, 1.0, False),
    "collisions.time_step": (0.0, 1.0, True),
    "collisions.step_fraction": (0.0, 1.0, True),
    "collisions.skin": (0.0, 10.0, True),
    "collisions.air_step_fraction": (0.0, 1.0, True),
    "air.density": (0.0, 100.0, False),
    "air.viscosity": (0.0, 1.0, True),
    "air.sound_speed": (1.0, 1e4, False),
    "air.drag_factor": (0.0, 10.0, True),
    "numerics.flight_tolerance": (1e-12, 1e-2, False),
    "numerics.surface_tolerance": (1e-12, 1e-2, False),
}
INTEGERS = {
    "shot.count": (1, 2**31 - 1),
    "shot.seed": (0, 2**31 - 1),
    "physics.bounces": (1, 16),
    "numerics.chunk_size": (1, 2**31 - 1),
    "shot.shots": (1, 2**31 - 1),
    "collisions.rounds": (1, 64),
    "collisions.max_neighbours": (1, 256),
    "collisions.max_steps": (1, 2**31 - 1),
    "collisions.frame_every": (0, 2**31 - 1),
}
VECTORS = {
    "shot.direction": 1e6,
    "shot.direction_jitter": 1e6,
    "shot.envelope_center": 1e6,
    "shot.spin": 1e8,
    "surfaces.0.point": 1e6,
    "surfaces.0.normal": 1e6,
    "physics.gravity": 1e4,
    "air.wind": 1e3,
}
REQUIRED = [
    "shot.diameter",
    "shot.density",
    "shot.count",
    "shot.speed",
    "surfaces.0.point",
    "surfaces.0.normal",
    "surfaces.0.restitution",
    "surfaces.0.mu_s",
]
TABLES = {
    "shot": list(VALID["shot"]) + ["file"],
    "surfaces.0": list(VALID["surfaces"][0]),
    "physics": list(VALID["physics"]),
    "numerics": list(VALID["numerics"]),
    "output": ["path", "fields"],
    "collisions": list(VALID["collisions"]),
    "air": list(VALID["air"]) + ["drag_coefficient", "drag_table", "lift_slope", "lift_max"],
    "": list(VALID),
}
FIELDS = {"initial", "impact", "landing"} | {
    f"{g}.{f}"
    for g, fs in {
        "initial": ("position", "velocity", "angular_velocity"),
        "impact": (
            "time",
            "position",
            "velocity_before",
            "angular_velocity_before",
            "velocity",
            "angular_velocity",
            "slipped",
            "surface",
        ),
        "landing": ("time", "position", "velocity", "range", "surface"),
    }.items()
    for f in fs
}


# ---------------------------------------------------------------------------------------------- harness


def toml_document(raw: dict) -> str:
    """Top-level keys only, tables inline: any value goes anywhere."""
    return "".join(f"{json.dumps(key, ensure_ascii=False)} = {toml_value(value)}\n" for key, value in raw.items())


def set_path(raw, dotted, value=None, *, delete=False):
    """A deep copy of raw with dotted (numeric parts index lists) set to value, or deleted."""
    raw = json.loads(json.dumps(raw))
    *parents, last = dotted.split(".")
    node = raw
    for part in parents:
        node = node[int(part)] if isinstance(node, list) else node[part]
    if isinstance(node, list):
        last = int(last)
    if delete:
        del node[last]
    else:
        node[last] = value
    return raw


class Workspace:
    """A folder holding a valid scene file and a precious existing output file."""

    PRECIOUS = b"an earlier result that must survive\n"

    def __init__(self, root: Path):
        self.root = root
        self.scene = root / "scene.toml"
        self.scene.write_text(toml_document(VALID))
        self.output = root / "out.h5"
        self.output.write_bytes(self.PRECIOUS)
        os.utime(self.output, ns=(1_000_000_000, 1_000_000_000))
        self.listing = sorted(os.listdir(root))

    def write_scene(self, raw: dict) -> str:
        path = self.root / "bad.toml"
        path.write_text(toml_document(raw))
        self.listing = sorted(os.listdir(self.root))
        return str(path)

    def untouched(self):
        assert self.output.read_bytes() == self.PRECIOUS
        assert self.output.stat().st_mtime_ns == 1_000_000_000
        assert sorted(os.listdir(self.root)) == self.listing  # no NAME.partial, nothing else


@pytest.fixture
def ws(tmp_path, monkeypatch):
    def work_began(*args, **kwargs):
        raise AssertionError("bad input reached the simulation")

    monkeypatch.setattr(api, "run_pipeline", work_began)
    return Workspace(tmp_path)


def cli(argv):
    """main(argv) in-process: (status, stdout, stderr); any exception escaping is a traceback."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse usage errors
            rc = exc.code
    return rc, out.getvalue(), err.getvalue()


def assert_rejected(result, key, ws=None):
    rc, out, err = result
    lines = err.splitlines()
    assert rc == 2, (rc, err)
    assert out == ""
    assert len(lines) == 1 and lines[0].startswith(PREFIX), err
    assert "Traceback" not in err
    message = lines[0][len(PREFIX) :]
    assert message.startswith(f"{key} = "), (key, message)  # KEY = VALUE: what is allowed
    assert ": " in message[len(key) + 3 :], message
    if ws is not None:
        ws.untouched()
    return message


def run_args(ws, scene=None, *extra):
    return ["run", scene or ws.scene, "--device", "cpu", "-o", ws.output, "--overwrite", *extra]


# ---------------------------------------------------------------------------------------------- malformed values

# no digits: a string with a number is a value with its unit (scene.units; tests/test_units.py)
TEXT = st.text(alphabet=st.characters(blacklist_categories=("Cs", "Nd")), max_size=8)
NOT_A_NUMBER = st.one_of(
    TEXT,
    st.booleans(),
    st.lists(st.floats(-10, 10), max_size=3),
    st.dictionaries(st.sampled_from("abc"), st.integers(0, 3), max_size=2),
)
NON_FINITE = st.sampled_from([math.nan, math.inf, -math.inf])


@st.composite
def bad_real(draw, lo, hi, lo_open):
    kind = draw(st.sampled_from(["type", "nonfinite", "below", "above"]))
    if kind == "type":
        return draw(NOT_A_NUMBER)
    if kind == "nonfinite":
        return draw(NON_FINITE)
    if kind == "below":  # lo itself too where it is excluded
        return draw(st.one_of(st.floats(-1e300, lo, exclude_max=not lo_open), st.integers(-(2**63), math.ceil(lo) - 1)))
    return draw(st.one_of(st.floats(hi, 1e300, exclude_min=True), st.integers(int(hi) + 1, 2**63 - 1)))


@st.composite
def bad_integer(draw, lo, hi):
    kind = draw(st.sampled_from(["type", "float", "nonfinite", "out"]))
    if kind == "type":
        return draw(st.one_of(TEXT, st.booleans(), st.lists(st.integers(), max_size=2)))
    if kind == "float":
        # a float is refused unless it is an integer in range (TOML's 1e6 is one: tests/test_scene.py)
        return draw(st.floats(-1e12, 1e12).filter(lambda x: not (x.is_integer() and lo <= x <= hi)))
    if kind == "nonfinite":
        return draw(NON_FINITE)
    return draw(st.one_of(st.integers(-(2**63), lo - 1), st.integers(hi + 1, 2**63 - 1)))


@st.composite
def bad_vector(draw, bound):
    kind = draw(st.sampled_from(["length", "type", "element", "nonfinite", "bound", "empty"]))
    if kind == "length":
        return draw(st.lists(st.floats(-1, 1), min_size=4, max_size=6) | st.lists(st.floats(-1, 1), min_size=1, max_size=2))
    if kind == "type":
        return draw(st.one_of(TEXT, st.dictionaries(st.sampled_from("xyz"), st.floats(-1, 1), max_size=3)))
    if kind == "empty":
        return []
    v = [0.5, -0.5, 0.25]
    i = draw(st.integers(0, 2))
    if kind == "element":
        v[i] = draw(st.one_of(TEXT, st.booleans(), st.lists(st.floats(-1, 1), max_size=2)))
    elif kind == "nonfinite":
        v[i] = draw(NON_FINITE)
    else:
        v[i] = draw(st.floats(bound, 1e300, exclude_min=True)) * draw(st.sampled_from([1, -1]))
    return v


def malformed():
    """(key, bad value) for every kind of scene value."""
    cases = [st.tuples(st.just(k), bad_real(*r)) for k, r in REALS.items()]
    cases += [st.tuples(st.just(k), bad_integer(*r)) for k, r in INTEGERS.items()]
    cases += [st.tuples(st.just(k), bad_vector(b)) for k, b in VECTORS.items()]
    cases += [
        st.tuples(
            st.just("numerics.precision"),
            st.one_of(TEXT.filter(lambda s: s not in ("float32", "float64")), st.integers(), st.just(["float32"])),
        ),
        st.tuples(st.just("numerics.fast_math"), st.one_of(TEXT, st.integers(), st.floats(), st.just([]))),
        st.tuples(
            st.just("output.fields"),
            st.one_of(
                st.lists(TEXT.filter(lambda s: s not in FIELDS), min_size=1, max_size=3),
                st.lists(st.integers(), min_size=1, max_size=2),
                TEXT,
                st.integers(),
                st.just([[]]),
            ),
        ),
        st.tuples(st.just("output.path"), st.one_of(st.integers(), st.just(""), st.just([]), st.just("a\x00.h5"))),
        st.tuples(st.just("surfaces.0.name"), st.one_of(st.integers(), st.floats(), st.lists(TEXT, max_size=2))),
        st.tuples(
            st.just("surfaces.0.material"),
            st.one_of(TEXT.filter(lambda s: s not in MATERIALS), st.integers(), st.floats(), st.just(["turf"])),
        ),
        st.tuples(
            st.sampled_from(["air.drag", "air.lift", "air.spin_decay_law"]),
            st.one_of(
                TEXT.filter(
                    lambda s: s not in ("loth2021", "constant", "table", "loth2008", "linear", "sawicki2003", "dennis1980")
                ),
                st.integers(),
                st.just([]),
            ),
        ),
        st.tuples(st.sampled_from(["air.magnus", "air.spin_decay"]), st.one_of(TEXT, st.integers(), st.floats())),
        st.tuples(
            st.just("air.drag_table"),
            st.one_of(
                TEXT.filter(lambda s: s not in ("braun", "gs")),
                st.integers(),
                st.just([]),
                st.just([[0.0, 0.5]]),
                st.just([[0.5, 0.5], [0.4, 0.6]]),
                st.just([[0.0, -1.0], [1.0, 0.5]]),
                st.just([[0.0, 0.5, 1.0], [1.0, 0.5]]),
            ),
        ),
        st.tuples(
            st.sampled_from(["shot", "physics", "numerics", "output", "surfaces.0", "air"]),
            st.one_of(TEXT, st.integers(), st.floats(), st.lists(st.integers(), max_size=2)),
        ),
        st.tuples(
            st.just("surfaces"),
            st.one_of(TEXT, st.integers(), st.dictionaries(st.sampled_from("ab"), st.integers(), min_size=1, max_size=2)),
        ),
    ]
    return st.one_of(cases)


@SETTINGS
@given(case=malformed(), via_set=st.booleans())
def test_malformed_scene_values_are_one_line_errors_before_any_work(ws, case, via_set):
    key, value = case
    if via_set:
        result = cli(run_args(ws, None, "--set", f"{key}={toml_value(value)}"))
    else:
        result = cli(run_args(ws, ws.write_scene(set_path(VALID, key, value))))
    message = assert_rejected(result, key, ws)
    if key in REALS and isinstance(value, float) and not math.isfinite(value):
        assert "finite" in message


@SETTINGS
@given(key=st.sampled_from(REQUIRED), via_set=st.booleans())
def test_missing_keys_are_named(ws, key, via_set):
    raw = set_path(VALID, key, delete=True)
    if via_set:  # the override replaces the whole table without the key
        table, _, name = key.rpartition(".")
        parent = raw
        for part in table.split("."):
            parent = parent[int(part)] if isinstance(parent, list) else parent[part]
        result = cli(run_args(ws, None, "--set", f"{table}={toml_value(parent)}"))
    else:
        result = cli(run_args(ws, ws.write_scene(raw)))
    assert "is required" in assert_rejected(result, key, ws)


@SETTINGS
@given(
    table=st.sampled_from(sorted(TABLES)),
    name=st.from_regex(r"[a-z_][a-z0-9_-]{0,10}", fullmatch=True),
    value=st.one_of(st.integers(), TEXT, st.booleans()),
    via_set=st.booleans(),
)
def test_unknown_keys_are_named(ws, table, name, value, via_set):
    assume(name not in TABLES[table])
    key = f"{table}.{name}" if table else name
    if via_set:
        result = cli(run_args(ws, None, "--set", f"{key}={toml_value(value)}"))
    else:
        result = cli(run_args(ws, ws.write_scene(set_path(VALID, key, value))))
    assert "unknown key" in assert_rejected(result, key, ws)


@SETTINGS
@given(mu_s=st.floats(0.0, 100.0), excess=st.floats(1e-9, 50.0))
def test_mu_d_above_mu_s_is_named(ws, mu_s, excess):
    raw = set_path(set_path(VALID, "surfaces.0.mu_s", mu_s), "surfaces.0.mu_d", mu_s + excess * max(mu_s, 1.0))
    assert_rejected(cli(run_args(ws, ws.write_scene(raw))), "surfaces.0.mu_d", ws)


def test_a_float32_step_counter_past_2_to_the_24_is_named(ws):
    """In float32 a shot's step counter is a float32, exact up to 2^24 steps: a
    collisions.max_steps whose checkpoint comes later (the counter would stop counting, the shot
    never stop) is refused in float32 only, as is a frame_every beyond 2^24."""
    raw = set_path(set_path(VALID, "collisions.enabled", True), "numerics.precision", "float32")
    result = cli(run_args(ws, ws.write_scene(set_path(raw, "collisions.max_steps", 2**24 + 1))))
    assert "float64" in assert_rejected(result, "collisions.max_steps", ws)
    from warp_ricochet.scene import scene_from_dict

    for precision, steps in (("float32", 2**24), ("float64", 2**31 - 1)):
        scene = scene_from_dict(set_path(set_path(raw, "numerics.precision", precision), "collisions.max_steps", steps))
        assert scene.collisions.max_steps == steps
    # a shot stops at a checkpoint (every frame_every steps): the one at or after max_steps must
    # come by 2^24 (with frame_every 3, 2^24 itself is not a checkpoint: 2^24 - 1 is the last)
    framed = set_path(raw, "collisions.frame_every", 3)
    result = cli(run_args(ws, ws.write_scene(set_path(framed, "collisions.max_steps", 2**24))))
    assert f"at most {2**24 - 1:,}" in assert_rejected(result, "collisions.max_steps", ws)
    assert scene_from_dict(set_path(framed, "collisions.max_steps", 2**24 - 1)).collisions.max_steps == 2**24 - 1
    result = cli(run_args(ws, ws.write_scene(set_path(framed, "collisions.frame_every", 2**24 + 1))))
    assert_rejected(result, "collisions.frame_every", ws)


# ---------------------------------------------------------------------------------------------- pellet files

ARRAYS = ("position", "velocity", "angular_velocity")


@st.composite
def bad_pellet_file(draw):
    """(arrays, the array the message must name, what is wrong)."""
    n = draw(st.integers(1, 6))
    arrays = {
        "position": np.tile([0.0, 1.0, 0.0], (n, 1)),
        "velocity": np.tile([300.0, -300.0, 0.0], (n, 1)),
        "angular_velocity": np.zeros((n, 3)),
    }
    name = draw(st.sampled_from(ARRAYS))
    defect = draw(st.sampled_from(["missing", "empty", "shape", "count", "dtype", "nonfinite", "bound"]))
    if defect == "missing":
        name = draw(st.sampled_from(ARRAYS[:2]))  # angular_velocity may be left out (zeros)
        del arrays[name]
    elif defect == "empty":
        name = "position"
        for k in arrays:
            arrays[k] = np.zeros((0, 3))
    elif defect == "shape":
        arrays[name] = np.ones(draw(st.sampled_from([(n,), (n, 2), (n, 4), (n, 3, 1), (3, n, 1), ()])))
    elif defect == "count":
        other = draw(st.integers(0, 8).filter(lambda m: m != n))
        name = draw(st.sampled_from(ARRAYS[1:]))
        arrays[name] = np.ones((other, 3))
    elif defect == "dtype":
        arrays[name] = draw(st.sampled_from([arrays[name].astype(bool), arrays[name].astype(complex), arrays[name].astype(str)]))
    elif defect == "nonfinite":
        arrays[name] = arrays[name].copy()
        arrays[name][draw(st.integers(0, n - 1)), draw(st.integers(0, 2))] = draw(NON_FINITE)
    else:
        bound = {"position": 1e6, "velocity": 1e5, "angular_velocity": 1e8}[name]
        arrays[name] = arrays[name].copy()
        arrays[name][draw(st.integers(0, n - 1)), draw(st.integers(0, 2))] = draw(st.floats(bound, 1e300, exclude_min=True))
    return arrays, name, defect


@SETTINGS
@given(case=bad_pellet_file(), suffix=st.sampled_from([".npz", ".h5"]), via_set=st.booleans())
def test_malformed_pellet_files_name_the_array(ws, case, suffix, via_set):
    arrays, name, defect = case
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"pellets{suffix}"
        if suffix == ".npz":
            np.savez(path, **arrays)
        else:
            with h5py.File(path, "w") as f:
                for k, v in arrays.items():
                    f[k] = v if v.dtype.kind != "U" else v.astype("S")
        shot = {"file": str(path), "diameter": 0.0025, "density": 7000.0}
        if via_set:
            result = cli(run_args(ws, None, "--set", f"shot={toml_value(shot)}"))
        else:
            result = cli(run_args(ws, ws.write_scene({**VALID, "shot": shot})))
    message = assert_rejected(result, f"shot.file:{name}", ws)
    if defect == "missing":
        assert "missing" in message
    if defect == "count":
        assert "same N" in message or "at least one" in message


@pytest.mark.parametrize("content", [b"", b"not a pellet file\n", b"\x89HDF\r\n\x1a\n" + b"\0" * 40, b"PK\x03\x04"])
@pytest.mark.parametrize("suffix", [".npz", ".h5"])
def test_unreadable_pellet_files_are_one_line(ws, content, suffix):
    path = ws.root / f"pellets{suffix}"
    path.write_bytes(content)
    ws.listing = sorted(os.listdir(ws.root))
    result = cli(run_args(ws, None, "--set", f"shot={toml_value({'file': str(path), 'diameter': 0.0025, 'density': 7000.0})}"))
    assert "cannot be read" in assert_rejected(result, "shot.file", ws)


# ---------------------------------------------------------------------------------------------- output paths


@SETTINGS
@given(
    name=st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="/"), min_size=1, max_size=12),
    defect=st.sampled_from(["suffix", "nul", "no folder", "folder is a file", "is a folder"]),
)
def test_unusable_output_paths_are_one_line(ws, name, defect):
    assume(name not in (".", ".."))
    if defect == "suffix":
        assume(not name.lower().endswith((".h5", ".hdf5")))
        path = str(ws.root / name)
    elif defect == "nul":
        path = str(ws.root / f"{name}\x00.h5")
    elif defect == "no folder":
        path = str(ws.root / "missing" / f"{name}.h5")
    elif defect == "folder is a file":
        path = str(ws.output / f"{name}.h5")
    else:
        folder = ws.root / "folder.h5"
        folder.mkdir(exist_ok=True)
        ws.listing = sorted(os.listdir(ws.root))
        path = str(folder)
    rc, out, err = cli(["run", ws.scene, "--device", "cpu", "-o", path, "--overwrite"])
    assert_rejected((rc, out, err), "output path", ws)
    if defect == "nul":  # the C library would have cut the name at the NUL: no file of the shorter name
        assert not (ws.root / name).exists()


def test_existing_non_hdf5_output_is_refused_without_overwrite(ws):
    message = assert_rejected(cli(["run", ws.scene, "--device", "cpu", "-o", ws.output]), "output path", ws)
    assert "exists" in message and "--overwrite" in message


def test_nul_in_output_path_never_truncates_the_shorter_name(ws):
    """'out.h5\\0x.h5' ends in .h5, but the C library stops at the NUL: it would truncate out.h5.partial
    (or out.h5 itself through the rename); it must be refused."""
    victim = ws.root / "out.h5.partial"
    victim.write_bytes(b"chunks of an earlier run")
    ws.listing = sorted(os.listdir(ws.root))
    assert_rejected(cli(["run", ws.scene, "--device", "cpu", "-o", f"{ws.output}\x00x.h5", "--overwrite"]), "output path", ws)
    assert victim.read_bytes() == b"chunks of an earlier run"


def test_chunk_size_beyond_memory_is_refused_before_any_file(ws):
    if chunks.host_memory_available() is None:
        pytest.skip("host memory cannot be read here")
    result = cli(
        run_args(
            ws,
            None,
            "--set",
            "shot.count=2147483647",
            "--set",
            "numerics.chunk_size=2147483647",
            "--set",
            'output.fields=["initial", "impact", "landing"]',
        )
    )
    assert "GiB" in assert_rejected(result, "numerics.chunk_size", ws)


def test_chunk_size_beyond_memory_counts_every_shot(ws, monkeypatch):
    """A chunk of many small shots: its pellets are count x shots (here a chunk of 1e6 pellets with
    every field, 0.26 GiB, where 0.1 GiB is free), not the 1,000 of one shot."""
    monkeypatch.setattr(chunks, "host_memory_available", lambda: 100 << 20)
    result = cli(
        run_args(ws, None, "--set", "shot.count=1000", "--set", "shot.shots=1000", "--set", "numerics.chunk_size=1000000")
    )
    assert "a chunk of 1000000 pellets" in assert_rejected(result, "numerics.chunk_size", ws)


def test_a_hazard_map_beyond_memory_or_disk_is_refused_before_any_file(ws, monkeypatch):
    """A map within the limits (4e6 cells x 31 thresholds) costs gigabytes (4.9 GB of memory and a
    1 GB file for 200 pellets, issue 24): its estimate is checked before any work, in one line
    naming the keys and the estimate, against host memory and the output's disk."""
    thresholds = "{" + ", ".join(f"t{i} = {1000.0 + i}" for i in range(30)) + "}"
    args = run_args(
        ws,
        None,
        "--set",
        f"hazard.energy_density={thresholds}",
        "--set",
        "hazard.map_cell=0.1",
        "--set",
        "hazard.map_extent=[0.0, 200.0, -100.0, 100.0]",
    )
    monkeypatch.setattr(chunks, "host_memory_available", lambda: 2 << 30)
    message = assert_rejected(cli(args), "hazard.map_cell", ws)
    assert message.startswith(
        "hazard.map_cell = 0.1: the hazard map of 4,000,000 cells (2,000 x 2,000 cells of "
        "hazard.map_cell over hazard.map_extent [0.0, 200.0, -100.0, 100.0]) x 31 thresholds "
        "needs up to 13.7 GB of host memory, 2.15 GB is free: a larger map_cell"
    ), message
    monkeypatch.setattr(chunks, "host_memory_available", lambda: 1 << 40)
    monkeypatch.setattr(chunks, "free_bytes", lambda path: 1 << 20)  # the map's layers are gzip: 200 landings need little
    assert "needs up to 1.07 GB on the output's disk, 1.05 MB is free" in assert_rejected(cli(args), "hazard.map_cell", ws)


# ---------------------------------------------------------------------------------------------- devices


@SETTINGS
@given(name=st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=10))
def test_devices_that_do_not_exist_are_one_line(ws, name):
    import warp as wp

    assume(name != "cpu" and not (name.startswith("cuda") and wp.get_cuda_device_count() > 0))
    message = assert_rejected(cli(["run", ws.scene, f"--device={name}", "-o", ws.output, "--overwrite"]), "device", ws)
    assert "available" in message


# ---------------------------------------------------------------------------------------------- sweep arguments


@SETTINGS
@given(
    spec=st.one_of(
        st.builds(
            lambda k, t: f"{k}={t}",
            st.sampled_from(["surfaces.0.mu_s", "shot.seed"]),
            TEXT.filter(lambda t: not any(c.isdigit() for c in t)),
        ),  # no numbers at all
        st.builds(lambda a, b: f"surfaces.0.mu_s={a}:{b}:0", st.integers(0, 1), st.integers(0, 1)),  # step 0
        st.builds(lambda v: f"surfaces.0.mu_s={v}", st.sampled_from(["nan", "inf", "-inf", "1e400", "0:nan:0.1"])),
        st.builds(lambda v: f"surfaces.0.mu_s={v}", st.floats(100.0, 1e300, exclude_min=True).map(repr)),  # out of range
    )
)
def test_malformed_sweeps_are_one_line(ws, spec):
    rc, out, err = cli(["sweep", ws.scene, "--device", "cpu", "-o", ws.output, "--overwrite", "--param", spec])
    key = spec.partition("=")[0]
    assert_rejected((rc, out, err), key if key.strip() else "sweep", ws)


@SETTINGS
@given(
    tie=st.one_of(
        st.builds(lambda f: f"surfaces.0.mu_d={f}*", st.sampled_from(["nan", "inf", "x", "1e400"])),
        st.builds(lambda k: f"surfaces.0.mu_d=0.5*{k}", st.sampled_from(["shot.count", "physics.bounces"])),
        st.builds(lambda f: f"surfaces.0.mu_d={f!r}*", st.floats(1.001, 1e300)),  # mu_d above mu_s
    )
)
def test_malformed_ties_are_one_line(ws, tie):
    rc, out, err = cli(
        ["sweep", ws.scene, "--device", "cpu", "-o", ws.output, "--overwrite", "--param", "surfaces.0.mu_s=0.1,0.2", "--tie", tie]
    )
    lines = err.splitlines()
    assert rc == 2 and out == "" and len(lines) == 1 and lines[0].startswith(PREFIX), err
    assert "surfaces.0.mu_d" in lines[0] or "--tie" in lines[0]
    ws.untouched()


# ---------------------------------------------------------------------------------------------- end to end


def test_bad_input_end_to_end_is_exactly_one_stderr_line(tmp_path):
    """In a fresh process (Warp's start-up included): one stderr line, no traceback, nothing written."""
    pellets = tmp_path / "p.npz"
    np.savez(pellets, position=np.zeros((4, 3)), velocity=np.ones((3, 3)))
    with_file = tmp_path / "f.toml"
    with_file.write_text(toml_document({**VALID, "shot": {"file": str(pellets), "diameter": 0.0025, "density": 7000.0}}))
    valid = tmp_path / "s.toml"
    valid.write_text(toml_document(VALID))
    out = tmp_path / "o.h5"
    out.write_bytes(b"keep")
    for scene, extra, expected in (
        (with_file, [], "shot.file:velocity = (3, 3): "),
        (valid, ["--set", "surfaces.0.restitution=nan"], "surfaces.0.restitution = nan: "),
        (valid, ["--device", "cuda:9"], "device = 'cuda:9': "),
    ):
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "warp_ricochet.cli",
                "run",
                str(scene),
                "--device",
                "cpu",
                "-o",
                str(out),
                "--overwrite",
                *extra,
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert proc.returncode == 2 and proc.stdout == ""
        assert len(proc.stderr.splitlines()) == 1 and proc.stderr.startswith(PREFIX + expected), proc.stderr
    assert out.read_bytes() == b"keep" and sorted(os.listdir(tmp_path)) == ["f.toml", "o.h5", "p.npz", "s.toml"]


@pytest.mark.parametrize(
    "key,value,law",
    [("air.drag_coefficient", 0.5, "air.drag"), ("air.drag_table", "gs", "air.drag"), ("air.lift_slope", 1.0, "air.lift")],
)
def test_a_law_parameter_without_its_law_is_named(ws, key, value, law):
    """A parameter of a law the scene does not use is refused, naming the law it needs (it would
    be ignored silently); with its law it is taken. The constant law needs its coefficient."""
    result = cli(run_args(ws, ws.write_scene(set_path(VALID, key, value))))
    assert f"only with {law} = " in assert_rejected(result, key, ws)
    result = cli(run_args(ws, ws.write_scene(set_path(VALID, "air.drag", "constant"))))
    assert "is required" in assert_rejected(result, "air.drag_coefficient", ws)


@pytest.mark.parametrize("key", ["numerics.flight_tolerance", "numerics.surface_tolerance"])
def test_a_tolerance_float32_cannot_resolve_is_named(ws, key):
    raw = set_path(VALID, "numerics.precision", "float32")
    result = cli(run_args(ws, ws.write_scene(set_path(raw, key, 1e-8))))
    assert "float64" in assert_rejected(result, key, ws)


def test_more_planes_than_a_flight_in_air_tracks_is_named(ws):
    """A flight in air keeps its planes' states in the bits of an int32: 31 planes at most; in
    vacuum there is no such limit."""
    planes = [dict(VALID["surfaces"][0], point=[0.0, -float(i), 0.0]) for i in range(32)]
    result = cli(run_args(ws, ws.write_scene(dict(VALID, surfaces=planes))))
    assert "at most 31 with [air]" in assert_rejected(result, "surfaces", ws)
    vacuum = {k: v for k, v in VALID.items() if k != "air"}
    assert len(scene_from_dict(dict(vacuum, surfaces=planes)).surfaces) == 32


def test_a_drag_table_float32_cannot_hold_is_refused(ws):
    """A Mach of 1e300 is finite in float64 and inf in float32 (numpy's overflow warning): refused
    in one line; the domain's largest, 1e6, is taken."""
    raw = set_path(set_path(VALID, "air.drag", "table"), "numerics.precision", "float32")
    result = cli(run_args(ws, ws.write_scene(set_path(raw, "air.drag_table", [[0.0, 0.5], [1e300, 0.6]]))))
    assert "Mach in [0, 1e+06]" in assert_rejected(result, "air.drag_table", ws)
    air = scene_from_dict(set_path(raw, "air.drag_table", [[0.0, 0.5], [1e6, 0.6]])).air
    assert air.table == ((0.0, 0.5), (1e6, 0.6))


class _Untouchable(list):
    """A list whose elements must not be looked at one by one."""

    def __iter__(self):
        raise AssertionError("a long list was walked element by element")


def test_a_long_list_is_refused_by_its_length_alone():
    """2,000,000 tail distances: refused on their count (the message shows 8 of them), no element read."""
    raw = set_path(VALID, "output.tail_distances", [])
    raw["output"]["tail_distances"] = _Untouchable([1.0] * 2_000_000)
    with pytest.raises(SceneError) as e:
        scene_from_dict(raw)
    assert str(e.value).startswith("output.tail_distances = list of 2,000,000 items: 1.0, 1.0, ")
    assert "at most 64 numbers" in str(e.value) and len(str(e.value)) < 300


def test_a_scene_file_too_long_to_be_a_scene_is_refused_before_parsing(ws):
    """A scene holds no bulk data (pellets go in shot.file): over 1 MiB of text it is refused unparsed
    (an 18 MB file of 2,000,000 tail distances took the TOML parser ~10 s)."""
    scene = Path(ws.write_scene(VALID))
    scene.write_text(scene.read_text() + "# " + "x" * (1 << 20) + "\n")
    assert "a scene is at most 1,048,576" in assert_rejected(cli(run_args(ws, scene)), "scene", ws)


def _lying_npz(path, rows, held=b"\0" * 48):
    """An .npz whose arrays' .npy headers declare (rows, 3) float64 and hold only `held`."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": (rows, 3)})
    import zipfile

    with zipfile.ZipFile(path, "w") as z:
        for name in ("position", "velocity"):
            z.writestr(f"{name}.npy", header.getvalue() + held)


def test_a_pellet_files_declared_sizes_are_checked_before_reading(ws, monkeypatch):
    """A 2 kB .h5 declaring (3e8, 3) arrays (fill values, nothing stored) drove memory to 21.5 GB:
    refused from its declared shape, naming the file, the array and how many pellets fit, before a
    value is read; with shot.count given, its mismatch is named first."""
    from warp_ricochet.scene import pellets

    def no_reading(*args, **kwargs):
        raise AssertionError("the pellet file was read")

    monkeypatch.setattr(pellets, "_read", no_reading)
    monkeypatch.setattr(pellets, "host_memory_available", lambda: 4 << 30)
    path = ws.root / "pellets.h5"
    with h5py.File(path, "w") as f:
        for name in ("position", "velocity"):
            f.create_dataset(name, shape=(300_000_000, 3), dtype="f8", chunks=(65536, 3))
    assert path.stat().st_size < 10_000
    ws.listing = sorted(os.listdir(ws.root))
    shot = {"file": str(path), "diameter": 0.0025, "density": 7000.0}
    message = assert_rejected(cli(run_args(ws, None, "--set", f"shot={toml_value(shot)}")), "shot.file:position", ws)
    assert f"(300000000, 3): {path} declares 300,000,000 pellets" in message
    assert "more than half the 4 GiB of host memory available: at most 29,826,161 pellets" in message
    result = cli(run_args(ws, None, "--set", f"shot={toml_value({**shot, 'count': 5})}"))
    assert "must equal the pellets per shot in shot.file (300000000" in assert_rejected(result, "shot.count", ws)
    with h5py.File(path, "w") as f:  # a storage chunk is read whole: one of 805 MB is refused too
        for name in ("position", "velocity"):
            f.create_dataset(name, shape=(2**25, 3), dtype="f8", chunks=(2**25, 3))
    assert "storage chunks of 805,306,368 bytes" in assert_rejected(
        cli(run_args(ws, None, "--set", f"shot={toml_value(shot)}")), "shot.file:position", ws
    )


def test_a_pellet_file_holding_less_than_it_declares_is_read_in_bounded_pieces(ws, monkeypatch):
    """An .npz declaring (3e7, 3) float64 (720 MB) and holding 48 bytes, with memory to spare: read a
    piece at a time, it is refused at its end having taken at most a piece of memory."""
    import tracemalloc

    from warp_ricochet.scene import pellets

    monkeypatch.setattr(pellets, "host_memory_available", lambda: 1 << 40, raising=False)
    path = ws.root / "pellets.npz"
    _lying_npz(path, 30_000_000)
    ws.listing = sorted(os.listdir(ws.root))
    tracemalloc.start()
    try:
        result = cli(
            run_args(ws, None, "--set", f"shot={toml_value({'file': str(path), 'diameter': 0.0025, 'density': 7000.0})}")
        )
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 100 << 20, peak  # (numpy's own reading allocated the 720 MB array first)
    assert "it declares more than it holds" in assert_rejected(result, "shot.file", ws)
