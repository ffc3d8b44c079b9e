"""Ground materials: the catalogue of `[[surfaces]] material = "..."`, each value with its source
(docs/ground.md, "Ground materials"), and the host-side conversions the kernels' `Material` needs.

A material is a name ("turf") or one end of its bracket ("turf:far", "turf:near"): where the
sources disagree or give a range, "far" is the end that lets a pellet run or ricochet farther
(lower friction, rolling and ploughing resistance, a larger critical angle, rougher ground, which
"will increase ricochet and enlarge the surface danger zone", MIL-HDBK-1027/3B), "near" the other.
The plain name is the far end: this package answers safety questions, and a danger distance must
not come out short because the ground was taken softer than it may be. Every value may be
overridden key by key in the scene.

Keys (SI, angles in degrees as the sources give them):
- restitution E, mu_s, mu_d: the impact law's (physics/impact.py);
- rolling_resistance c: a resisting force c N while rolling (5/7 c g on a level plane);
- ploughing c2 (kg/m^3) and ploughing_area f: Poncelet's speed-squared resistance F = c2 A_eff v^2
  of the ground a pellet ploughs through, A_eff = f pi R^2 its ploughing cross-section: per unit
  mass b v^2 with b = c2 f pi R^2 / m = 3 c2 f / (4 rho_p R) (`ploughing_rate`);
- critical_angle theta_0, critical_angle_rise k (deg s/m), critical_speed v_c (m/s): a pellet
  striking steeper (from the surface) than theta_c(v) = theta_0 + k min(v, v_c) enters the ground
  (embeds); 90 deg: never. On water theta_0 is Johnson's constant: theta_c = theta_0 / sqrt(SG);
- roughness sigma (deg): the tilt of the local normal per impact, Rayleigh-distributed with mode
  sigma (physics/ground.py); restitution_scatter, friction_scatter: the per-impact scatter of E
  and of mu (relative; docs/ground.md "Rough ground");
- skip_loss (water only): tan(beta) of the water's force on a skipping sphere; a skip keeps
  exp(-2 theta skip_loss) of the speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

# the keys a [[surfaces]] table may override, in the order of the kernels' Material after E, mu_s, mu_d
GROUND_KEYS = (
    "rolling_resistance",
    "ploughing",
    "ploughing_area",
    "critical_angle",
    "critical_angle_rise",
    "critical_speed",
    "roughness",
    "restitution_scatter",
    "friction_scatter",
    "skip_loss",
)
NO_CRITICAL_ANGLE = 90.0  # deg: every impact angle ricochets (never embeds)
# a surface without `material`: the rigid plane of today (no rolling resistance, ploughing,
# embedding or roughness)
RIGID = {
    "rolling_resistance": 0.0,
    "ploughing": 0.0,
    "ploughing_area": 0.0,
    "critical_angle": NO_CRITICAL_ANGLE,
    "critical_angle_rise": 0.0,
    "critical_speed": 0.0,
    "roughness": 0.0,
    "restitution_scatter": 0.0,
    "friction_scatter": 0.0,
    "skip_loss": 0.0,
}
WATER_DENSITY = 1000.0  # kg/m^3: the specific gravity SG of Johnson's law is rho_p / this
MAX_ROUGHNESS = 15.0  # deg: the Rayleigh draw's largest tilt (24-bit uniforms) stays below 90 deg (physics/ground.py)

# allowed range of each key: (low, high, unit, why the bound)
RANGES = {
    "rolling_resistance": (0.0, 1.0, "1", "published rolling coefficients are below 0.5; 1 holds a sphere on a 45 deg slope"),
    "ploughing": (0.0, 2e4, "kg/m^3", "c2 = C rho_ground with C at most ~5 and rho_ground at most ~3000 kg/m^3"),
    "ploughing_area": (0.0, 1.0, "1", "a fraction of the pellet's cross-section"),
    "critical_angle": (0.0, 90.0, "deg", "an angle from the surface"),
    "critical_angle_rise": (0.0, 90.0, "deg s/m", "an angle per speed"),
    "critical_speed": (0.0, 1e5, "m/s", "a speed"),
    "roughness": (0.0, MAX_ROUGHNESS, "deg", "the tilt's mode; larger tilts could pass 90 deg"),
    "restitution_scatter": (0.0, 1.0, "1", "a fraction of E"),
    "friction_scatter": (0.0, 1.0, "1", "the log-normal's sigma"),
    "skip_loss": (0.0, 10.0, "1", "tan(beta) of the water's force"),
}


@dataclass(frozen=True)
class Entry:
    """A catalogue material: its bracket's two ends (dicts of every key), whether it is a liquid,
    and the source of each key."""

    far: dict
    near: dict
    sources: dict
    liquid: bool = False
    note: str = ""
    ends: tuple = field(default=("far", "near"), repr=False)


def _ends(**values):
    """(far, near) dicts from keyword values, each a number (both ends) or a (far, near) pair."""
    far, near = dict(RIGID), dict(RIGID)
    for key, value in values.items():
        far[key], near[key] = value if isinstance(value, tuple) else (value, value)
    return far, near


def _entry(sources, liquid=False, note="", **values) -> Entry:
    far, near = _ends(**values)
    return Entry(far=far, near=near, sources=sources, liquid=liquid, note=note)


# Sources, cited as [key]; "estimate" marks values no source read for this package gives (docs/ground.md
# says what could be read). Soil friction mu_s = tan(phi), phi the internal friction angle 30-35 deg of
# sands and compacted soils (a textbook range, e.g. Terzaghi, Peck & Mesri, "Soil Mechanics in Engineering
# Practice", 3rd ed., 1996: not read here); mu_d = 0.9 mu_s as the paper's (Zohdi 2021) unless given.
_STIMP = "USGA Stimpmeter: c = 7 v0^2 / (10 g S), v0 = 1.83 m/s, S the stimp distance (Penner, Can. J. Phys. 80 (2002) 83)"
_PONCELET = (
    "Poncelet F = A (c0 + c2 v^2); c2 = C rho_ground, C from 0.5 (a sphere's Newton drag, C_D ~ 1) to 2 "
    "(granular inertial drag reported larger: Katsuragi & Durian, Nat. Phys. 3 (2007) 420, not read here): estimate"
)
_WRIGHT = (
    "Wright, Quillen et al. 2020 (arXiv 2002.01468, abstract read): the critical angle rises with speed; "
    "linear form and values estimates"
)
_ROUGH = "estimate; a rocky surface increases ricochet (MIL-HDBK-1027/3B)"
_SCATTER = "Montaine et al., arXiv 1104.0049 (two exponentials, abstract read); widths estimates"

CATALOGUE = {
    "steel_plate": _entry(
        {
            "restitution": "far 0.6: steel on steel at moderate speed (Goldsmith, Impact, 1960: not read here); near 0.3, a deforming lead pellet: estimate",
            "mu_s": "near: dry steel 0.74/0.57 (Serway & Jewett, table 5.1); far: a smooth plate 0.2/0.15 (examples/steel_plate.toml, estimate)",
            "rolling_resistance": "a steel wheel or ball on steel: 0.001-0.002 (the usual engineering tables' range, not read here)",
            "roughness": "estimate: a rolled plate",
            "restitution_scatter": _SCATTER,
            "friction_scatter": "estimate",
        },
        restitution=(0.6, 0.3),
        mu_s=(0.2, 0.74),
        mu_d=(0.15, 0.57),
        rolling_resistance=(0.001, 0.002),
        roughness=(1.0, 0.5),
        restitution_scatter=0.1,
        friction_scatter=0.1,
    ),
    "concrete": _entry(
        {
            "restitution": "estimate: lead and steel pellets deform on concrete",
            "mu_s": "estimate: metal on concrete 0.4-0.6",
            "rolling_resistance": "estimate: a steel ball on concrete",
            "roughness": _ROUGH,
            "restitution_scatter": _SCATTER,
            "friction_scatter": "estimate",
        },
        restitution=(0.4, 0.2),
        mu_s=(0.4, 0.6),
        mu_d=(0.35, 0.5),
        rolling_resistance=(0.01, 0.02),
        roughness=(3.0, 1.5),
        restitution_scatter=0.2,
        friction_scatter=0.2,
    ),
    "packed_soil": _entry(
        {
            "restitution": "estimate",
            "mu_s": "tan(30 deg) far, tan(35 deg) near (soil friction angles, Terzaghi, Peck & Mesri 1996, not read here); mu_d = 0.9 mu_s",
            "rolling_resistance": "estimate, between turf and sand",
            "ploughing": _PONCELET + "; rho 1800 kg/m^3",
            "ploughing_area": "estimate: a pellet ploughing 0.1-0.3 of its cross-section deep",
            "critical_angle": "far: no embedding law (never embeds); near: the sand law (" + _WRIGHT + ")",
            "roughness": _ROUGH,
            "restitution_scatter": _SCATTER,
            "friction_scatter": "estimate",
        },
        restitution=(0.3, 0.1),
        mu_s=(0.58, 0.70),
        mu_d=(0.52, 0.63),
        rolling_resistance=(0.05, 0.15),
        ploughing=(900.0, 3600.0),
        ploughing_area=(0.1, 0.3),
        critical_angle=(NO_CRITICAL_ANGLE, 5.0),
        critical_angle_rise=(0.0, 2.0),
        critical_speed=(0.0, 6.0),
        roughness=(5.0, 2.5),
        restitution_scatter=0.3,
        friction_scatter=0.2,
    ),
    "turf": _entry(
        {
            "restitution": "estimate: mown grass on soil",
            "mu_s": "far: examples/field.toml's 0.5/0.45; near 0.7/0.63: estimate",
            "rolling_resistance": "far: a green of stimp 3.66 m (12 ft), c = 0.065; near: mown grass of stimp ~1 m, c = 0.24 (estimate). "
            + _STIMP,
            "ploughing": _PONCELET + "; rho 1500 kg/m^3 (topsoil with roots, estimate)",
            "ploughing_area": "estimate: the grass mat holds a pellet up (far 0.05) or it cuts 0.3 of its cross-section deep",
            "critical_angle": "far: no embedding law (never embeds); near: the sand law (" + _WRIGHT + ")",
            "roughness": "estimate: a lawn",
            "restitution_scatter": _SCATTER,
            "friction_scatter": "estimate",
        },
        restitution=(0.3, 0.15),
        mu_s=(0.5, 0.7),
        mu_d=(0.45, 0.63),
        rolling_resistance=(0.065, 0.24),
        ploughing=(750.0, 3000.0),
        ploughing_area=(0.05, 0.3),
        critical_angle=(NO_CRITICAL_ANGLE, 5.0),
        critical_angle_rise=(0.0, 2.0),
        critical_speed=(0.0, 6.0),
        roughness=(6.0, 3.0),
        restitution_scatter=0.3,
        friction_scatter=0.2,
    ),
    "sand": _entry(
        {
            "restitution": "estimate",
            "mu_s": "tan(30 deg) far, tan(35 deg) near (sand friction angles, Terzaghi, Peck & Mesri 1996, not read here)",
            "mu_d": "mu_s / 5 far, mu_s / 4 near: friction during penetration 4-5x lower than the sand's (Wright et al. 2020, abstract)",
            "rolling_resistance": "estimate: a ball rolling on loose sand",
            "ploughing": _PONCELET + "; rho 1600 kg/m^3",
            "ploughing_area": "estimate",
            "critical_angle": _WRIGHT + "; held above critical_speed (an extrapolation to pellet speeds)",
            "roughness": "estimate: ripples",
            "restitution_scatter": _SCATTER,
            "friction_scatter": "estimate",
        },
        restitution=(0.2, 0.05),
        mu_s=(0.58, 0.70),
        mu_d=(0.116, 0.175),
        rolling_resistance=(0.1, 0.3),
        ploughing=(800.0, 3200.0),
        ploughing_area=(0.1, 0.3),
        critical_angle=(10.0, 5.0),
        critical_angle_rise=(4.0, 2.0),
        critical_speed=6.0,
        roughness=(4.0, 2.0),
        restitution_scatter=0.3,
        friction_scatter=0.2,
    ),
    "gravel": _entry(
        {
            "restitution": "far 0.4, near 0.2 (examples/steel_plate.toml's 0.3 between): estimate",
            "mu_s": "far: examples/steel_plate.toml's 0.6/0.5; near 0.8/0.7: estimate",
            "rolling_resistance": "estimate",
            "roughness": _ROUGH,
            "restitution_scatter": _SCATTER,
            "friction_scatter": "estimate",
        },
        restitution=(0.4, 0.2),
        mu_s=(0.6, 0.8),
        mu_d=(0.5, 0.7),
        rolling_resistance=(0.1, 0.3),
        roughness=(12.0, 6.0),
        restitution_scatter=0.3,
        friction_scatter=0.3,
    ),
    "water": _entry(
        {
            "critical_angle": "Johnson & Reid 1975 (not read here): theta_c = 18 deg / sqrt(SG), as quoted by Nagahiro & Hayakawa ("
            "arXiv physics/0411125, read)",
            "skip_loss": "the Birkhoff-Johnson skip model with the force at a fixed angle beta to the normal of the "
            "velocity: v_out / v_in = exp(-2 theta tan(beta)) (docs/ground.md); tan(beta) 0.5-2: estimate",
        },
        liquid=True,
        note="a pellet skips below the critical angle and sinks otherwise, or once it would stay on the surface",
        restitution=0.0,
        mu_s=0.0,
        mu_d=0.0,
        critical_angle=18.0,
        skip_loss=(0.5, 2.0),
    ),
}


def split(name: str) -> tuple[str, str]:
    """("turf", "far") of "turf" or "turf:far"; ("turf", "near") of "turf:near"."""
    base, _, end = name.partition(":")
    return base, end or "far"


def names() -> tuple[str, ...]:
    """Every name `material` accepts: each material and each end of its bracket."""
    return tuple(n for base in CATALOGUE for n in (base, f"{base}:far", f"{base}:near"))


def resolve(name: str) -> dict:
    """Every key's value (restitution, mu_s, mu_d and GROUND_KEYS) of a catalogue name; KeyError if unknown."""
    base, end = split(name)
    entry = CATALOGUE[base]
    if end not in entry.ends:
        raise KeyError(name)
    return dict(getattr(entry, end))


def is_liquid(name: str | None) -> bool:
    """Whether material `name` (None: the rigid plane) is a liquid (water)."""
    return name is not None and CATALOGUE[split(name)[0]].liquid


def ploughing_rate(ploughing: float, area: float, radius: float, density: float) -> float:
    """b (1/m) of the per-unit-mass ploughing resistance b |v|^2: c2 f pi R^2 / m = 3 c2 f / (4 rho_p R)
    for ground coefficient c2 (kg/m^3), ploughing fraction f of the cross-section, radius R (m) and
    pellet density rho_p (kg/m^3)."""
    return 3.0 * ploughing * area / (4.0 * density * radius)


def critical_angle(surface, density: float) -> float:
    """theta_0 (rad) of a surface for a pellet of `density` (kg/m^3): on a liquid Johnson's
    theta_0 / sqrt(SG), SG = density / WATER_DENSITY; else theta_0 itself (90 deg: none)."""
    theta = surface.critical_angle if surface.critical_angle is not None else NO_CRITICAL_ANGLE
    if is_liquid(surface.material):
        theta = theta / math.sqrt(density / WATER_DENSITY)
    return math.radians(theta)


def stop_distance(speed: float, rolling_resistance: float, rate: float, gravity: float = 9.81) -> float:
    """A sphere's closed-form rolling run-out (m) on a level plane from `speed` (m/s) against c N and
    the ploughing b v^2 (per unit mass, 1/m): v dv/dx = -5/7 (c g + b v^2), so
    x = 7/(10 b) ln(1 + b v^2/(c g)) (b = 0: 7 v^2 / (10 c g); c = 0 and b = 0: inf)."""
    c, b, v = rolling_resistance, rate, speed
    if b == 0.0:
        return math.inf if c == 0.0 else 7.0 * v * v / (10.0 * c * gravity)
    if c == 0.0:
        return math.inf  # b v^2 alone never stops it (logarithmic)
    return 7.0 / (10.0 * b) * math.log1p(b * v * v / (c * gravity))
