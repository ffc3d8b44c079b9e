"""Values written with their units (scene.units): converted to the key's unit, refused in one line
for a unit of the wrong dimension; --set and --param take them too (no warp)."""

import math
import re

import pytest
from helpers import make_scene, paper_raw

from warp_ricochet.errors import SceneError
from warp_ricochet.io.writer import unit_of_key
from warp_ricochet.scene import apply_override, parse_sweep, scene_from_dict
from warp_ricochet.scene.convert import SCHEMAS
from warp_ricochet.scene.units import KEY_UNITS, split_unit, to_unit, unit_of


def scene_with(**shot):
    raw = paper_raw()
    raw["shot"].update(shot)
    return make_scene(raw)


@pytest.mark.parametrize(
    ("key", "text", "si"),
    [
        ("shot.diameter", "2.4 mm", 0.0024),
        ("shot.diameter", "0.095 in", 0.002413),
        ("shot.speed", "1350 ft/s", 411.48),  # the paper's speed
        ("shot.speed", "1350 fps", 411.48),
        ("shot.density", "11.1 g/cm^3", 11100.0),
        ("shot.envelope_radius", "1 in", 0.0254),
        ("hazard.map_cell", "40 yd", 36.576),
        ("shot.load.charge", "1 1/8 oz", 1.125 * 0.028349523125),
        ("shot.load.charge", "1-1/8 oz", 1.125 * 0.028349523125),
        ("shot.load.charge", "7/8 oz", 0.875 * 0.028349523125),
        ("shot.load.charge", "28 g", 0.028),
        ("shot.load.charge", "437.5 gr", 0.028349523125),  # grains: an ounce is 437.5
        ("surfaces.0.critical_angle", "30 deg", 30.0),
        ("surfaces.0.critical_angle", "0.5 rad", math.degrees(0.5)),
        ("surfaces.3.roughness", "30°", 30.0),
        ("shot.spin", "3000 rpm", 100 * math.pi),
        ("surfaces.0.restitution", "50 %", 0.5),
        ("physics.impact_duration", "10 us", 1e-5),
        ("hazard.energy_density.eye", "1 J/cm^2", 1e4),
        ("surfaces.0.mu_s", "0.5", 0.5),  # a number without a unit: the key's own
    ],
)
def test_a_value_with_a_unit_is_converted_to_the_keys_unit(key, text, si):
    assert to_unit(text, key, "rule") == pytest.approx(si, rel=1e-12)


def test_scenes_overrides_and_lists_take_units_and_plain_numbers_stay_si():
    scene = scene_with(diameter="2.4 mm", speed="1350 ft/s", envelope_center=["1 yd", 0.0, "3 in"])
    assert scene.shot.diameter == 0.0024 and scene.shot.speed == 411.48  # exact: pint's factors to 15 digits
    assert scene.shot.envelope_center == (0.9144, 0.0, 0.0762)
    assert scene_with(diameter=0.0024).shot.diameter == 0.0024
    raw = apply_override(paper_raw(), "shot.diameter=2.4 mm")  # (not TOML: kept as the string)
    assert scene_from_dict(raw).shot.diameter == 0.0024
    assert make_scene(output={"tail_distances": ["10 yd", 20.0]}).output.tail_distances == (9.144, 20.0)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("diameter", "1350 ft/s", "shot.diameter = '1350 ft/s': shot.diameter takes a length (m); 'ft/s' is a speed"),
        ("speed", "1 1/8 oz", "shot.speed = '1 1/8 oz': shot.speed takes a speed (m/s); 'oz' is a mass"),
        ("density", "3 m", "shot.density = '3 m': shot.density takes a density (kg/m^3); 'm' is a length"),
        (
            "diameter",
            "2.4 blorbs",
            "shot.diameter = '2.4 blorbs': 'blorbs' is not a unit pint knows; shot.diameter takes a length (m)",
        ),
        ("diameter", "two mm", "shot.diameter = 'two mm': must be a number in [1e-06, 1] (m), or a number with a unit of"),
        ("diameter", "2 m", "shot.diameter = '2 m': must be a number in [1e-06, 1] (m)"),  # converted, then checked
        ("count", "300 mm", "shot.count = '300 mm': must be an integer in [1, 2147483647]"),
        ("direction", ["1 m", 0, 0], "shot.direction = '1 m': must be a list of 3 numbers"),  # a key without a unit
        ("speed", "1e999 m/s", "shot.speed = '1e999 m/s': must be finite"),
        ("speed", "2**99 m/s", "shot.speed = '2**99 m/s': must be a number in (0, 100000] (m/s), or a number"),
    ],
)
def test_a_wrong_unit_is_refused_in_one_line_naming_key_value_and_unit(key, value, message):
    with pytest.raises(SceneError) as info:
        scene_with(**{key: value})
    assert str(info.value).startswith(message) and "\n" not in str(info.value)


def test_an_angle_is_no_pure_number_and_a_pure_number_no_angle():
    with pytest.raises(SceneError, match=r"takes a pure number \(1\); 'deg' is an angle"):
        to_unit("30 deg", "surfaces.0.restitution", "rule")
    with pytest.raises(SceneError, match=r"takes an angle \(deg\); 'm' is a length"):
        to_unit("3 m", "surfaces.0.critical_angle", "rule")


def test_a_sweep_takes_one_unit_for_its_values():
    assert parse_sweep("shot.speed=1000:1400:200 ft/s") == ("shot.speed", [304.8, 365.76, 426.72])
    assert parse_sweep("shot.speed=1000 ft/s,1400 ft/s") == ("shot.speed", [304.8, 426.72])
    assert parse_sweep("shot.speed=300,400") == ("shot.speed", [300, 400])  # SI, ints kept
    assert parse_sweep("shot.speed=1e3:2e3:500") == ("shot.speed", [1000.0, 1500.0, 2000.0])
    with pytest.raises(SceneError, match="one unit for all its values"):
        parse_sweep("shot.speed=1 m/s,2 ft/s")
    with pytest.raises(SceneError, match=r"takes a speed \(m/s\); 'mm' is a length"):
        parse_sweep("shot.speed=3:4:1 mm")
    assert split_unit("1.5e3 ft/s") == ("1.5e3", "ft/s") and split_unit("x") == ("x", "")


def test_swept_keys_are_written_with_their_units_from_the_table():
    assert unit_of_key("hazard.energy_density.eye") == "J/m^2"  # (by the key's last part alone: unknown)
    assert unit_of_key("surfaces.2.critical_angle") == "deg" and unit_of_key("shot.speed") == "m/s"
    assert unit_of_key("numerics.precision") == "see the scene key"


NO_UNIT = {  # numeric keys that take numbers only: directions, a raster's own units
    "shot.direction",
    "surfaces.0.normal",
    "surfaces.0.axis_u",
    "surfaces.0.origin",
    "surfaces.0.nodata",
    "hazard.map_axis",
    "air.drag_table",
}


def test_every_numeric_key_has_a_unit_and_the_one_its_rule_states():
    """Each key whose converter takes numbers is in KEY_UNITS (or named in NO_UNIT), with the unit its
    one-line rule gives in parentheses: the table cannot fall behind the schema."""
    tables = {name: schema for name, schema in SCHEMAS.items() if name}
    checked = 0
    for table, schema in tables.items():
        for key, conv in schema.items():
            rule = getattr(conv, "rule", "")
            if "number" not in rule or "table of name" in rule or "array of" in rule:
                continue
            path = f"{table}.0.{key}" if table == "surfaces" else f"{table}.{key}"
            if path in NO_UNIT:
                assert unit_of(path) is None, path
                continue
            unit = unit_of(path)
            assert unit is not None, f"{path} is missing from KEY_UNITS"
            stated = re.findall(r"\(([^()]*)\)$", rule)
            if stated and stated[0] not in ("the raster's CRS units",):
                assert stated[0] == unit, (path, stated, unit)
            checked += 1
    assert checked >= 50
    assert all(unit_of(k.replace("*", "0")) == u for k, u in KEY_UNITS.items())


# ---------------------------------------------------------------------------------------------- --units imperial

STATS = {
    "pellets": 100,
    "hits": 100,
    "stick": 10,
    "slip": 90,
    "landed": 100,
    "missed": 0,
    "escaped": 0,
    "pre_mean_vt": 411.48,
    "post_mean_vt": 30.48,
    "pre_mean_vn": 304.8,
    "post_mean_vn": 3.048,
    "range_mean": 91.44,
    "range_max": 182.88,
    "range_min": 9.144,
    "landing_mean_WT": 1.5,
}


def test_imperial_summaries_print_yards_and_feet_per_second_and_keep_joules():
    from warp_ricochet import display
    from warp_ricochet.report import format_run_summary

    metric = format_run_summary(STATS)
    with display.using("imperial"):
        imperial = format_run_summary(STATS)
    assert "mean range <L>       91.440 m\n" in metric and "mean v_t pre/post    411.480 m/s / 30.480 m/s" in metric
    assert "mean range <L>       100.000 yd\n" in imperial and "L- (shortest)        10.000 yd" in imperial
    assert "mean v_t pre/post    1,350.000 ft/s / 100.000 ft/s" in imperial
    assert "mean W_T at landing  1.500000 J" in imperial and "1.500000 J" in metric
    assert format_run_summary(STATS) == metric  # (the system is the block's only)
    # issue 28: the pellets that hit and never landed in words of their own, the columns as before
    assert "landed               100\nhit, never landed    0\nmissed               0\n" in metric


def test_imperial_tables_convert_values_and_headers_and_swept_keys():
    from warp_ricochet import display
    from warp_ricochet.report import format_tables, results_from_sweep

    res = results_from_sweep([({"shot.speed": 411.48}, STATS), ({"shot.speed": 304.8}, STATS)], ["shot.speed"])
    metric = format_tables(res)
    with display.using("imperial"):
        text = format_tables(res, "markdown")
    assert "<L> (m)" in metric and "(yd)" not in metric and "speed (" not in metric  # (metric: as before)
    table3 = text.split("Table 3")[1]
    assert "|   speed (ft/s) |   \\<L\\> (yd) |   L+ (yd) |   L- (yd) |" in table3
    assert "|      1,350.000 |      100.000 |   200.000 |    10.000 |" in table3
    assert "\\<W_T\\> (J)" in text  # energies stay in joules


def test_imperial_danger_distances_quantiles_and_bounds():
    import numpy as np

    from warp_ricochet import display
    from warp_ricochet.bound import BoundResult
    from warp_ricochet.report.hazard_tables import tally_lines

    results = {
        "levels": [0.5, 0.75, 0.9, 0.99, 0.999, 1 - 1e-6],
        "landed": 10**7,
        "quantiles": {"distance": (np.array([9.144, 18.288, 27.432, 36.576, 45.72, 54.864]), None)},
        "tail": {"distance": np.array([9.144, 91.44]), "fraction": np.array([0.5, 0.0])},
        "hazard": {
            "names": ["eye"],
            "kinds": ["energy_density"],
            "fractions": [1e-3],
            "landings": np.array([5000]),
            "values": np.array([1503.0]),
            "distance": np.array([[91.44]]),
            "ci_low": np.array([[82.296]]),
            "ci_high": np.array([[100.584]]),
            "needed_landings": np.array([[0]]),
        },
    }
    with display.using("imperial"):
        lines = tally_lines(results, 1e7)
        bound = BoundResult("eye", 1e-3, 9.144, 1000, 800, 8, True, 91.44, 82.296, 100.584, 3).summary()
    assert "  distance 10 / 20 / 30 / 40 / 50 / 60 yd" in lines
    assert "landed beyond  >=10 yd: 0.5" in lines
    assert "  eye (1503 J/m^2, 5,000 landings): p=0.001: 100 yd [90, 110]" in lines
    assert bound.endswith("95% interval [90, 110] yd, width 20 yd < 10 yd")
    assert "p=0.001: 91.44 m [82.3, 100.6]" in "\n".join(tally_lines(results, 1e7))


def test_paper_comparison_is_refused_in_imperial_in_one_line(tmp_path, capsys):
    from warp_ricochet.cli import main

    assert main(["report", str(tmp_path / "none.h5"), "--paper", "--units", "imperial"]) == 2
    err = capsys.readouterr().err
    assert (
        err
        == "warp-ricochet: error: --units = 'imperial': --paper compares with the paper's tables in SI; give it without --units\n"
    )


def test_pattern_and_station_keys_take_units():
    """The keys of the pattern and stations tables (docs/scenes.md, "Units"): a percentage, angles
    and positions per station."""
    assert to_unit("60 %", "shot.pattern", "rule") == 60.0 and to_unit("60", "shot.pattern", "rule") == 60.0
    assert to_unit("0.5 rad", "stations.3.azimuth", "rule") == pytest.approx(math.degrees(0.5), rel=1e-12)
    assert to_unit("40 yd", "stations.0.position", "rule") == pytest.approx(36.576, rel=1e-15)
    with pytest.raises(SceneError, match=r"stations.3.azimuth takes an angle \(deg\); 'm' is a length"):
        to_unit("3 m", "stations.3.azimuth", "rule")
