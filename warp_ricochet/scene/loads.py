"""Shot loads: `[shot] load = {size = "US 7.5", material = "lead", charge = "1 1/8 oz"}` resolved to
the pellet's diameter (m), density (kg/m^3) and count per shot, from the catalogue below; each
table is cited beside its data (docs/scenes.md, "Shot loads").

Shot numbers differ between numbering systems (US 7.5 is 0.095 in, UK 7.5 is 0.090 in, Italian
7 is 2.5 mm), so a size names its system: "US 7.5" (also "US 7 1/2", "US 7½", "US #7.5"), "UK 7",
"IT 9.5", or a diameter with its unit ("2.4 mm", as central European makers label shot). The count
is the charge's mass over one pellet's, rho pi d^3 / 6, rounded to the nearest integer (halves
up); a charge lighter than one pellet is refused. Explicit shot.diameter, shot.density and
shot.count override what the load gives.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .keys import MISSING, check_keys, err, join, suggest
from .units import split_unit

INCH = 0.0254  # m
OUNCE = 0.028349523125  # kg, avoirdupois


@dataclass(frozen=True)
class Source:
    """A published table: its name, publisher, year and address."""

    name: str
    publisher: str
    year: str
    url: str

    def __str__(self) -> str:
        return f"{self.name}, {self.publisher}, {self.year}, {self.url}"


FEDERAL = Source(
    "Federal Ammunition catalog, nominal diameters of US shot sizes, quoted in C. Hawks, "
    '"Shot Pellet Information and Recommendations"',
    "Guns and Shooting Online (chuckhawks.com)",
    "n.d.",
    "http://chuckhawks.com/shot_info.htm",
)
KEPHART = Source(
    'H. Kephart, Sporting Firearms, "Shot Patterns and Penetration": sizes of shot, American standard',
    "Outing Publishing Company",
    "1912",
    "http://bookdome.com/arts/Sporting-Firearms/Shot-Patterns-And-Penetration-Part-3.html",
)
PURDEY = Source(
    'T.D.S. and J.A. Purdey, The Shot Gun; Table 1 of J. Spencer, "Shotgun barrels and ammunition: specifications & performance"',
    "jonathan-spencer.co.uk",
    "2001",
    "http://www.jonathan-spencer.co.uk/Reference/Guns/Shotgun/Ammo/Shotsize1.htm",
)
MORI = Source(
    'E. Mori, "Pallini di acciaio" (Italian lead shot numbers, diameters in mm)',
    "earmi.it",
    "n.d.",
    "https://earmi.it/balistica/acciaio.htm",
)
FIOCCHI = Source(
    '"Quanti pallini in una cartuccia" (Italian numbering; lead with 2% antimony 11.1 g/cm^3, steel 7.8 g/cm^3)',
    "Fiocchi Munizioni",
    "n.d.",
    "https://fiocchi.com/it/blog/post/quanti-pallini-in-una-cartuccia",
)
FIELD = Source(
    '"Other non-toxic shot materials" (tungsten matrix 10.8, bismuth-tin 9.6, pure lead 11.3, lead with antimony 11 g/cm^3)',
    "The Field",
    "2021",
    "https://www.pressreader.com/uk/the-field/20210701/282114934509104",
)

# system -> (sources, {size: diameter in inches or mm as the source gives it}, the unit: INCH or 1e-3)
_US = {"12": 0.05, "11": 0.06, "10": 0.07, "9": 0.08, "8.5": 0.085, "8": 0.09, "7.5": 0.095, "7": 0.10, "6": 0.11}
_US |= {"5": 0.12, "4": 0.13, "3": 0.14, "2": 0.15, "1": 0.16, "B": 0.17, "BB": 0.18, "BBB": 0.19}
_US |= {"T": 0.20, "TT": 0.21, "F": 0.22, "FF": 0.23}
_UK = {"8": 0.087, "7.5": 0.090, "7": 0.095, "6.5": 0.099, "6": 0.102, "5.5": 0.107, "5": 0.110, "4": 0.120}
_UK |= {"3": 0.128, "2": 0.135, "1": 0.143, "B": 0.154, "BB": 0.161, "BBB": 0.170, "A": 0.180, "AA": 0.194}
_UK |= {"AAA": 0.203}
_IT = {"12": 1.5, "10": 1.8, "9.5": 2.0, "8": 2.3, "7": 2.5, "5": 2.9, "4.5": 3.0, "3": 3.3, "2": 3.5, "0": 3.9}
SYSTEMS = {
    # US: 9 to BBB from Federal; 10 to 12, B and T to FF from Kephart's American standard, whose
    # diameters are Federal's where both give them (the American standard: 17 - number hundredths
    # of an inch, tests/test_loads.py)
    "US": ((FEDERAL, KEPHART), _US, INCH),
    "UK": ((PURDEY,), _UK, INCH),  # English sizes (Purdey's diameters); UK 9 is in neither table
    "IT": ((MORI, FIOCCHI), _IT, 1e-3),  # 12 and 0 from Fiocchi, the others from Mori (mm)
}


@dataclass(frozen=True)
class Material:
    density: float  # kg/m^3
    source: Source
    note: str


MATERIALS = {
    "lead": Material(11100.0, FIOCCHI, "hardened shot: lead with about 2% antimony (The Field: 11 with antimony)"),
    "pure lead": Material(11300.0, FIELD, "soft (unhardened) lead"),
    "steel": Material(7800.0, FIOCCHI, "soft iron shot"),
    "bismuth": Material(9600.0, FIELD, "bismuth-tin alloy shot (pure bismuth 9.8)"),
    "tungsten matrix": Material(10800.0, FIELD, "tungsten powder in a polymer binder"),
}
LOAD_KEYS = ("size", "material", "charge")
LOAD_RULE = 'must be a table {size = "US 7.5", material = "lead", charge = "1 1/8 oz"} (any of them)'
_FRACTIONS = {"½": ".5", " 1/2": ".5", "-1/2": ".5"}


def diameter_of(size: str, path: str, as_length) -> float:
    """The diameter (m) of a size "SYSTEM NUMBER", or of a length with its unit ("2.4 mm"), which
    `as_length(text, path)` (shot.diameter's converter) converts and checks."""
    system, _, number = size.strip().partition(" ")
    system, number = system.upper(), number.strip().lstrip("#").strip().upper()
    if system not in SYSTEMS:
        if split_unit(size)[1]:  # a number with a unit
            return as_length(size, path)
        raise err(path, size, SIZE_RULE)
    for text, decimal in _FRACTIONS.items():
        number = number.replace(text, decimal)
    _sources, table, unit = SYSTEMS[system]
    if number not in table:
        raise err(path, size, f"unknown {system} size; {system} sizes: " + ", ".join(table))
    return float(f"{table[number] * unit:.15g}")  # (0.095 in is 0.002413 m, not 0.0024129999999999998)


SIZE_RULE = (
    'must name its numbering system and number: "US 7.5", "UK 7", "IT 9.5" (systems: '
    + ", ".join(SYSTEMS)
    + '), or be a diameter with its unit, e.g. "2.4 mm"'
)


def pellets(charge: float, diameter: float, density: float) -> float:
    """Pellets in a charge (kg) of spheres of `diameter` (m) and `density` (kg/m^3), unrounded."""
    return charge / (density * math.pi * diameter**3 / 6.0)


def count_of(charge: float, diameter: float, density: float) -> int:
    """The whole number of pellets in a charge: rounded to the nearest, halves up."""
    return math.floor(pellets(charge, diameter, density) + 0.5)


def check_load(v, path: str, charge_conv, diameter_conv) -> dict:
    """The validated table: size (a string; its diameter, m, as `diameter`), material (a catalogue
    name), charge (kg, > 0)."""
    if not isinstance(v, dict):
        raise err(path, v, LOAD_RULE)
    check_keys(v, path, LOAD_KEYS)
    out = {}
    if v.get("size") is not None:
        if not isinstance(v["size"], str):
            raise err(join(path, "size"), v["size"], SIZE_RULE)
        out["size"] = v["size"].strip()
        out["diameter"] = diameter_of(out["size"], join(path, "size"), diameter_conv)
    if v.get("material") is not None:
        name = v["material"]
        if not isinstance(name, str) or name.strip().lower() not in MATERIALS:
            shown = name if isinstance(name, str) else ""
            raise err(
                join(path, "material"), name, f"unknown material; {suggest(shown, MATERIALS)}allowed: " + ", ".join(MATERIALS)
            )
        out["material"] = name.strip().lower()
    if v.get("charge") is not None:
        out["charge"] = charge_conv(v["charge"], join(path, "charge"))
    return out


def apply_load(kw: dict, raw: dict, int_max: int) -> dict:
    """The shot's keys with the load's diameter, density and count where the scene gives none, and
    `load` its record ((key, value), ...): size, material and charge (kg) as given."""
    load = kw["load"]
    path = "shot.load"
    out = dict(kw)
    if "size" in load:
        out.setdefault("diameter", load["diameter"])
    if "material" in load:
        out.setdefault("density", MATERIALS[load["material"]].density)
    if "charge" in load:
        if "file" in kw:
            raise err(join(path, "charge"), raw["load"]["charge"], "not allowed with shot.file (its pellets are counted there)")
        for key, source in (("diameter", "size"), ("density", "material")):
            if key not in out:
                raise err(
                    join(path, "charge"),
                    raw["load"]["charge"],
                    f"needs the pellet's {key}: give shot.load.{source} or shot.{key}",
                )
        n = pellets(load["charge"], out["diameter"], out["density"])
        if n < 1.0 or n >= int_max + 0.5:
            mass = out["density"] * math.pi * out["diameter"] ** 3 / 6.0
            raise err(
                join(path, "charge"),
                raw["load"]["charge"],
                f"gives {n:.3g} pellets of {out['diameter'] * 1e3:.4g} mm and {out['density']:g} kg/m^3; "
                f"a charge holds 1 to {int_max} pellets (at least one pellet's mass, {mass * 1e3:.4g} g)",
            )
        out.setdefault("count", count_of(load["charge"], out["diameter"], out["density"]))
    out["load"] = tuple((key, load[key]) for key in LOAD_KEYS if key in load)
    return out


def required(kw: dict, key: str, rule: str) -> None:
    """A missing shot.diameter or shot.density, named with the load key that would give it."""
    if key not in kw:
        source = {"diameter": "size", "density": "material"}[key]
        raise err(f"shot.{key}", MISSING, f"is required (or shot.load.{source}); it {rule}")


def describe_load(load: dict) -> str:
    """A load in words: "US 7.5 lead, 31.9 g charge" (the keys given)."""
    words = " ".join(str(load[key]) for key in ("size", "material") if key in load)
    charge = f"{float(load['charge']) * 1e3:.3g} g charge" if "charge" in load else ""
    return ", ".join(w for w in (words, charge) if w)


def sources_of(record) -> list[str]:
    """The citations of the tables a load record's size and material come from."""
    load = dict(record or ())
    out = []
    system = str(load.get("size", "")).strip().partition(" ")[0].upper()
    if system in SYSTEMS:
        out += [str(s) for s in SYSTEMS[system][0]]
    if "material" in load:
        out.append(str(MATERIALS[load["material"]].source))
    return list(dict.fromkeys(out))


def catalogue_lines() -> list[str]:
    """`warp-ricochet loads`: every size of each system (mm and inch) and every material, with sources."""
    lines = ['Shot sizes: [shot] load = {size = "US 7.5", material = "lead", charge = "1 1/8 oz"}', ""]
    lead = MATERIALS["lead"].density
    for system, (sources, table, unit) in SYSTEMS.items():
        lines.append(f"{system} sizes (diameter; pellets per ounce of lead at {lead:,.0f} kg/m^3):")
        for name, value in table.items():
            d = value * unit
            lines.append(f"  {system} {name:<4} {d * 1e3:5.2f} mm  {d / INCH:.3f} in  {pellets(OUNCE, d, lead):7.1f} per oz")
        lines += [f"  source: {s}" for s in sources] + [""]
    lines.append('Or a diameter with its unit: size = "2.4 mm".')
    lines += ["", "Materials (density):"]
    for name, m in MATERIALS.items():
        lines.append(f"  {name:<16} {m.density:7,.0f} kg/m^3  {m.note}")
        lines.append(f"  {'':<16} source: {m.source}")
    lines += ["", "count = charge / (density pi d^3 / 6), rounded to the nearest integer; shot.diameter,"]
    lines.append("shot.density and shot.count given in the scene override the load's (docs/scenes.md).")
    return lines
