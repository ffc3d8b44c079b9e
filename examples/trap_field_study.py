"""How much of a trap shot the berm of the trap-field raster contains (issue 27, docs/geometry.md
"Terrain"): the shipped synthetic raster (warp_ricochet/examples/terrain/trap_field.asc, made by
make_trap_field.py: ground falling 2% down range, a 4 m berm 152.5 m from its west edge), a station
10 m from that edge on its centre line, #7.5 lead shot (2.4 mm) at 400 m/s in sea-level air, aimed
at the elevations trap targets fly at; each pellet's first impact: short of the berm's crest, on the
berm's back slope, or beyond (on the falling ground, or past the raster's end: a plane 20 m below
the raster catches those). To the first impact; followed to rest (`physics.until = "rest"`), the
berm holds far less of the low shot (docs/geometry.md, "Example: does the trap field's berm ...").

    python examples/trap_field_study.py [--shots 20] [--device cpu] [--elevation 5 15]

With --hazard, each pellet is followed to rest and the hazard along its path is watched above the
terrain (docs/hazard.md section 11): the danger distances of the eye's and the skin's thresholds,
beside the same shot over a level plane of turf at the station's ground.
"""

import argparse
from importlib.resources import files

import numpy as np

import warp_ricochet as wr
from warp_ricochet.scene import scene_from_dict

RASTER = str(files("warp_ricochet") / "examples" / "terrain" / "trap_field.asc")
STATION = (500_010.0, 4_200_050.0, 119.8)  # the raster's (east, north) of the station and its ground (m)
CREST, BACK_FOOT = 142.5, 152.5  # m down range from the station: the berm's crest and its back slope's foot


HAZARD = {  # docs/hazard.md section 3: the eye's lowest threshold and the skin's
    "energy_density": {"corneal_abrasion": 1503.0},
    "speed": {"skin_perforation": 101.0},
    "fractions": [1e-2, 1e-3],
    "shooter": [0.0, 0.0, 0.0],  # the station's foot
    "map_cell": 5.0,
    "map_extent": [-10.0, 300.0, -60.0, 60.0],
}


def scene(shots: int, elevation: tuple[float, float], seed: int = 1, hazard: bool = False, level: bool = False):
    """The study's scene; `hazard`: to rest, watched along the path (HAZARD); `level`: over a level
    plane of turf at the station's ground instead of the raster."""
    low, high = np.radians(elevation)
    mid, half = 0.5 * (low + high), 0.5 * (high - low)
    raw = {
        "shot": {
            "count": 300,
            "shots": shots,
            "diameter": 0.0024,
            "density": 11_340.0,
            "speed": 400.0,
            "direction": [float(np.cos(mid)), float(np.sin(mid)), 0.0],
            "direction_jitter": [0.0, float(np.tan(half)), 0.3],  # elevation spread, +-17 deg across
            "envelope_radius": 0.02,
            "envelope_center": [0.0, 1.5, 0.0],
            "seed": seed,
        },
        "surfaces": [
            {
                "name": "trap field",
                "kind": "terrain",
                "file": RASTER,
                "origin": list(STATION[:2]),
                "elevation": STATION[2],
                "material": "turf",
            },
            {"name": "beyond the raster", "point": [0.0, -20.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "turf"},
        ],
        "physics": {"until": "landing", "bounces": 1},
        "air": {},
        "numerics": {"precision": "float64"},
        "output": {"fields": ["impact"]},
    }
    if hazard:
        raw.update(hazard=HAZARD, physics={"until": "rest", "bounces": 3}, output={"fields": ["hazard", "rest"]})
    if level:
        raw["surfaces"] = [{"name": "level turf", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "turf"}]
    return scene_from_dict(raw)


def hazard_study(args) -> None:
    """The danger distances (reach along the path, and of the landings) on the raster and on a level plane."""
    import h5py

    for level in (False, True):
        out = f"{args.out[:-3]}_{'level' if level else 'terrain'}.h5"
        wr.run(scene(args.shots, tuple(args.elevation), hazard=True, level=level), out, device=args.device, overwrite=True)
        with h5py.File(out) as f:
            names = [n.decode() for n in f["hazard/thresholds/name"][()]]
            fractions = f["hazard/danger_distance/fraction"][()]
            print(f"{'level plane' if level else 'the raster'}: {f['pellets/hazard/reach'].shape[0]} pellets to rest")
            for i, name in enumerate(names):
                for j, p in enumerate(fractions):
                    d = f["hazard/danger_distance"]
                    o = f["hazard/landing_danger_distance"]
                    print(
                        f"  {name:18s} p = {p:g}: along the path {d['distance'][i, j]:7.1f} m "
                        f"[{d['ci_low'][i, j]:.1f}, {d['ci_high'][i, j]:.1f}], landings {o['distance'][i, j]:7.1f} m"
                    )
            reach, below = f["pellets/hazard/reach"][:, 0], f["pellets/rest/position"][:, 1] < -10.0
            if below.any():  # resting on the plane 20 m below: off the raster, below its base plane (within body height)
                print(
                    f"  {below.mean():.1%} rest off the raster, on the plane 20 m below; 99th percentile of the "
                    f"{names[0]} reach: {np.nanquantile(reach[~below], 0.99):.1f} m of those on the raster, "
                    f"{np.nanquantile(reach[below], 0.99):.1f} m of those off it"
                )


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--shots", type=int, default=20)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--elevation", type=float, nargs=2, default=(5.0, 15.0), metavar=("LOW", "HIGH"))
    parser.add_argument("--out", default="trap_field.h5")
    parser.add_argument("--hazard", action="store_true", help="to rest, the danger distances along the path (docs/hazard.md 11)")
    args = parser.parse_args(argv)
    if args.hazard:
        hazard_study(args)
        return
    import h5py

    sc = scene(args.shots, tuple(args.elevation))
    wr.run(sc, args.out, device=args.device, overwrite=True)
    with h5py.File(args.out) as f:
        surface = f["pellets/impact/surface"][:, 0]
        x = f["pellets/impact/position"][:, 0, 0]
    n = len(surface)
    on = surface == 0
    groups = {
        "short of the berm's crest": on & (x < CREST),
        "on the berm's back slope": on & (x >= CREST) & (x < BACK_FOOT),
        "beyond the berm, on the raster": on & (x >= BACK_FOOT),
        "past the raster's end": surface == 1,
        "no impact": surface < 0,
    }
    print(f"{n} pellets, elevations {args.elevation[0]:g}-{args.elevation[1]:g} deg, first impacts:")
    for label, mask in groups.items():
        k = int(mask.sum())
        p = k / n
        half = 1.96 * np.sqrt(p * (1 - p) / n)  # (pellets of a shot are not independent: a guide only)
        print(f"  {label:32s} {k:6d}  {100 * p:5.1f}% +- {100 * half:.1f}")


if __name__ == "__main__":
    main()
