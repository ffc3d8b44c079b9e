"""Ground materials in the scene (warp_ricochet.scene.materials): the catalogue and its sources,
`material = "..."` with overrides, every refusal, the resolved values in the run file, and the
host-side conversions (ploughing rate, critical angles, closed-form stop distances)."""

import math

import h5py
import numpy as np
import pytest

from warp_ricochet.errors import SceneError
from warp_ricochet.model import ground_of
from warp_ricochet.scene import scene_from_dict
from warp_ricochet.scene.materials import (
    CATALOGUE,
    GROUND_KEYS,
    NO_CRITICAL_ANGLE,
    RANGES,
    RIGID,
    critical_angle,
    names,
    ploughing_rate,
    resolve,
    stop_distance,
)

REQUIRED = ("steel_plate", "concrete", "packed_soil", "turf", "sand", "gravel", "water")
LEAD, STEEL = 11340.0, 7850.0  # kg/m^3


def scene(surface, density=LEAD):
    raw = {
        "shot": {"count": 1, "diameter": 0.0025, "density": density, "speed": 100.0},
        "surfaces": [{"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], **surface}],
    }
    return scene_from_dict(raw)


def test_the_catalogue_has_every_material_with_values_in_range_and_a_source_for_each_law():
    assert set(REQUIRED) <= set(CATALOGUE)
    for base, entry in CATALOGUE.items():
        for end in ("far", "near"):
            values = getattr(entry, end)
            assert set(values) == {"restitution", "mu_s", "mu_d", *GROUND_KEYS}, base
            assert 0.0 <= values["restitution"] <= 1.0 and 0.0 <= values["mu_d"] <= values["mu_s"]
            for key, (lo, hi, _unit, _why) in RANGES.items():
                assert lo <= values[key] <= hi, (base, end, key)
        used = {k for k in GROUND_KEYS if entry.far[k] != RIGID[k] or entry.near[k] != RIGID[k]}
        for key in used - {"critical_angle_rise", "critical_speed", "ploughing_area", "mu_d"}:
            assert entry.sources.get(key), f"{base}.{key} has no source"
        if not entry.liquid:
            assert entry.sources.get("restitution") and entry.sources.get("mu_s"), base


def test_the_far_end_carries_a_pellet_at_least_as_far_as_the_near_end():
    for base, entry in CATALOGUE.items():
        far, near = entry.far, entry.near
        assert far["rolling_resistance"] <= near["rolling_resistance"], base
        assert far["ploughing"] * far["ploughing_area"] <= near["ploughing"] * near["ploughing_area"], base
        assert far["mu_d"] <= near["mu_d"] and far["restitution"] >= near["restitution"], base
        assert far["critical_angle"] >= near["critical_angle"] and far["roughness"] >= near["roughness"], base
        assert far["skip_loss"] <= near["skip_loss"], base


def test_a_material_gives_its_default_end_and_the_scene_keeps_the_resolved_values():
    s = scene({"material": "turf"}).surfaces[0]
    assert s.material == "turf" and resolve("turf") == resolve("turf:far") != resolve("turf:near")
    for key, value in resolve("turf").items():
        assert getattr(s, key) == value
    again = scene_from_dict(scene({"material": "turf"}).to_dict())
    assert again == scene({"material": "turf"})  # the echo carries every resolved value


def test_overrides_replace_the_catalogue_key_by_key():
    s = scene({"material": "sand:near", "rolling_resistance": 0.2, "roughness": 1.0, "restitution": 0.5}).surfaces[0]
    near = resolve("sand:near")
    assert (s.rolling_resistance, s.roughness, s.restitution) == (0.2, 1.0, 0.5)
    assert (s.ploughing, s.mu_s, s.mu_d, s.critical_angle) == (
        near["ploughing"],
        near["mu_s"],
        near["mu_d"],
        near["critical_angle"],
    )
    lowered = scene({"material": "gravel", "mu_s": 0.1}).surfaces[0]
    assert lowered.mu_d == 0.1  # the material's mu_d 0.5 would exceed the scene's mu_s


def test_a_surface_without_a_material_is_todays_rigid_plane():
    s = scene({"restitution": 0.2, "mu_s": 0.5}).surfaces[0]
    assert s.material is None and all(getattr(s, key) is None for key in GROUND_KEYS)
    assert {key: s.ground(key) for key in GROUND_KEYS} == RIGID
    assert "rolling_resistance" not in scene({"restitution": 0.2, "mu_s": 0.5}).to_toml()  # the echo unchanged
    with pytest.raises(SceneError, match=r"surfaces\.0\.restitution = \(missing\): is required"):
        scene({"mu_s": 0.5})
    rolling = scene({"restitution": 0.2, "mu_s": 0.5, "rolling_resistance": 0.05}).surfaces  # a key on its own
    got = ground_of(rolling, 0.00125, LEAD)
    assert got["rolling_resistance"] == [0.05] and got["critical_angle"] == [0.5 * math.pi] and got["ploughing"] == [0.0]


@pytest.mark.parametrize(
    ("surface", "message"),
    [
        ({"material": "turff"}, r"surfaces\.0\.material = 'turff': unknown material; did you mean turf\? allowed: steel_plate"),
        ({"material": "sand:middle"}, r"surfaces\.0\.material = 'sand:middle': unknown material; did you mean \"sand:near\"\?"),
        ({"material": 3}, r"surfaces\.0\.material = 3: must be a string"),
        (
            {"material": "turf", "rolling_resistance": -0.1},
            r"surfaces\.0\.rolling_resistance = -0\.1: must be a number in \[0, 1\]",
        ),
        (
            {"material": "turf", "ploughing": 3e4},
            r"surfaces\.0\.ploughing = 30000\.0: must be a number in \[0, 20000\] \(kg/m\^3\)",
        ),
        ({"material": "turf", "ploughing_area": 1.5}, r"surfaces\.0\.ploughing_area = 1\.5: must be a number in \[0, 1\]"),
        ({"material": "sand", "critical_angle": 91}, r"surfaces\.0\.critical_angle = 91: must be a number in \[0, 90\] \(deg\)"),
        (
            {"material": "sand", "critical_angle_rise": -1},
            r"surfaces\.0\.critical_angle_rise = -1: must be a number in \[0, 90\]",
        ),
        (
            {"material": "sand", "critical_speed": -6},
            r"surfaces\.0\.critical_speed = -6: must be a number in \[0, 100000\] \(m/s\)",
        ),
        ({"material": "gravel", "roughness": 20}, r"surfaces\.0\.roughness = 20: must be a number in \[0, 15\] \(deg\)"),
        (
            {"material": "gravel", "restitution_scatter": -0.5},
            r"surfaces\.0\.restitution_scatter = -0\.5: must be a number in \[0, 1\]",
        ),
        ({"material": "gravel", "friction_scatter": 2}, r"surfaces\.0\.friction_scatter = 2: must be a number in \[0, 1\]"),
        ({"material": "water", "skip_loss": -1}, r"surfaces\.0\.skip_loss = -1: must be a number in \[0, 10\]"),
        ({"material": "turf", "restitution": 1.2}, r"surfaces\.0\.restitution = 1\.2: must be a number in \[0, 1\]"),
        ({"material": "turf", "mu_d": 0.9}, r"surfaces\.0\.mu_d = 0\.9: must be a number in \[0, mu_s = 0\.5\]"),
        ({"material": "turf", "colour": "green"}, r"surfaces\.0\.colour = 'green': unknown key"),
    ],
)
def test_bad_ground_keys_are_refused_in_one_line(surface, message):
    with pytest.raises(SceneError, match=message) as info:
        scene(surface)
    assert "\n" not in str(info.value)


def test_every_accepted_name_resolves():
    for name in names():
        assert scene({"material": name}).surfaces[0].material == name


def test_water_critical_angle_is_johnsons_18_deg_over_root_specific_gravity():
    water = scene({"material": "water"}).surfaces[0]
    assert math.degrees(critical_angle(water, LEAD)) == pytest.approx(5.345, abs=5e-4)  # issue: lead 5.35 deg
    assert math.degrees(critical_angle(water, STEEL)) == pytest.approx(6.424, abs=5e-4)  # steel 6.42 deg
    assert math.degrees(critical_angle(water, 1000.0)) == 18.0
    sand = scene({"material": "sand"}).surfaces[0]
    assert critical_angle(sand, LEAD) == math.radians(10.0)  # not scaled off water
    assert critical_angle(scene({"restitution": 0.1, "mu_s": 0.1}).surfaces[0], LEAD) == math.radians(NO_CRITICAL_ANGLE)


def test_the_ploughing_rate_is_c2_f_pi_r2_over_m():
    radius, density, c2, f = 0.00125, LEAD, 800.0, 0.2
    mass = density * 4.0 / 3.0 * math.pi * radius**3
    assert ploughing_rate(c2, f, radius, density) == pytest.approx(c2 * f * math.pi * radius**2 / mass, rel=1e-14)
    turf = scene({"material": "turf:near"}).surfaces
    got = ground_of(turf, radius, density)
    assert got["ploughing"][0] == pytest.approx(ploughing_rate(3000.0, 0.3, radius, density), rel=1e-15)
    assert got["roughness"][0] == math.radians(3.0) and got["rolling_resistance"][0] == 0.24


def test_stop_distance_is_the_closed_form_of_v_dv_dx_against_c_g_plus_b_v2():
    from scipy.integrate import solve_ivp

    c, b, g, v0 = 0.1, 3.0, 9.81, 187.0
    sol = solve_ivp(lambda v, x: [-v / (5.0 / 7.0 * (c * g + b * v * v))], (v0, 0.0), [0.0], rtol=1e-12, atol=1e-12)
    assert stop_distance(v0, c, b, g) == pytest.approx(sol.y[0, -1], rel=1e-9)
    assert stop_distance(20.0, c, 0.0, g) == pytest.approx(7 * 400 / (10 * c * g), rel=1e-15)
    assert stop_distance(20.0, 0.0, 0.0) == math.inf


def test_the_run_file_carries_the_resolved_ground_values(tmp_path):
    import warp_ricochet as wr

    raw = {
        "shot": {"count": 4, "diameter": 0.0025, "density": LEAD, "speed": 100.0, "direction": [1.0, -1.0, 0.0]},
        "surfaces": [
            {"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "turf", "roughness": 2.0},
            {"point": [50.0, 0.0, 0.0], "normal": [-1.0, 0.0, 0.0], "restitution": 0.3, "mu_s": 0.2},
        ],
    }
    out = tmp_path / "run.h5"
    wr.run(scene_from_dict(raw), out, device="cpu")
    with h5py.File(out, "r") as f:
        g = f["constants/surfaces"]
        assert list(g.attrs["material"]) == ["turf", ""]
        np.testing.assert_array_equal(g["roughness"][()], [2.0, 0.0])
        np.testing.assert_array_equal(g["rolling_resistance"][()], [0.065, 0.0])
        np.testing.assert_array_equal(g["critical_angle"][()], [90.0, 90.0])
        assert g["ploughing"].attrs["units"] == "kg/m^3"
        assert 'material = "turf"' in f.attrs["scene_toml"] and "roughness = 2.0" in f.attrs["scene_toml"]
