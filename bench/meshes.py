"""Benchmarks of triangle meshes (docs/geometry.md, "Meshes and boxes"), figures, not tests:

  box    pellets fired at a closed box from all sides, half exactly at its edges and vertices
         (issue 27, part 4: 1e7 of them), in chunks: how many meet it, how many centres are inside
         it at an impact or a landing (must be 0), and pellets/s of the runs
  plane  the paper's shot (statistics only) on its plane and on a two-triangle mesh of that
         plane (2e4 m square), in vacuum (default) and/or in sea-level air: pellets/s of each and
         their ratio (issue 27, part 5: at most 3x)
  terrain  the paper's shot (statistics only) over a synthetic terrain of 1,002,528 triangles
         (`terrain_raster`: 708 x 708 cells of 0.5 m, 0.5 m waves, a GeoTIFF in a temporary
         folder) beside its flat plane, in vacuum and in air (issue 27, part 5: at least 2e8
         pellets/s in vacuum and 1e8 in air on an H200)
  posts  the hazard example's field shot (examples/hazard.toml: #6 lead, sea-level air, turf,
         statistics only, float32) followed to rest, beside the same shot with a fence post in
         its way (a post of 0.1 m radius, 1.2 m high, 20 m down range on the line of fire) and with
         pellet-pellet collisions off: seconds and pellets/s of each, the post's cost
  rest   the trap field on the shipped terrain (examples/trap_field_study.py's scene: #7.5 lead at
         400 m/s in sea-level air, a station 10 m from the raster's west edge) followed to rest
         (`until = "rest"`, docs/geometry.md "Rest on triangles") beside the same shot on a level
         plane of turf: seconds, pellets/s, where the pellets end and their mean steps

    python -m bench.meshes box [--n 1e7] [--chunk 1e6] [--jitter 1e-5] [--precision float32] [--device cpu]
    python -m bench.meshes plane [--n 1e6] [--precision float32] [--device cpu] [--repeats 3] [--flights vacuum,air]
    python -m bench.meshes terrain [--n 1e6] [--precision float32] [--device cpu] [--repeats 3] [--cells 708]
                                   [--flights vacuum,air]
    python -m bench.meshes rest [--n 1200] [--device cpu] [--repeats 3]
    python -m bench.meshes posts [--n 1e6] [--device cpu] [--repeats 3]

`box_shots` is also the tests' (tests/test_meshes.py). Figures: bench/RESULTS.md.
"""

import argparse
import math
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
GRAVITY = np.array([0.0, 0.0, -9.81])
AHEAD = 0.05  # s: the pellets reach their targets this long after launch
BOX = {"point": [0.3, -0.2, 1.5], "normal": [0.2, 0.1, 1.0], "axis_u": [1.0, 0.5, -0.25], "size": [1.2, 0.8, 0.5]}
MATERIAL = {"restitution": 0.5, "mu_s": 0.3}


def aimed(targets, v, time=AHEAD):
    """Launch positions whose centres, with launch velocities v, pass the points `targets` after
    `time` (s) in vacuum (eq. 36 backwards)."""
    return targets - v * time - 0.5 * GRAVITY * time**2


def box_axes(box):
    """The box's unit axes (rows u, v, n) and half sides (m), as `scene.triangles.box_triangles`."""
    from warp_ricochet.scene.triangles import box_triangles

    tri = box_triangles(box["point"], box["normal"], box["axis_u"], box["size"])
    axes = np.stack([tri.vertices[4] - tri.vertices[0], tri.vertices[2] - tri.vertices[0], tri.vertices[1] - tri.vertices[0]])
    return axes / np.linalg.norm(axes, axis=1, keepdims=True), 0.5 * np.asarray(box["size"], dtype=np.float64)


def box_shots(rng, count, box=BOX):
    """(x0, v0) of pellets whose centres, unhindered, reach points of a closed box AHEAD s later:
    half random points inside it from random directions all around, half exactly its edges,
    vertices and face points with velocities there in their inward cones."""
    axes, half = box_axes(box)
    n = count // 2
    inner = rng.uniform(-1, 1, (n, 3)) * half
    way = rng.normal(size=(n, 3))
    signs = rng.choice([-1.0, 0.0, 1.0], size=(count - n, 3))  # 0: anywhere along that axis
    signs[(signs == 0).all(axis=1), 0] = 1.0
    on = np.where(signs == 0, rng.uniform(-1, 1, signs.shape), signs) * half
    cone = np.abs(rng.normal(size=signs.shape)) * signs + np.where(signs == 0, 0.3 * rng.normal(size=signs.shape), 0.0)
    outward = np.r_[-way, cone]
    speed = rng.uniform(30.0, 300.0, (count, 1))
    v = (
        -speed * (outward / np.linalg.norm(outward, axis=1, keepdims=True)) @ axes - GRAVITY * AHEAD
    )  # v0: in the cone at the target
    return aimed(np.asarray(box["point"]) + np.r_[inner, on] @ axes, v), v


def inside_box(points, box, slack):
    """Whether centres lie inside the box by more than `slack` (m)."""
    axes, half = box_axes(box)
    return (np.abs((points - np.asarray(box["point"])) @ axes.T) < half - slack).all(axis=1)


def _box_run(folder, x, v, precision, device, name):
    """(first surface, first impact centre, landing centre, seconds) of one run at the box."""
    import h5py

    from warp_ricochet.api import run
    from warp_ricochet.scene import scene_from_dict

    np.savez(folder / f"{name}.npz", position=x, velocity=v)
    raw = {
        "shot": {"file": str(folder / f"{name}.npz"), "diameter": 0.0025, "density": 7000.0},
        "surfaces": [{"kind": "box", **BOX, **MATERIAL}],
        "physics": {"gravity": list(GRAVITY), "until": "landing", "bounces": 1},
        "numerics": {"precision": precision},
        "output": {"fields": ["impact.surface", "impact.position", "landing.position"]},
    }
    start = time.perf_counter()
    run(scene_from_dict(raw), folder / f"{name}.h5", device=device, overwrite=True)
    seconds = time.perf_counter() - start
    with h5py.File(folder / f"{name}.h5") as f:
        surface = f["pellets/impact/surface"][()].reshape(len(x), -1)[:, 0]
        return surface, f["pellets/impact/position"][()].reshape(len(x), -1, 3)[:, 0], f["pellets/landing/position"][()], seconds


def box(n, chunk, precision, device, seed=27, jitter=0.0):
    """`n` pellets at the box in chunks of `chunk` (`box_shots`); `jitter`: each launch position
    moved by up to that fraction of its coordinates, so pellets aimed at an edge or a vertex pass
    within a fraction of a millimetre of it, inside or outside (a sphere of radius R = 1.25 mm
    that passes outside within R touches it)."""
    rng = np.random.default_rng(seed)
    slack = 1e-9 if precision == "float64" else 1e-5
    met = inside = landed = 0
    seconds = 0.0
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        _box_run(folder, *box_shots(rng, 1000), precision, device, "warm")  # compiles
        done = 0
        while done < n:
            x, v = box_shots(rng, min(chunk, n - done))
            x = x + rng.uniform(-1.0, 1.0, x.shape) * jitter * np.abs(x)
            surface, first, landing, took = _box_run(folder, x, v, precision, device, "chunk")
            ok = ~np.isnan(landing).any(axis=1)
            met += int((surface == 0).sum())
            inside += int(inside_box(first, BOX, slack).sum() + inside_box(landing[ok], BOX, slack).sum())
            landed += int(ok.sum())
            seconds += took
            done += len(x)
    print(
        f"box, {precision}, {device}, jitter {jitter:g}: {n:,} pellets, {met:,} meet it, {landed:,} land again, {inside} centres inside"
    )
    print(
        f"  runs (with per-pellet output) {seconds:.1f} s: {n / seconds:.3g} pellets/s  [{platform.processor() or platform.machine()}]"
    )


def plane_mesh(folder) -> list:
    """The settings that make the paper's plane (y = 0, up +y) surface 0 as a two-triangle mesh of
    a 2e4 m square, its STL written in `folder`."""
    import trimesh

    square = np.array([[-1, 0, 1], [1, 0, 1], [1, 0, -1], [-1, 0, -1]], dtype=np.float64) * 1.0e4
    trimesh.Trimesh(vertices=square, faces=[[0, 1, 2], [0, 2, 3]], process=False).export(Path(folder) / "plane.stl")
    return ['surfaces.0.kind="mesh"', f'surfaces.0.file="{Path(folder) / "plane.stl"}"']


def plane(n, precision, device, repeats, flights=("vacuum",)):
    """The paper's shot (statistics only) on its plane and on `plane_mesh`, in vacuum and/or in
    sea-level air: pellets/s of each (median wall time of `repeats` runs after a warm-up) and the
    mesh's time over the plane's."""
    import warp_ricochet as wr
    from warp_ricochet.scene import load_scene

    sets = [f"shot.count={n}", f"numerics.precision={precision}", "output.fields=[]"]
    with tempfile.TemporaryDirectory() as folder:
        mesh = plane_mesh(folder)
        for flight in flights:
            times = {}
            air = ['air.drag="loth2021"'] if flight == "air" else []  # (an [air] table of defaults: sea-level air)
            for label, extra in (("plane", []), ("mesh", mesh)):
                scene = load_scene(ROOT / "examples" / "paper.toml", sets + air + extra)
                wr.run(scene, None, device=device)  # warm-up: compiles
                runs = []
                for _ in range(repeats):
                    start = time.perf_counter()
                    wr.run(scene, None, device=device)
                    runs.append(time.perf_counter() - start)
                times[label] = float(np.median(runs))
                where = f"{flight}, " if flights != ("vacuum",) else ""
                print(f"{where}{label}: {n / times[label]:.3g} pellets/s ({times[label] * 1e3:.1f} ms, median of {repeats})")
            where = f"{flight}: " if flights != ("vacuum",) else ""
            print(f"{where}mesh / plane time: {times['mesh'] / times['plane']:.2f}x  [{precision}, {device}]")


CELL = 0.5  # m: the synthetic terrain's pixel


def terrain_raster(folder, cells=708):
    """A GeoTIFF of (cells + 1)^2 samples (2 cells^2 triangles) at CELL m, written in `folder`:
    gentle relief about 0 (0.5 m waves of 240 m east and 180 m north: slopes below 0.022, a few
    times the paper's ricochet angle of 0.014 rad); its corner at (0, 0) of its CRS, north up.
    Returns its path."""
    import rasterio
    from rasterio.transform import Affine

    east = CELL * (np.arange(cells + 1) + 0.5)
    north = -CELL * (np.arange(cells + 1) + 0.5)[:, None]
    z = 0.5 * np.sin(2 * np.pi * east / 240.0) * np.cos(2 * np.pi * north / 180.0)
    path = Path(folder) / "terrain.tif"
    profile = {"driver": "GTiff", "width": cells + 1, "height": cells + 1, "count": 1, "dtype": "float32"}
    with rasterio.open(path, "w", **profile, transform=Affine(CELL, 0.0, 0.0, 0.0, -CELL, 0.0)) as out:
        out.write(z.astype(np.float32), 1)
    return path


def terrain_surfaces(raster, cells=708):
    """`terrain`'s surfaces: `terrain_raster`'s raster (its launch point 20 m from the raster's west
    edge, half way along it) and a plane 5 m below that catches what leaves it."""
    half = 0.5 * CELL * (cells + 1)
    ground = {"kind": "terrain", "file": str(raster), "origin": [20.0, -half], "restitution": 0.01, "mu_s": 0.5, "mu_d": 0.45}
    catch = {"point": [0.0, -5.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.01, "mu_s": 0.5, "mu_d": 0.45}
    return [ground, catch]


def _paper(n, precision, air, surfaces=None):
    """The paper's scene (examples/paper.toml), statistics only, `n` pellets, in vacuum or in sea-level air."""
    import tomllib

    from warp_ricochet.scene import scene_from_dict

    raw = tomllib.loads((ROOT / "examples" / "paper.toml").read_text())
    raw["shot"]["count"] = n
    raw["numerics"]["precision"] = precision
    raw["output"] = {"fields": []}
    if surfaces is not None:
        raw["surfaces"] = surfaces
    if air:
        raw["air"] = {}
    return scene_from_dict(raw)


def terrain(n, precision, device, repeats, cells=708, flights=("vacuum", "air")):
    """The paper's shot over `terrain_raster` (its launch point 20 m from the raster's west edge,
    half way along it; a plane 5 m below catches what leaves it) and on its plane: pellets/s."""

    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        raster = terrain_raster(folder, cells)
        made = time.perf_counter() - start
        print(f"terrain: {2 * cells * cells:,} triangles, raster written in {made:.2f} s  [{precision}, {device}]")
        for air in (flight == "air" for flight in flights):
            times = {}
            for label, surfaces in (("plane", None), ("terrain", terrain_surfaces(raster, cells))):
                setup, _ = _timed(_paper(1, precision, air, surfaces), device, repeats)  # (also compiles)
                total, stats = _timed(_paper(n, precision, air, surfaces), device, repeats)
                times[label] = total - setup
                rate = (
                    f"{n / times[label]:.3g} pellets/s without the set-up"
                    if total > 1.5 * setup
                    else "(the run is within 1.5x its set-up: no rate)"
                )
                print(
                    f"  {'air' if air else 'vacuum'}, {label}: {rate}, {n / total:.3g} with it"
                    f" ({total * 1e3:.1f} ms a run of {n:,}, set-up (a run of 1) {setup * 1e3:.1f} ms; medians of {repeats});"
                    f" {stats['hits'] / n:.3f} hit, {stats['landed'] / n:.3f} land, mean range {stats['range_mean']:.1f} m"
                )
            if min(times.values()) > 0:
                print(f"  {'air' if air else 'vacuum'}: terrain / plane time {times['terrain'] / times['plane']:.2f}x")


def rest(n, device, repeats):
    """The trap-field study's shot (`n` pellets, 5-15 deg, float64) to rest on its terrain and on a
    level plane of turf: wall time (median of `repeats` after a warm-up), where they end, steps."""
    import sys

    sys.path.insert(0, str(ROOT / "examples"))
    from trap_field_study import scene as trap_scene

    from warp_ricochet.scene import scene_from_dict

    base = trap_scene(max(1, n // 300), (5.0, 15.0)).to_dict()
    base["physics"] = {**base["physics"], "until": "rest"}
    base["output"] = {"fields": ["rest"]}
    level = {"name": "level turf", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "turf"}
    for label, surfaces in (("terrain", base["surfaces"]), ("plane", [level])):
        scene = scene_from_dict({**base, "surfaces": surfaces})
        with tempfile.TemporaryDirectory() as folder:
            out = Path(folder) / "rest.h5"
            seconds, stats = _timed(scene, device, repeats, out)
            import h5py

            with h5py.File(out) as f:
                state, where = f["pellets/rest/state"][()], f["pellets/rest/position"][()]
        count = len(state)
        ends = ", ".join(
            f"{name} {np.mean(state == code):.3f}" for code, name in enumerate(("at rest", "embedded", "escaped", "not finished"))
        )
        reach = where[state <= 1, 0]
        print(
            f"{label}: {count} pellets in {seconds:.2f} s ({count / seconds:.3g} pellets/s; median of {repeats}); {ends};"
            f" rest x mean {reach.mean():.1f} m, 99% {np.quantile(reach, 0.99):.1f} m, max {reach.max():.1f} m;"
            f" {stats.get('rest_steps_mean', float('nan')):.1f} steps/pellet  [{device}]"
        )


POST = {"name": "post", "kind": "cylinder", "point": [20.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0]}
POST |= {"radius": 0.1, "length": 1.2, "material": "concrete"}  # a fence post 20 m out on the line of fire


def hazard_shot(n, post: bool):
    """The hazard example's shot (`n` pellets rounded to whole shots) to rest on turf, statistics only,
    without its hazard, with or without POST in its way: the scene's dict."""
    import tomllib

    raw = tomllib.loads((ROOT / "examples" / "hazard.toml").read_text())
    raw["shot"]["shots"] = max(1, n // raw["shot"]["count"])
    raw["physics"] = {**raw["physics"], "until": "rest"}
    raw["output"] = {"fields": []}
    raw.pop("hazard")
    if post:
        raw["surfaces"] = raw["surfaces"] + [POST]
    return raw


def posts(n, device, repeats):
    """The hazard example's shot, statistics only, to rest on turf without and with a fence post
    in its way: the median wall time of `repeats` runs after a warm-up, pellets/s and the ratio."""
    from warp_ricochet.scene import scene_from_dict

    raw = hazard_shot(n, False)
    count = raw["shot"]["shots"] * raw["shot"]["count"]
    times = {}
    for label, post in (("turf", False), ("turf and a post", True)):
        seconds, stats = _timed(scene_from_dict(hazard_shot(n, post)), device, repeats)
        times[label] = seconds
        print(
            f"{label}: {count:,} pellets to rest in {seconds * 1e3:.1f} ms ({count / seconds:.3g} pellets/s; median of"
            f" {repeats}), {stats.get('rest_steps_mean', float('nan')):.1f} steps/pellet, rest distance mean"
            f" {stats.get('rest_distance_mean', float('nan')):.2f} m  [{device}]"
        )
    print(f"  post / turf time {times['turf and a post'] / times['turf']:.2f}x")


def _timed(scene, device, repeats, out=None):
    """(The median wall time (s) of `repeats` runs of `scene` after one warm-up, its statistics)."""
    import warp_ricochet as wr

    wr.run(scene, out, device=device, overwrite=True)
    runs = []
    for _ in range(repeats):
        start = time.perf_counter()
        stats = wr.run(scene, out, device=device, overwrite=True)
        runs.append(time.perf_counter() - start)
    return float(np.median(runs)), stats


def _fraction(text: str) -> float:
    """--jitter: a fraction in [0, 1) (1 or more could move a launch position through the origin)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"{text!r}: must be a fraction in [0, 1)")
    return value


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.meshes", description=__doc__.split("\n\n")[0])
    parser.add_argument("what", choices=("box", "plane", "terrain", "rest", "posts"))
    parser.add_argument("--n", type=float, default=1e6)
    parser.add_argument("--chunk", type=float, default=1e6)
    parser.add_argument("--precision", default="float32", choices=("float32", "float64"))
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--jitter", type=_fraction, default=0.0, help="box: launch positions moved by up to this fraction")
    parser.add_argument("--cells", type=int, default=708, help="terrain: cells per side (2 cells^2 triangles)")
    parser.add_argument("--flights", help="terrain, plane: vacuum, air or both (comma-separated; terrain: both, plane: vacuum)")
    args = parser.parse_args(argv)
    if args.flights is not None and not set(args.flights.split(",")) <= {"vacuum", "air"}:
        parser.error(f"--flights = {args.flights!r}: vacuum, air or both, comma-separated")
    if args.what == "box":
        box(int(args.n), int(args.chunk), args.precision, args.device, jitter=args.jitter)
    elif args.what == "rest":
        rest(int(args.n), args.device, args.repeats)
    elif args.what == "posts":
        posts(int(args.n), args.device, args.repeats)
    elif args.what == "terrain":
        terrain(int(args.n), args.precision, args.device, args.repeats, args.cells, (args.flights or "vacuum,air").split(","))
    else:
        plane(int(args.n), args.precision, args.device, args.repeats, tuple((args.flights or "vacuum").split(",")))


if __name__ == "__main__":
    main()
