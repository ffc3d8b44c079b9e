"""The scene key `[[hazard.references]]` (issue 26, part 3) and its datasets in the run file."""

from pathlib import Path

import h5py
import pytest

import warp_ricochet as wr
from warp_ricochet.errors import SceneError
from warp_ricochet.scene import load_scene, scene_from_dict

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    """A real run of examples/hazard.toml (14 shots: 3,920 pellets, enough to bound p = 1e-3 of the
    corneal threshold; to rest, on the CPU) with two references."""
    refs = "[{name = 'CPSA shot fall', distance = 275.0, source = 'CPSA'}, {name = 'short', distance = 50.0}]"
    scene = load_scene(
        ROOT / "examples" / "hazard.toml",
        ["shot.shots=14", 'output.fields=["landing", "hazard", "rest"]', f"hazard.references={refs}"],
    )
    path = tmp_path_factory.mktemp("html") / "run.h5"
    wr.run(scene, path, device="cpu")
    return path


# ---------------------------------------------------------------------------------------------- the key


def test_references_key_round_trips_and_bad_values_are_one_line():
    refs = "[{name = 'CPSA', distance = 275.0, source = 'CPSA guidance'}, {name = 'BSA', distance = 274.32}]"
    scene = load_scene(ROOT / "examples" / "hazard.toml", [f"hazard.references={refs}"])
    assert [(r.name, r.distance, r.source) for r in scene.hazard.references] == [
        ("CPSA", 275.0, "CPSA guidance"),
        ("BSA", 274.32, ""),
    ]
    import tomllib

    assert scene_from_dict(tomllib.loads(scene.to_toml())) == scene
    assert "references" not in load_scene(ROOT / "examples" / "hazard.toml", ["hazard.references=[]"]).to_toml()
    for bad, key in (
        ("[{name = 'a'}]", "hazard.references.0.distance"),
        ("[{name = 'a', distance = -1.0}]", "hazard.references.0.distance"),
        ("[{name = 'a', distance = 1.0, src = 'x'}]", "hazard.references.0.src"),
        ("[{name = 'a', distance = 1.0}, {name = 'a', distance = 2.0}]", "hazard.references.1.name"),
        ("[{name = '', distance = 1.0}]", "hazard.references.0.name"),
        ("[1]", "hazard.references.0"),
        ("3", "hazard.references"),
    ):
        with pytest.raises(SceneError) as exc:
            load_scene(ROOT / "examples" / "hazard.toml", [f"hazard.references={bad}"])
        message = str(exc.value)
        assert message.startswith(key + " =") and "\n" not in message, message


def test_references_are_written_into_the_run_file(run_file):
    with h5py.File(run_file, "r") as f:
        g = f["hazard/references"]
        assert [n.decode() for n in g["name"][()]] == ["CPSA shot fall", "short"]
        assert g["distance"][()].tolist() == [275.0, 50.0]
        assert [s.decode() for s in g["source"][()]] == ["CPSA", ""]
        for name in ("name", "distance", "source"):
            assert "units" in g[name].attrs and g[name].attrs["description"]
        assert g["distance"].attrs["units"] == "m"
