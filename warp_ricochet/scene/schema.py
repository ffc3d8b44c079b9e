"""The scene's validated, frozen dataclasses and the physical domain the kernels are built for (SI units)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ..fields import default_fields
from ..physics.drag_tables import DRAG_TABLES
from .materials import RIGID
from .patterns import pattern_spread
from .toml_out import plain, toml_lines

Vec3 = tuple[float, float, float]
INT32_MAX = 2**31 - 1

# The physical domain the kernels are built for: every product they form stays far inside float32
# (speeds^2 ~ 1e10, spins times radii ~ 1e8), so a float32 run cannot overflow or lose a pellet.
MIN_DIAMETER, MAX_DIAMETER = 1e-6, 1.0  # m
MIN_DENSITY, MAX_DENSITY = 1.0, 1e5  # kg/m^3
MAX_SPEED = 1e5  # m/s
MAX_SPIN = 1e8  # rad/s, each component
MAX_COORDINATE = 1e6  # m, each component of positions (and of direction vectors)
MAX_GRAVITY = 1e4  # m/s^2, each component
MAX_FRICTION = 100.0
MAX_IMPACT_DURATION = 1.0  # s
MAX_AIR_DENSITY = 100.0  # kg/m^3: gases (the laws of docs/air.md are for a gas)
MAX_WIND = 1e3  # m/s, each component

SURFACE_KINDS = ("plane", "rectangle", "disc", "box", "mesh", "terrain", "cylinder")  # [[surfaces]] kind (docs/geometry.md)
PERPENDICULAR = 1e-9  # a rectangle's axis_u within this (cosine) of perpendicular to its normal
FLOAT32_EXACT_STEPS = 2**24  # float32 counts every integer up to here
CHECKPOINT_STEPS = 8  # a shot's steps between checkpoints when collisions.frame_every is 0 (dense.constants.BLOCK_STEPS)
# shot keys that a pellet file replaces
FILE_EXCLUSIVE = ("speed", "direction", "direction_jitter", "envelope_radius", "envelope_center", "spin", "seed")


@dataclass(frozen=True)
class Shot:
    """The pellets: sampled from count/speed/direction/... or read from a pellet file (`file`, absolute path)."""

    diameter: float  # m
    density: float  # kg/m^3
    count: int = 0  # pellets per shot
    shots: int = 1  # independent shots of `count` pellets each
    speed: float = 0.0  # m/s
    direction: Vec3 = (1.0, -1.0, 0.0)  # not normalised
    direction_jitter: Vec3 = (0.0, 0.0, 0.0)
    envelope_radius: float = 0.0  # m
    envelope_center: Vec3 = (0.0, 0.0, 0.0)  # m
    spin: Vec3 = (0.0, 0.0, 0.0)  # rad/s
    seed: int = 0
    file: str | None = None
    choke: str | None = None  # scene.patterns.CHOKES: gives `pattern`
    pattern: float | None = None  # percent of the charge in a 30-inch circle at 40 yards (replaces the jitter)
    # the shot load the diameter, density and count came from (scene.loads): (("size", "US 7.5"),
    # ("material", "lead"), ("charge", kg)), the keys given; None without [shot] load
    load: tuple | None = None

    @property
    def pellets(self) -> int:
        """All pellets of the run: count per shot times shots."""
        return self.count * self.shots

    @property
    def pattern_spread(self) -> float | None:
        """The pattern's angular spread (tan of the polar angle per axis, ~ rad; scene.patterns), else None."""
        return None if self.pattern is None else pattern_spread(self.pattern)


@dataclass(frozen=True)
class Surface:
    """A plane through `point` (m) with unit `normal` pointing to the side the pellets come from; or,
    with `kind`, a finite plate in that plane centred on `point` (docs/geometry.md): a "rectangle" of
    sides `size` (m) along the unit `axis_u` and normal x axis_u, or a "disc" of `radius` (m); or
    triangles (scene.triangles): a "box" (centre `point`, sides `size` along axis_u, normal x axis_u
    and normal) or a "mesh" read from `file`, its vertices moved by `point`; or a "cylinder" (a post:
    base centre `point`, axis `normal` from base to top, `radius` and `length`, m)."""

    point: Vec3
    normal: Vec3
    restitution: float
    mu_s: float
    mu_d: float | None = None
    name: str = ""
    # ground materials (scene/materials.py, docs/ground.md): the catalogue name and every value it
    # resolves to with the scene's overrides; None without `material` and the key (a rigid plane:
    # scene.materials.RIGID)
    material: str | None = None
    rolling_resistance: float | None = None  # c: resisting force c N while rolling
    ploughing: float | None = None  # kg/m^3: Poncelet's c2
    ploughing_area: float | None = None  # fraction of the pellet's cross-section ploughing
    critical_angle: float | None = None  # deg from the surface (water: Johnson's 18 deg / sqrt(SG) constant)
    critical_angle_rise: float | None = None  # deg s/m
    critical_speed: float | None = None  # m/s: the rise stops here
    roughness: float | None = None  # deg: the mode of the normal's Rayleigh tilt
    restitution_scatter: float | None = None  # relative
    friction_scatter: float | None = None  # log-normal sigma
    skip_loss: float | None = None  # water: tan(beta)
    kind: str | None = None  # None: an infinite plane ("plane"); "rectangle" or "disc": a plate; "terrain"
    axis_u: Vec3 | None = None  # a rectangle's first side (unit, perpendicular to normal)
    size: tuple[float, float] | None = None  # m: a rectangle's sides along axis_u and normal x axis_u
    radius: float | None = None  # m: a disc's, a cylinder's
    length: float | None = None  # m: a cylinder's, along its axis (`normal`) from its base centre `point`
    two_sided: bool | None = None  # True: a plate met from either face; None: from the normal's side only
    file: str | None = None  # a mesh's file (absolute; its vertices moved by `point`) or terrain's raster
    # terrain (scene.terrain): the raster's (x, y) and elevation (m) placed at `point` (None: its
    # stored corner, 0), a value taken as nodata; `normal` is its up
    origin: tuple[float, float] | None = None
    elevation: float | None = None
    nodata: float | None = None

    @property
    def is_plane(self) -> bool:
        """An infinite plane (no `kind`, or kind = "plane")."""
        return self.kind is None

    @property
    def is_mesh(self) -> bool:
        """Made of triangles (a box, a mesh: `scene.triangles`; a terrain: `scene.terrain`)."""
        return self.kind in ("box", "mesh", "terrain")

    @property
    def is_solid(self) -> bool:
        """Triangles (`is_mesh`) or a post: compiled in with the meshes (`spec.plates` MESHES)."""
        return self.is_mesh or self.kind == "cylinder"

    def ground(self, key: str) -> float:
        """The value of a ground key (scene.materials.GROUND_KEYS): its own, else the rigid plane's."""
        value = getattr(self, key)
        return RIGID[key] if value is None else value


@dataclass(frozen=True)
class Physics:
    """`bounces`: the ricochets before the landing (the landing fields); `until`: "rest" follows every
    pellet on to where it stops (docs/ground.md), "landing" ends it at the landing; `rest_speed` (m/s):
    a pellet on a surface slower than it, and held there, is at rest (None: sqrt(10 g R / 7), the speed
    below which a rolling pellet cannot climb a step of its own radius); `max_impacts`: the impacts a
    pellet may make (its budget: past it, and past `max_steps` integration steps of its motion along
    surfaces, it is "not finished")."""

    gravity: Vec3 = (0.0, -9.81, 0.0)  # m/s^2
    impact_duration: float = 0.0  # s
    bounces: int = 1
    until: str = "rest"
    rest_speed: float | None = None  # m/s
    max_impacts: int = 1000
    max_steps: int = 100_000

    def rest_speed_for(self, radius: float) -> float:
        """The rest speed (m/s) for a pellet of `radius` (m): the key's, else sqrt(10 |g| R / 7)."""
        if self.rest_speed is not None:
            return self.rest_speed
        g = sum(x * x for x in self.gravity) ** 0.5
        return (10.0 * g * radius / 7.0) ** 0.5


# Steel on steel (docs/collisions.md): restitution 0.9 for hardened steel spheres at low speed
# (Goldsmith, "Impact", 1960); dry friction mu_s 0.74, mu_d 0.57 (Serway & Jewett, Physics for
# Scientists and Engineers, table 5.1). contact_duration: the Hertz contact time of two 2.5 mm steel
# spheres at 10 m/s is about 0.3 us; 1 us is the TC model's default window.
@dataclass(frozen=True)
class Collisions:
    """Pellet-pellet collisions (the paper neglects them). Off unless `enabled`."""

    enabled: bool = False
    restitution: float = 0.9  # pair E, on the normal relative velocity
    mu_s: float = 0.74
    mu_d: float | None = 0.57  # <= mu_s; defaults to min(0.57, mu_s)
    contact_duration: float = 1e-6  # s, TC model: a pellet hit again within it rebounds elastically
    time_step: float | None = None  # s, fixed step of the dense phase; None adapts it
    step_fraction: float = 0.25  # adaptive step: closing displacement per step / diameter
    air_step_fraction: float = 0.01  # in air, adaptive step: at most this of |u| / |a_air| (dense/air.py)
    air_leaps: bool = True  # in air, leap to the next possible event past the arrival window (dense/leap.py)
    skin: float = 2.25  # neighbour-list skin, in diameters (9 x step_fraction: a list lasts a block of 8 steps, and one more)
    rounds: int = 4  # event rounds per step (several contacts of one pellet)
    max_neighbours: int = 32  # per pellet in the neighbour list at first (grows when needed)
    max_steps: int = 1_000_000  # the dense phase stops (and says so) after these
    frame_every: int = 0  # H5MD trajectory frame every k steps (0: none)
    separate: bool = True  # sample each shot without overlaps (launch.sampling); false: as without collisions


# International Standard Atmosphere at sea level (15 C, 101,325 Pa): density 1.225 kg/m^3, sound speed
# 340.3 m/s = sqrt(1.4 x 287.05 x 288.15), viscosity 1.789e-5 Pa s (Sutherland's law at 288.15 K;
# 1.81e-5 is the 20 C value). docs/air.md gives every default's source.
@dataclass(frozen=True)
class Air:
    """Flight in air: drag, Magnus lift, spin decay, wind (docs/air.md). Absent: the vacuum's exact
    parabola. density = 0 is the vacuum too."""

    density: float = 1.225  # kg/m^3
    viscosity: float = 1.789e-5  # Pa s
    sound_speed: float = 340.3  # m/s
    wind: Vec3 = (0.0, 0.0, 0.0)  # m/s; drag and lift act on u = v - wind
    drag: str = "loth2021"  # "loth2021" | "constant" | "table"
    drag_coefficient: float | None = None  # the constant law's C_D (required with it)
    drag_table: str | tuple | None = None  # the table law's: "braun" (default), "gs", or ((mach, C_D), ...)
    drag_factor: float = 1.0  # multiplies C_D (shot programs: 0.90 to 1.15)
    magnus: bool = True
    lift: str = "loth2008"  # "loth2008" | "linear" | "sawicki2003"
    lift_slope: float | None = None  # the linear law's C_L / S (default 0.5)
    lift_max: float | None = None  # the cap on C_L of every lift law (default: `cap`)
    spin_decay: bool = True
    spin_decay_law: str = "dennis1980"  # "dennis1980" | "loth2008"

    @property
    def table(self):
        """The table law's ((Mach, C_D), ...): its own or a named one."""
        table = self.drag_table or "braun"
        return DRAG_TABLES[table] if isinstance(table, str) else table

    @property
    def slope(self) -> float:
        return 0.5 if self.lift_slope is None else self.lift_slope

    @property
    def cap(self) -> float:
        """The largest C_L: sawicki2003's published cap (0.4), else 0.5 (docs/air.md 2.2)."""
        if self.lift_max is not None:
            return self.lift_max
        return 0.4 if self.lift == "sawicki2003" else 0.5

    @property
    def still(self) -> bool:
        """No air at all (density 0): the vacuum's flight."""
        return self.density == 0.0


FLIGHT_TOLERANCE = 1e-6  # numerics.flight_tolerance by default (bench/RESULTS.md: the knee of run time against error)
SURFACE_TOLERANCE = 1e-6  # numerics.surface_tolerance by default (docs/ground.md 9)
MIN_FLIGHT_TOLERANCE = {"float32": 1e-6, "float64": 1e-12}  # what each precision can resolve


@dataclass(frozen=True)
class Numerics:
    precision: str = "float32"
    chunk_size: int | None = None  # None: automatic
    fast_math: bool = True  # CUDA float32: approximate div/sqrt/sin (see README)
    flight_tolerance: float = FLIGHT_TOLERANCE  # relative, of the integrated flight in air
    surface_tolerance: float = SURFACE_TOLERANCE  # relative, of the integrated phases along surfaces


# Tail fractions (share of landed pellets beyond these distances from the shooter), m
TAIL_DISTANCES = (1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0)


@dataclass(frozen=True)
class Output:
    path: str | None = None  # relative to the current working directory
    fields: tuple[str, ...] = default_fields(False, False, True)  # "group.field", canonical order (until = "rest")
    quantiles: bool = True  # landing histograms: quantiles, tail fractions (docs/hazard.md)
    tail_distances: tuple[float, ...] = TAIL_DISTANCES  # m, from the shooter
    compression: str = "none"  # of the per-pellet datasets: COMPRESSIONS (docs/output.md)


# output.compression -> h5py's create_dataset filter options (shuffle: bytes grouped by significance first)
COMPRESSIONS = {
    "none": {},
    "lzf": {"compression": "lzf", "shuffle": True},
    **{f"gzip-{level}": {"compression": "gzip", "compression_opts": level, "shuffle": True} for level in range(1, 10)},
}


# Hazard thresholds (docs/hazard.md; ../shared/reference/air-and-hazard-sources.md). Energy density
# E/A, J/m^2: eye, 50% risk (Duma et al., J Trauma 2005, doi:10.1097/01.ta.0000174830.55282.32)
# of corneal abrasion 1,503 and of globe rupture 23,771; eye penetration ~4.3 J/cm^2 (Marshall,
# Dahlstrom, Powley 2011, Am J Forensic Med Pathol 32(2), pig eyes, 4.5 mm steel BBs). Speed, m/s:
# skin perforation by a 0.177 in lead pellet ~101 m/s (DiMaio et al. 1982, J Forensic Sci 27(4):894).
HAZARD_ENERGY_DENSITY = (("corneal_abrasion", 1503.0), ("globe_rupture", 23771.0), ("eye_penetration", 43000.0))
HAZARD_SPEED = (("skin_perforation", 101.0),)
MAX_THRESHOLDS = 31  # a pellet's thresholds exceeded are the bits of an int32

# A person (docs/hazard.md, section 9): a pellet whose centre is at most `body_height` above the
# map's surface is within body height. 1.8 m: above the mean stature of adult men in the 2012 US
# Army anthropometric survey (ANSUR II; Gordon et al. 2014, NATICK/TR-15/007: about 1.76 m, SD
# about 0.07 m) and of nearly all women (about 1.63 m). The area a person presents at a named place,
# 0.7 m^2 = 1.8 m x 0.39 m: the body's height times about its shoulder breadth, the rectangle around
# the frontal silhouette (the silhouette itself is smaller: the default overstates a hit, never less).
BODY_HEIGHT = 1.8  # m
PERSON_AREA = 0.7  # m^2
MAX_PLACES = 64  # named places of one scene (each pellet is tested against every one)


@dataclass(frozen=True)
class Place:
    """A named place (`[[hazard.points]]`): a person standing at `position` (m; its (u, v) on the map),
    presenting `area` (m^2): a vertical cylinder of the scene's body height and radius
    area / (2 body_height) (`Hazard.radii`)."""

    name: str
    position: Vec3
    area: float = PERSON_AREA


@dataclass(frozen=True)
class Reference:
    """A distance the report compares the danger distances with (`[[hazard.references]]`): a
    regulator's fixed distance, a rule of thumb (docs/hazard.md, "The report")."""

    name: str
    distance: float  # m, from the shooter
    source: str = ""


@dataclass(frozen=True)
class Site:
    """[hazard.site]: where the map lies on a site plan (docs/hazard.md, "Outlines and GIS files")."""

    crs: str  # a CRS pyproj knows by an authority code, e.g. "EPSG:32630"
    shooter: tuple[float, float]  # the shooter's position in `crs`: [easting, northing] or [lon, lat]
    azimuth: float = 0.0  # deg clockwise from north (grid north of a projected CRS, true north of a geographic one)


@dataclass(frozen=True)
class Bound:
    """[hazard.bound]: run until the 95% interval of the danger distance of `threshold` at `fraction`
    is finite and narrower than `width` (m), adding shots, at most `max_pellets` pellets (docs/hazard.md)."""

    threshold: str
    fraction: float
    width: float  # m
    max_pellets: int


@dataclass(frozen=True)
class Hazard:
    """Hazard thresholds, danger-distance fractions and the ground map (docs/hazard.md). Absent:
    no thresholds, no map (quantiles are still counted)."""

    energy_density: tuple[tuple[str, float], ...] = HAZARD_ENERGY_DENSITY  # (name, J/m^2)
    speed: tuple[tuple[str, float], ...] = HAZARD_SPEED  # (name, m/s)
    fractions: tuple[float, ...] = (1e-3, 1e-6)  # p of the danger distances
    shooter: Vec3 | None = None  # m; None: shot.envelope_center (the origin for a pellet file)
    map_cell: float | None = None  # m, square cells; the map needs it and map_extent
    map_extent: tuple[float, float, float, float] | None = None  # m: u_min, u_max, v_min, v_max
    map_surface: int = 0  # the surface the map lies on
    map_axis: Vec3 | None = None  # the grid's u axis (projected on the plane); None: shot.direction
    body_height: float = BODY_HEIGHT  # m, of a pellet's centre above the map's surface (along -g)
    points: tuple[Place, ...] = ()  # named places (they need the map)

    @property
    def radii(self) -> tuple[float, ...]:
        """The radius (m) of each named place's cylinder: area / (2 body_height), its side's area seen
        from any horizontal direction being the place's area."""
        return tuple(p.area / (2.0 * self.body_height) for p in self.points)

    references: tuple[Reference, ...] = ()  # distances the report compares with
    site: Site | None = None  # georeference of the map (needs pyproj: the gis extra)
    bound: Bound | None = None  # run until the danger distance is bounded (`warp_ricochet.bound`)

    @property
    def thresholds(self) -> tuple[tuple[str, str, float], ...]:
        """(name, kind "energy_density" or "speed", value) of every threshold, in the order of their bits."""
        return tuple((n, "energy_density", v) for n, v in self.energy_density) + tuple((n, "speed", v) for n, v in self.speed)

    @property
    def has_map(self) -> bool:
        return self.map_cell is not None and self.map_extent is not None


@dataclass(frozen=True)
class Scene:
    shot: Shot
    surfaces: tuple[Surface, ...]
    physics: Physics
    numerics: Numerics
    output: Output
    source: str = dataclasses.field(default="", compare=False)
    collisions: Collisions = Collisions()
    air: Air | None = None
    hazard: Hazard | None = None
    stations: tuple = ()  # scene.stations.Station: [[stations]] (empty: one shooter, shot.direction)
    bound_first: int = dataclasses.field(default=0, compare=False)  # `bound.planned`: the scene's shot.shots

    @property
    def in_air(self) -> bool:
        """Pellets fly through air (an [air] table with a density above 0)."""
        return self.air is not None and not self.air.still

    @property
    def terrain_ground(self) -> bool:
        """The hazard's ground (`hazard.map_surface`) is a terrain: the hazard is watched above its
        triangles (`tallies.terrain_ground`)."""
        return self.hazard is not None and self.surfaces[self.hazard.map_surface].kind == "terrain"

    @property
    def pair_collisions(self) -> bool:
        """Pellets of a shot can meet each other: collisions enabled and more than one pellet per
        shot (the run goes through the dense phase, `pipeline.CollisionStage`)."""
        return self.collisions.enabled and self.shot.count > 1

    def to_dict(self) -> dict:
        """Plain TOML-able dict (None omitted, tuples as lists); scene_from_dict(s.to_dict()) == s."""
        shot = plain(self.shot)
        if self.shot.load is not None:  # an inline table {size = ..., material = ..., charge = kg}
            shot["load"] = dict(self.shot.load)
        if self.shot.file is not None:
            for key in FILE_EXCLUSIVE:
                shot.pop(key, None)
        if self.shot.choke is not None:  # (its pattern follows from it)
            del shot["pattern"]
        out = {
            "shot": shot,
            "surfaces": [plain(s) for s in self.surfaces],
            "physics": plain(self.physics),
            "numerics": plain(self.numerics),
            "output": plain(self.output),
        }
        if self.collisions.enabled:
            out["collisions"] = plain(self.collisions)
        if self.air is not None:
            out["air"] = plain(self.air)
        if self.hazard is not None:
            out["hazard"] = plain(self.hazard)
            for key in ("energy_density", "speed"):  # inline tables {name = value}
                out["hazard"][key] = dict(getattr(self.hazard, key))
            if not self.hazard.points:  # (an array of tables [[hazard.points]] when given)
                del out["hazard"]["points"]
            if not self.hazard.references:
                del out["hazard"]["references"]
        if self.stations:  # (each shot starts at its station: no envelope_center)
            shot.pop("envelope_center", None)
            out["stations"] = [plain(s) for s in self.stations]
        return out

    def to_toml(self) -> str:
        return "\n".join(toml_lines(self.to_dict(), "")).lstrip("\n") + "\n"

    def replace(self, **changes) -> Scene:
        return dataclasses.replace(self, **changes)
