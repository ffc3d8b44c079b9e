"""Posts, plates and planes far from the origin in float32 (issue 27; docs/geometry.md, "Far from
the origin"), figures, not tests: pellets dropped onto a post's cap rim and beside its side, onto a
level rectangle's and disc's edges and corners, and onto a tilted infinite plane, the scene moved D m
from the origin (the level ground stays: a plane through the origin), followed to rest (vacuum or
sea-level air). Per case: the end states NOT_FINISHED and escaped, the rests with the centre inside
the post, the rests on a plate's level beyond its edge (by more than R/16), the farthest such, and
against the same scene at the origin (moved back) the share of rests within 1e-4 m and the KS p of
the rests' distances from the solid's axis.

    python -m bench.far_solids [--n 2000] [--shapes post,rectangle,disc,plane] [--distances 0,200,1000,2000,5000]
                               [--flights vacuum,air] [--precision float32] [--direction 0.6,0.8]

`drops`, `surfaces_for`, `rests`, `run_rests` and `measures` are also the tests' (tests/test_far_solids.py).
Figures: bench/RESULTS.md ("Posts, plates and planes far from the origin in float32").
"""

import argparse
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

R = 0.00125  # m: the pellets' radius
G = 9.81
POST_R, POST_L = 0.1, 1.0  # m: the post's radius and length (base at the origin, axis z)
PLATE_Z, HALF, DISC_R = 1.0, 0.5, 0.5  # m: the plates' height, the square's half side, the disc's radius
TILT = 0.06  # rad: the plane's slope about the y axis (it rests pellets: its rolling resistance is larger)
GROUND = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "restitution": 0.05, "mu_s": 0.5, "mu_d": 0.45}
GROUND |= {"rolling_resistance": 0.2}
SOLID = {"restitution": 0.3, "mu_s": 0.3, "mu_d": 0.27, "rolling_resistance": 0.05}
SHAPES = ("post", "rectangle", "disc", "plane")


def surfaces_for(shape: str, shift) -> list:
    """The scene's surfaces with the solid moved by `shift` (m); the ground stays (a plane through
    the origin, whose level coordinates a horizontal shift does not change). The plane case is a
    plane tilted by TILT through `shift` (no ground)."""
    shift = np.asarray(shift, dtype=np.float64)
    if shape == "plane":
        n = [np.sin(TILT), 0.0, np.cos(TILT)]
        return [{"point": list(shift), "normal": n, **SOLID, "rolling_resistance": 0.3}]
    if shape == "post":
        solid = {"kind": "cylinder", "point": list(shift), "normal": [0.0, 0.0, 1.0], "radius": POST_R, "length": POST_L}
    elif shape == "rectangle":
        solid = {"kind": "rectangle", "point": list(shift + [0, 0, PLATE_Z]), "normal": [0.0, 0.0, 1.0]}
        solid |= {"axis_u": [1.0, 0.0, 0.0], "size": [2 * HALF, 2 * HALF]}
    else:
        solid = {"kind": "disc", "point": list(shift + [0, 0, PLATE_Z]), "normal": [0.0, 0.0, 1.0], "radius": DISC_R}
    return [{**solid, **SOLID}, GROUND]


def drops(shape: str, n: int, seed: int = 27):
    """(x0, v0) about the origin: n pellets dropped 1 mm to 0.3 m onto the solid's rims within a
    few R of them (a post: its top rim, and a quarter beside its side, 0 to 2 R off it, from
    above the cap; a rectangle: its edges and, a quarter, corners; a disc: its rim), falling at
    up to 1 m/s and moving at about 0.1 m/s; the plane: anywhere over 1 m^2 of it."""
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0.0, 2.0 * np.pi, n)
    if shape == "post":
        rho = POST_R + np.where(np.arange(n) % 4 == 3, rng.uniform(0.0, 2.0 * R, n), rng.normal(0.0, 1.5 * R, n))
        x, y, top = rho * np.cos(angle), rho * np.sin(angle), POST_L
    elif shape == "disc":
        rho = DISC_R + rng.normal(0.0, 1.5 * R, n)
        x, y, top = rho * np.cos(angle), rho * np.sin(angle), PLATE_Z
    elif shape == "rectangle":
        along, side = rng.uniform(-HALF, HALF, n), rng.integers(0, 4, n)
        corner = np.arange(n) % 4 == 0
        x = np.where(corner, rng.choice([-HALF, HALF], n), np.where(side < 2, np.where(side == 0, -HALF, HALF), along))
        y = np.where(corner, rng.choice([-HALF, HALF], n), np.where(side < 2, along, np.where(side == 2, -HALF, HALF)))
        x, y, top = x + rng.normal(0.0, 1.5 * R, n), y + rng.normal(0.0, 1.5 * R, n), PLATE_Z
    else:
        x, y = rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n)
        top = -np.tan(TILT) * x + R / np.cos(TILT) - R
    x0 = np.c_[x, y, top + R + rng.uniform(0.001, 0.3, n)]
    v0 = np.c_[rng.normal(0.0, 0.1, n), rng.normal(0.0, 0.1, n), -rng.uniform(0.0, 1.0, n)]
    return x0, v0


def rests(shape, distance, direction, precision, air, n, folder=None):
    """{state, position (less the shift, float64), impacts, warnings} at rest of `drops` with the
    scene moved `distance` m along the unit (x, y) `direction`."""
    shift = distance * np.array([direction[0], direction[1], 0.0])
    x0, v0 = drops(shape, n)
    folder = Path(folder or tempfile.mkdtemp(prefix="far-solids-"))
    np.savez(folder / "pellets.npz", position=x0 + shift, velocity=v0)
    raw = {
        "shot": {"file": str(folder / "pellets.npz"), "diameter": 2 * R, "density": 11340.0},
        "surfaces": surfaces_for(shape, shift),
        "physics": {"gravity": [0.0, 0.0, -G], "until": "rest"},
        "numerics": {"precision": precision},
        "output": {"fields": ["rest"]},
    }
    if air:
        raw["air"] = {"density": 1.225}
    return run_rests(raw, folder, shift)


def run_rests(raw: dict, folder, shift) -> dict:
    """{state, position less `shift` (float64), impacts} at rest of the scene `raw` (its output's
    fields ["rest"]) run on the CPU into `folder`/far.h5, and the PrecisionWarnings it gave."""
    import h5py

    import warp_ricochet as wr
    from warp_ricochet.scene import scene_from_dict

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        wr.run(scene_from_dict(raw), Path(folder) / "far.h5", device="cpu", overwrite=True)
    with h5py.File(Path(folder) / "far.h5") as f:
        end = {key: f[f"pellets/rest/{key}"][()] for key in ("state", "position", "impacts")}
    end["position"] = end["position"].astype(np.float64) - shift
    end["warnings"] = [str(w.message) for w in caught if issubclass(w.category, wr.PrecisionWarning)]
    return end


def _axis(shape, where):
    """Each rest's distance (m) from the solid's vertical axis (the plane: its x)."""
    return where[:, 0] if shape == "plane" else np.hypot(where[:, 0], where[:, 1])


def measures(shape, end, tol=R / 16):
    """{not_finished, escaped, inside, past_edge, past_max}: the end states, the rests with the
    centre inside the post by more than `tol`, and the rests at a plate's (or the post's cap's)
    level (R above it within `tol`) whose centre lies beyond its edge by more than `tol`, and the
    farthest of those beyond it (m); the plane: rests below the plane by more than `tol`."""
    from warp_ricochet.ends import ESCAPED, NOT_FINISHED

    where, state = end["position"], end["state"]
    out = {"not_finished": int((state == NOT_FINISHED).sum()), "escaped": int((state == ESCAPED).sum())}
    rho = np.hypot(where[:, 0], where[:, 1])
    if shape == "plane":
        height = where[:, 0] * np.sin(TILT) + where[:, 2] * np.cos(TILT)
        out["inside"], beyond = int((height < R - tol).sum()), np.zeros(0)
    elif shape == "post":
        out["inside"] = int(((rho < POST_R - tol) & (where[:, 2] > tol) & (where[:, 2] < POST_L - tol)).sum())
        level = np.abs(where[:, 2] - POST_L - R) <= tol
        beyond = (rho - POST_R)[level]
    else:
        out["inside"] = 0
        level = np.abs(where[:, 2] - PLATE_Z - R) <= tol
        off = rho - DISC_R if shape == "disc" else np.max(np.abs(where[:, :2]), axis=1) - HALF
        beyond = off[level]
    out["past_edge"] = int((beyond > tol).sum())
    out["past_max"] = float(max(beyond.max(initial=0.0), 0.0))
    return out


def agreement(shape, one, other):
    """(share of rests within 1e-4 m of each other, KS p of their distances from the axis)."""
    from scipy import stats

    ok = np.isfinite(one["position"][:, 0]) & np.isfinite(other["position"][:, 0])
    near = np.linalg.norm(one["position"][ok] - other["position"][ok], axis=1) <= 1e-4
    p = stats.ks_2samp(_axis(shape, one["position"][ok]), _axis(shape, other["position"][ok]), method="asymp").pvalue
    return float(near.sum() / len(near)), float(p)


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.far_solids", description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=2000)
    parser.add_argument("--shapes", default=",".join(SHAPES))
    parser.add_argument("--distances", default="0,200,1000,2000,5000")
    parser.add_argument("--flights", default="vacuum,air")
    parser.add_argument("--precision", default="float32")
    parser.add_argument("--direction", default="0.6,0.8", help="the shift's unit direction in x, y")
    parser.add_argument("--reference", default=None, help="also compare with this precision at the same distance")
    args = parser.parse_args(argv)
    direction = np.array([float(c) for c in args.direction.split(",")])
    direction /= np.linalg.norm(direction)
    also = f" within 1e-4 m of {args.reference} | KS p |" if args.reference else ""
    print(
        f"| shape | flight | D m | NOT_FINISHED | escaped | inside | past edge (max mm) | within 1e-4 m of D=0 | KS p |{also} s |"
    )
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |" + " ---: | ---: |" * bool(args.reference) + " ---: |")
    for shape in args.shapes.split(","):
        for flight in args.flights.split(","):
            origin = None
            for d in (float(s) for s in args.distances.split(",")):
                start = time.perf_counter()
                end = rests(shape, d, direction, args.precision, flight == "air", args.n)
                seconds = time.perf_counter() - start
                origin = end if origin is None else origin
                m = measures(shape, end)
                share, p = agreement(shape, end, origin)
                if args.reference:
                    exact = rests(shape, d, direction, args.reference, flight == "air", args.n)
                    also = " {:.3f} | {:.3g} |".format(*agreement(shape, end, exact))
                warned = " (warned)" if end["warnings"] else ""
                print(
                    f"| {shape} | {flight} | {d:g}{warned} | {m['not_finished']} | {m['escaped']} | {m['inside']} | "
                    f"{m['past_edge']} ({1e3 * m['past_max']:.3f}) | {share:.3f} | {p:.3g} |{also} {seconds:.1f} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
