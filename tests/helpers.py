"""Scene builders shared by the tests."""

import numpy as np

PAPER_SHOT = {
    "count": 450, "diameter": 0.0025, "density": 7000.0, "speed": 411.48,
    "direction": [1.0, -1.0, 0.0], "direction_jitter": [0.1, 0.1, 0.1],
    "envelope_radius": 0.025, "envelope_center": [0.0, 1.0, 0.0], "seed": 2021,
}
GROUND = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.01, "mu_s": 0.5, "mu_d": 0.45}


def paper_raw(**physics):
    return {"shot": dict(PAPER_SHOT), "surfaces": [dict(GROUND)], "physics": {"impact_duration": 1e-5, **physics}}


def make_scene(raw=None, precision="float32", **sections):
    """A Scene from a raw dict (default: the paper's), with tables replaced by `sections`."""
    from warp_ricochet.scene import scene_from_dict

    raw = dict(raw or paper_raw())
    raw.update(sections)
    raw.setdefault("numerics", {})
    raw["numerics"] = {**raw["numerics"], "precision": precision}
    return scene_from_dict(raw)


def explicit_scene(tmp_path, position, velocity, angular_velocity=None, *, surfaces, precision="float64",
                   diameter=0.0025, physics=None, name="pellets.npz"):
    """A Scene whose pellets come from a .npz file written in tmp_path."""
    path = tmp_path / name
    arrays = {"position": np.asarray(position, float), "velocity": np.asarray(velocity, float)}
    if angular_velocity is not None:
        arrays["angular_velocity"] = np.asarray(angular_velocity, float)
    np.savez(path, **arrays)
    raw = {
        "shot": {"file": str(path), "diameter": diameter, "density": 7000.0},
        "surfaces": surfaces,
        "physics": physics or {},
        "numerics": {"precision": precision},
    }
    return make_scene(raw, precision=precision)
