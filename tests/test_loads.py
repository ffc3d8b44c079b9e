"""Shot loads (scene.loads): the catalogue against published tables it was not made from, the
resolution of [shot] load with the scene's own keys over it, and bad loads refused in one line
before any work (no warp)."""

import math
import tomllib

import h5py
import pytest
from helpers import paper_raw

from warp_ricochet.cli import main
from warp_ricochet.errors import SceneError
from warp_ricochet.io.writer import _write_load
from warp_ricochet.scene import scene_from_dict
from warp_ricochet.scene.loads import INCH, MATERIALS, OUNCE, SYSTEMS, count_of, describe_load, pellets

# Pellets per ounce of 3% antimony lead and of steel shot, Winchester Ammunition 2004 Product Guide,
# quoted in C. Hawks, "Shot Pellet Information and Recommendations", chuckhawks.com,
# http://chuckhawks.com/shot_info.htm (the catalogue's US diameters are Federal's, its lead and
# steel densities Fiocchi's: neither comes from these counts)
WINCHESTER_LEAD = {"BB": 50, "2": 87, "4": 135, "5": 170, "6": 225, "7.5": 350, "8": 410, "8.5": 497, "9": 585}
WINCHESTER_STEEL = {"BBB": 62, "BB": 72, "1": 103, "2": 125, "3": 158, "4": 192, "5": 243, "6": 315}
# Pellets per ounce of chilled shot, American standard sizes: H. Kephart, Sporting Firearms, Outing
# Publishing Company, 1912, "Shot Patterns and Penetration",
# http://bookdome.com/arts/Sporting-Firearms/Shot-Patterns-And-Penetration-Part-3.html
KEPHART_CHILLED = {"12": 2385, "11": 1380, "10": 868, "9": 585, "8.5": 495, "8": 409, "7.5": 345, "7": 299, "6": 223}
KEPHART_CHILLED |= {"5": 172, "4": 136, "3": 109, "2": 88, "1": 73, "B": 59, "BB": 50, "BBB": 42}
KEPHART_CHILLED |= {"T": 36, "TT": 31, "F": 27, "FF": 24}
# English shot, pellets per ounce measured in cartridge tests: Clay Shooting magazine, 8 January
# 2020, https://www.pressreader.com/uk/clay-shooting/20200108/282067688836209 ("UK No.7 = 340
# pellets/oz; UK No.7.5 = 400 pellets/oz; UK No.8 = 450/oz")
CLAY_SHOOTING_UK = {"7": 340, "7.5": 400, "8": 450}
# Italian No. 12 (1.5 mm): "un grammo ne contiene 51", Fiocchi, "Quanti pallini in una cartuccia",
# https://fiocchi.com/it/blog/post/quanti-pallini-in-una-cartuccia
FIOCCHI_PER_GRAM = {"12": 51}
TOLERANCE = 0.03  # of a published count, beside half a pellet of its rounding: shot varies by maker and lot


def per_ounce(system, size, material):
    _sources, table, unit = SYSTEMS[system]
    return pellets(OUNCE, table[size] * unit, MATERIALS[material].density)


@pytest.mark.parametrize(
    ("system", "material", "published"),
    [
        ("US", "lead", WINCHESTER_LEAD),
        ("US", "steel", WINCHESTER_STEEL),
        ("US", "lead", KEPHART_CHILLED),
        ("UK", "lead", CLAY_SHOOTING_UK),
    ],
    ids=["winchester-lead", "winchester-steel", "kephart-1912", "clay-shooting-uk"],
)
def test_pellets_per_ounce_agree_with_published_counts(system, material, published):
    for size, count in published.items():
        ours = per_ounce(system, size, material)
        assert abs(ours - count) <= TOLERANCE * count + 0.5, (system, size, ours, count)


def test_italian_sizes_agree_with_fiocchis_count_per_gram():
    _sources, table, unit = SYSTEMS["IT"]
    for size, count in FIOCCHI_PER_GRAM.items():
        assert pellets(1e-3, table[size] * unit, MATERIALS["lead"].density) == pytest.approx(count, abs=0.5)


def test_us_sizes_follow_the_american_standard_rule():
    """SAAMI's American standard: a number-n pellet is 17 - n hundredths of an inch (T. Roster,
    "Understanding Lead Shot Quality - Part 1", shotgunlife.com)."""
    _sources, table, unit = SYSTEMS["US"]
    assert unit == INCH
    numbers = {size: d for size, d in table.items() if size[0].isdigit()}
    assert len(numbers) == 14
    for size, d in numbers.items():
        assert d == pytest.approx((17 - float(size)) / 100, abs=1e-12), size


def shot_with(load, **shot):
    raw = paper_raw()
    for key in ("diameter", "density", "count"):
        raw["shot"].pop(key)
    raw["shot"].update(load=load, **shot)
    return scene_from_dict(raw)


def test_a_load_gives_diameter_density_and_count():
    scene = shot_with({"size": "US 7.5", "material": "lead", "charge": "1 1/8 oz"})
    d, rho = 0.095 * 0.0254, 11100.0
    assert scene.shot.diameter == 0.002413 and scene.shot.density == rho
    assert scene.shot.count == round(1.125 * OUNCE / (rho * math.pi * d**3 / 6)) == 391
    assert scene.shot.load == (
        ("size", "US 7.5"),
        ("material", "lead"),
        ("charge", 0.031893213515625),
    )  # (decimal: 1.125 x 28.349523125 g)
    assert shot_with({"size": "UK 7", "material": "steel", "charge": "28 g"}).shot.diameter == 0.002413  # US 7.5 is UK 7
    assert shot_with({"size": "US 7 1/2"}, density=7000, count=5).shot.diameter == 0.002413
    assert shot_with({"size": "us #7½"}, density=7000, count=5).shot.diameter == 0.002413
    assert shot_with({"size": "2.4 mm", "material": "bismuth"}, count=5).shot.diameter == 0.0024
    assert shot_with({"size": "IT 8", "material": "Tungsten Matrix"}, count=5).shot.density == 10800.0


def test_the_scenes_own_keys_override_the_load():
    scene = shot_with({"size": "US 8", "material": "lead", "charge": "24 g"}, diameter="2.4 mm", density=11000, count=300)
    assert (scene.shot.diameter, scene.shot.density, scene.shot.count) == (0.0024, 11000.0, 300)
    # the charge is counted with the scene's diameter and density when given
    scene = shot_with({"size": "US 8", "material": "lead", "charge": "24 g"}, density=7800.0)
    assert scene.shot.count == count_of(0.024, 0.002286, 7800.0)
    assert scene_from_dict(tomllib.loads(scene.to_toml())) == scene  # the record round-trips


def test_the_count_rounds_to_the_nearest_pellet_halves_up():
    one = 11100.0 * math.pi * 0.002**3 / 6
    assert count_of(2.5 * one, 0.002, 11100.0) == 3 and count_of(2.49 * one, 0.002, 11100.0) == 2
    assert count_of(3.5 * one, 0.002, 11100.0) == 4  # (not the even 4 of round(); halves up)
    assert shot_with({"size": "2 mm", "material": "lead", "charge": 1.0 * one}).shot.count == 1


@pytest.mark.parametrize(
    ("load", "shot", "message"),
    [
        (
            {"size": "US 13", "material": "lead"},
            {},
            "shot.load.size = 'US 13': unknown US size; US sizes: 12, 11, 10, 9, 8.5, 8, 7.5, 7, 6, 5, 4, 3, 2, 1, B, BB, "
            "BBB, T, TT, F, FF",
        ),
        ({"size": "UK 9"}, {}, "shot.load.size = 'UK 9': unknown UK size; UK sizes: 8, 7.5, 7,"),
        ({"size": "7.5"}, {}, "shot.load.size = '7.5': must name its numbering system and number"),
        ({"size": "EU 7"}, {}, "shot.load.size = 'EU 7': must name its numbering system and number"),
        ({"size": 7.5}, {}, "shot.load.size = 7.5: must name its numbering system"),
        ({"size": "3 m"}, {}, "shot.load.size = '3 m': must be a number in [1e-06, 1] (m)"),
        ({"size": "3 g"}, {}, "shot.load.size = '3 g': shot.load.size takes a length (m); 'g' is a mass"),
        ({"material": "led"}, {}, "shot.load.material = 'led': unknown material; did you mean lead? allowed: lead, pure lead,"),
        (
            {"size": "US BB", "material": "lead", "charge": "0.1 g"},
            {},
            "shot.load.charge = '0.1 g': gives 0.18 pellets of 4.572 mm and 11100 kg/m^3; a charge holds 1 to 2147483647 "
            "pellets (at least one pellet's mass, 0.5554 g)",
        ),
        (
            {"size": "US 8", "charge": "24 g"},
            {},
            "shot.load.charge = '24 g': needs the pellet's density: give shot.load.material",
        ),
        (
            {"size": "US 8", "charge": "24 m"},
            {},
            "shot.load.charge = '24 m': shot.load.charge takes a mass (kg); 'm' is a length",
        ),
        ({"size": "US 8", "charge": -1}, {}, "shot.load.charge = -1: must be a number in (0, 100] (kg)"),
        ({"size": "US 8", "weight": 1}, {}, "shot.load.weight = 1: unknown key; allowed keys: size, material, charge"),
        ("US 8", {}, 'shot.load = \'US 8\': must be a table {size = "US 7.5", material = "lead", charge = "1 1/8 oz"}'),
        ({"size": "US 8"}, {"density": 11000}, "shot.count = (missing): is required without shot.file (or shot.load.charge)"),
        ({"charge": "1 oz"}, {"count": 1}, "shot.load.charge = '1 oz': needs the pellet's diameter: give shot.load.size"),
        ({"material": "lead"}, {"count": 1}, "shot.diameter = (missing): is required (or shot.load.size)"),
    ],
)
def test_a_bad_load_is_one_line_naming_key_value_and_what_is_allowed(load, shot, message):
    with pytest.raises(SceneError) as info:
        shot_with(load, **shot)
    assert str(info.value).startswith(message) and "\n" not in str(info.value)


def test_a_charge_of_less_than_a_pellet_stops_the_command_before_any_work(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    out = tmp_path / "out.h5"
    scene.write_text(
        '[shot]\nload = {size = "US BB", material = "lead", charge = "0.1 g"}\nspeed = 400\n'
        "[[surfaces]]\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\nrestitution = 0.5\nmu_s = 0.3\n"
    )
    assert main(["run", str(scene), "-o", str(out), "--device", "cpu"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("warp-ricochet: error: shot.load.charge = '0.1 g': gives 0.18 pellets") and err.count("\n") == 1
    assert not out.exists() and not (tmp_path / "out.h5.partial").exists()


def test_the_run_file_holds_the_load_with_units_and_sources(tmp_path):
    shot = shot_with({"size": "US 7.5", "material": "lead", "charge": "28 g"}).shot
    with h5py.File(tmp_path / "f.h5", "w") as f:
        _write_load(f.create_group("load"), shot)
        a = dict(f["load"].attrs)
    assert (a["size"], a["material"], a["charge"], a["charge_units"]) == ("US 7.5", "lead", 0.028, "kg")
    assert (a["diameter"], a["diameter_units"], a["density_units"], a["count"]) == (0.002413, "m", "kg/m^3", shot.count)
    assert any("chuckhawks.com" in s for s in a["sources"]) and any("fiocchi.com" in s for s in a["sources"])
    assert describe_load(dict(shot.load)) == "US 7.5 lead, 28 g charge"


def test_the_loads_command_lists_every_size_and_material_with_sources(capsys):
    assert main(["loads"]) == 0
    out = capsys.readouterr().out
    assert "US 7.5   2.41 mm  0.095 in" in out and "UK 7     2.41 mm  0.095 in" in out and "IT 9.5   2.00 mm" in out
    for name, material in MATERIALS.items():
        assert f"{name:<16} {material.density:7,.0f} kg/m^3" in out and material.source.url in out
    for sources, table, _unit in SYSTEMS.values():
        assert all(s.url in out for s in sources) and len(table) >= 10


def test_a_runs_file_holds_its_load(tmp_path):
    """The run writes /constants/load (a small run on the CPU: the paper's scene, 20 pellets)."""
    import warp_ricochet as wr

    scene = shot_with({"size": "UK 7", "material": "lead", "charge": "28 g"}, count=20)
    wr.run(scene, tmp_path / "run.h5", device="cpu")
    with h5py.File(tmp_path / "run.h5", "r") as f:
        a = dict(f["constants/load"].attrs)
        toml = f.attrs["scene_toml"]
    assert (a["size"], a["charge"], a["count"], a["diameter"], a["density"]) == ("UK 7", 0.028, 20, 0.002413, 11100.0)
    assert tomllib.loads(toml)["shot"]["load"] == {"size": "UK 7", "material": "lead", "charge": 0.028}
