"""What a run compiles: one frozen spec, the cache key of every kernel factory.

The kernels are specialised at code generation (`wp.static`) for what the scene needs: no output
code in a statistics-only run, loops over bounces and (up to MAX_STATIC_PLANES) planes unrolled,
launch states read from memory only for a pellet file, the dense phase only with pair collisions,
the flight model chosen. Two runs with equal specs share their kernels.
"""

from __future__ import annotations

from dataclasses import dataclass

from .fields import collision_fields, core_fields

MAX_STATIC_PLANES = 4  # scenes with more planes loop over them at run time
PRECISIONS = ("float32", "float64")


def _has_ground_laws(surface) -> bool:
    """Whether a scene surface draws rough ground or has a penetration or skip law (physics.ground)."""
    from .scene.materials import RIGID, is_liquid

    keys = ("critical_angle", "roughness", "restitution_scatter", "friction_scatter")
    return is_liquid(surface.material) or any(surface.ground(key) != RIGID[key] for key in keys)


def _thread_pieces(scene) -> bool:
    """Whether the core's threads hold consecutive slots of one shot (`RunSpec.thread_pieces`): pair
    collisions followed to rest, shots of at least a thread's slots (the shot-padded layout's stride
    is a power of two, a piece's pellets a multiple of a thread's)."""
    from .dense.schedule import shot_stride
    from .tallies.reduce import REST_PER_THREAD

    return scene.pair_collisions and scene.physics.until == "rest" and shot_stride(scene.shot.count) >= REST_PER_THREAD


def _log_steps() -> int:
    """Steps of a phase along a line a core thread logs for the watch (`physics.line_log.LOG_STEPS`,
    read at each call: the results are the same bits for any)."""
    from .physics import line_log

    return line_log.LOG_STEPS


MESHES = 2  # RunSpec.plates when the scene has triangles: the geometry's plate and mesh code


def _plates(scene) -> bool | int:
    """`RunSpec.plates`: False (planes only), True (plates) or MESHES or'ed with what the scene's
    solids do not need compiled in (`physics.geometry`: NO_POSTS, SMALL, NO_EDGES), FLAT where every
    solid is a small flat mesh (`physics.mesh_edges.flat_mesh`) and LEANING where a post run to rest
    leans from gravity (the kernels' test, `side_follow.leans`, in float64 here)."""
    import numpy as np

    from .physics.geometry import FLAT, LEANING, NO_EDGES, NO_POSTS, SMALL
    from .physics.mesh_contact import FEW_FACES
    from .physics.mesh_edges import flat_mesh
    from .physics.side_follow import LEAN
    from .scene.triangles import triangles_of

    solids = [s for s in scene.surfaces if s.is_solid]
    if not solids:
        return any(not s.is_plane for s in scene.surfaces)
    meshes = [s for s in solids if s.kind in ("box", "mesh")]  # (a terrain is large, without edges)
    found = [triangles_of(s) for s in meshes]
    small = all(s.kind != "terrain" for s in solids) and all(len(f.triangles) <= FEW_FACES for f in found)
    flags = (0 if any(s.kind == "cylinder" for s in solids) else NO_POSTS) | (SMALL if small else 0)
    if small and len(meshes) == len(solids) and all(flat_mesh(f.vertices, f.triangles) for f in found):
        flags |= FLAT
    g = np.asarray(scene.physics.gravity, dtype=np.float64)
    leaning = scene.physics.until == "rest" and any(
        s.kind == "cylinder"
        and np.linalg.norm(np.cross(np.asarray(s.normal) / np.linalg.norm(s.normal), g)) > LEAN * np.linalg.norm(g)
        for s in solids
    )
    return MESHES | flags | (0 if meshes else NO_EDGES) | (LEANING if leaning else 0)


@dataclass(frozen=True)
class RunSpec:
    """precision: "float32" or "float64"; bounces: ricochets followed; planes: surfaces in the
    scene; fields: per-pellet outputs computed (empty: statistics only); from_file: launch states
    from a pellet file; fast_math: CUDA float32 approximate maths; collisions: a dense phase of
    pellet-pellet collisions first; flight: the flight model (`physics.flight.MODELS`); air_laws:
    in air, (drag, lift or None, spin decay or None) of `physics.air`; tally: landing histograms
    (quantiles, danger distances, `tallies.landing`); hazard_map: the hazard map too; thresholds:
    the number of hazard thresholds (compiled in: the landing code tests each one unrolled); until:
    "landing" ends a pellet at its landing, "rest" follows it on until it stops (docs/ground.md); ground:
    a surface has rough ground or a penetration law (`physics.ground`), applied at every impact;
    rough: a surface has rough ground (a roughness above 0: phases off one line are followed over
    the distance, `physics.surface_line`; else those few go in 3-D); places: the named places of the hazard (`tallies.path`); plates: a surface is a finite plate
    (`physics.geometry`: its code compiled in only then); MESHES (2): a surface is a box, a mesh or a post (or'ed with the solids' code left out: `_plates`)
    (`physics.mesh_contact` compiled in too); pattern: the pellets' directions drawn from a choke's
    pattern (`launch.pattern`), not from the jitter; stations: each shot's start and aim from its
    station (`launch.stations`); thread_pieces: each core thread follows consecutive slots of one
    piece of one shot, so the per-shot partials come from the core's threads (`core.shots`: pair
    collisions followed to rest); terrain_ground: the hazard's ground is a terrain (`tallies.terrain_walk`);
    log_steps: steps of a phase along a line a thread keeps before its watch takes them (`physics.line_log`);
    replay: a run to rest records its watch for a kernel of its own (`tallies.path_replay`: on GPUs);
    watch_only: the core kernel that follows again the pellets whose records did not fit (`core.replay`):
    only their watch counted and written, nothing else."""

    precision: str
    bounces: int
    planes: int
    fields: tuple[str, ...] = ()
    from_file: bool = False
    fast_math: bool = False
    collisions: bool = False
    flight: str = "ballistic"
    air_laws: tuple | None = None
    tally: bool = False
    hazard_map: bool = False
    thresholds: int = 0
    until: str = "landing"
    ground: bool = False
    rough: bool = False
    places: int = 0
    plates: bool | int = False
    pattern: bool = False
    stations: bool = False
    thread_pieces: bool = False
    terrain_ground: bool = False
    log_steps: int = 32
    replay: bool = False
    watch_only: bool = False

    @classmethod
    def of(cls, scene, *, with_output: bool = True, device=None) -> RunSpec:
        """The spec of running `scene` on `device` (None: not known, no replay), writing its output
        fields or (not with_output) statistics only."""
        from .tallies.path_replay import replays_on

        precision = scene.numerics.precision
        air = scene.air if scene.in_air else None
        laws = (
            None if air is None else (air.drag, air.lift if air.magnus else None, air.spin_decay_law if air.spin_decay else None)
        )
        return cls(
            precision=precision,
            bounces=scene.physics.bounces,
            planes=len(scene.surfaces),
            fields=tuple(scene.output.fields) if with_output else (),
            from_file=scene.shot.file is not None,
            fast_math=scene.numerics.fast_math and precision == "float32",
            collisions=scene.pair_collisions,
            flight="ballistic" if air is None else "air",
            air_laws=laws,
            tally=scene.output.quantiles,
            hazard_map=scene.output.quantiles and scene.hazard is not None and scene.hazard.has_map,
            thresholds=0 if scene.hazard is None else len(scene.hazard.thresholds),
            until=scene.physics.until,
            ground=any(_has_ground_laws(surface) for surface in scene.surfaces),
            rough=any(surface.ground("roughness") > 0.0 for surface in scene.surfaces),
            places=0 if scene.hazard is None else len(scene.hazard.points),
            plates=_plates(scene),
            pattern=scene.shot.pattern is not None,
            stations=bool(scene.stations),
            thread_pieces=_thread_pieces(scene),
            terrain_ground=scene.terrain_ground,
            log_steps=_log_steps(),
            replay=replays_on(device) and scene.physics.until == "rest",
        )

    @property
    def to_rest(self) -> bool:
        """Whether pellets are followed on from their landing until they stop."""
        return self.until == "rest"

    @property
    def lanes(self) -> int:
        """Threads a statistics segment (`tallies.reduce.lanes_for`): many threads of few pellets where
        pellets are costly (followed to rest; against a terrain or a large mesh, whose BVH searches take
        most of a run), so that a GPU has work for all its multiprocessors from fewer pellets."""
        from .physics.geometry import SMALL
        from .tallies.reduce import lanes_for

        large = bool(self.plates & MESHES) and not self.plates & SMALL
        return lanes_for(self.to_rest or large)

    @property
    def watch(self) -> tuple[int, int, bool, bool, bool]:
        """(thresholds, places, map, terrain, replay) of the hazard watched along the path
        (`tallies.path`; replay: recorded by the core, `tallies.path_replay`): a scene with thresholds
        and its tallies; (0, 0, False, False, False) compiles the watch away."""
        if not (self.tally and self.thresholds > 0):
            return (0, 0, False, False, False)
        return (self.thresholds, self.places, self.hazard_map, self.terrain_ground, self.replay)

    @property
    def in_air(self) -> bool:
        return self.flight == "air"

    @property
    def core_fields(self) -> tuple[str, ...]:
        """The fields the core kernel writes."""
        return core_fields(self.fields)

    @property
    def collision_fields(self) -> tuple[str, ...]:
        """The fields the dense phase writes."""
        return collision_fields(self.fields)

    @property
    def static_planes(self):
        """The number of planes when the loops over them are unrolled, else None."""
        return self.planes if self.planes <= MAX_STATIC_PLANES else None
