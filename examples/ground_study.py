"""Where pellets land and where they stop, by ground (docs/ground.md section 12): the paper's scene in
sea-level air, the field shot and the hazard scene, each followed to rest on every catalogue ground
(both ends of its bracket) and, for the paper's scene, on its own rigid plane.

    python examples/ground_study.py [--pellets 20000] [--shots 20] [--device cpu] [--out ground-study]

Every number comes from the run files (statistics only): landing and rest distances from the shooter
(quantiles of the on-device histograms, /stats/quantiles), the end states (/stats/rest_*), mean
impacts, and for the hazard scene the danger distances of its thresholds at p = 1e-3: of the
landings (/hazard/landing_danger_distance) and along the path at body height (/hazard/danger_distance,
docs/hazard.md section 11). A ground replaces the scene's surface 0 whole
(restitution and friction included). Writes table.md under --out and prints it.
"""

import argparse
import sys
import tempfile
import tomllib
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

HERE = Path(__file__).resolve().parent
GROUNDS = ("turf", "turf:near", "packed_soil", "packed_soil:near", "sand", "sand:near", "gravel", "gravel:near")
GROUNDS += ("concrete", "concrete:near", "steel_plate", "steel_plate:near", "water")
SCENES = {  # name: (file, settings)
    "paper, air": ("paper.toml", {"air": {"density": 1.225}, "physics": {"until": "rest"}}),
    "field": ("field.toml", {}),
    "hazard": ("hazard.toml", {}),
}


def scene_for(name, ground, pellets, shots):
    """The scene `name` on `ground` (None: its own surface 0), statistics only."""
    from warp_ricochet.scene import scene_from_dict

    file, settings = SCENES[name]
    raw = tomllib.loads((HERE / file).read_text())
    for table, values in settings.items():
        raw.setdefault(table, {}).update(values)
    if ground is not None:
        own = raw["surfaces"][0]
        raw["surfaces"][0] = {"name": ground, "point": own["point"], "normal": own["normal"], "material": ground}
    raw["output"] = {**raw.get("output", {}), "fields": []}
    if "shots" in raw["shot"]:
        raw["shot"]["shots"] = shots
    else:
        raw["shot"]["count"] = pellets
    return scene_from_dict(raw, base_dir=HERE)


def measure(scene, device):
    """The figures of one run (read back from its file)."""
    import warp_ricochet as wr

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "run.h5"
        stats = wr.run(scene, path, device=device)
        with h5py.File(path, "r") as f:
            q = f["stats/quantiles"]
            levels = list(q["distance"].attrs["levels"])
            row = {
                "landing P50": q["distance"][levels.index(0.5)],
                "landing P99": q["distance"][levels.index(0.99)],
                "rest P50": q["rest_distance"][levels.index(0.5)],
                "rest P99": q["rest_distance"][levels.index(0.99)],
                "rest max": stats["rest_distance_max"],
                # p = 1e-3 (the first of hazard.fractions) of the landings above each threshold, and of the reach
                "danger": f["hazard/landing_danger_distance/distance"][:, 0].tolist() if "hazard" in f else [],
                "reach": f["hazard/danger_distance/distance"][:, 0].tolist() if "hazard" in f else [],
            }
    pellets = stats["pellets"]
    for state in ("at_rest", "embedded", "escaped", "not_finished"):
        row[state] = stats[f"rest_{state}"] / pellets
    row["impacts"] = stats["rest_impacts_mean"]
    row["path"] = stats["rest_path_mean"]
    return row


def fmt(x):
    return "-" if x is None or (isinstance(x, float) and not np.isfinite(x)) else f"{x:.3g}"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--pellets", type=int, default=20_000, help="pellets of the paper's scene")
    parser.add_argument("--shots", type=int, default=20, help="shots of the field and hazard scenes (280 pellets each)")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--out", type=Path, default=Path("ground-study"))
    args = parser.parse_args(argv)
    head = "| scene | ground | landing P50 / P99 (m) | rest P50 / P99 / max (m) | at rest / embedded / escaped / not finished | impacts | path on ground (m) | danger distances at landing, p = 1e-3 (m) | along the path (m) |"
    lines = [head, "|" + "---|" * 9]
    for name in SCENES:
        for ground in ((None,) if name.startswith("paper") else ()) + GROUNDS:
            row = measure(scene_for(name, ground, args.pellets, args.shots), args.device)
            label = ground or "its own rigid plane"
            ends = " / ".join(f"{row[s]:.3f}" for s in ("at_rest", "embedded", "escaped", "not_finished"))
            danger = ", ".join(fmt(x) for x in row["danger"]) or "-"
            reach = ", ".join(fmt(x) for x in row["reach"]) or "-"
            line = (
                f"| {name} | {label} | {fmt(row['landing P50'])} / {fmt(row['landing P99'])} | {fmt(row['rest P50'])} / "
                f"{fmt(row['rest P99'])} / {fmt(row['rest max'])} | {ends} | {row['impacts']:.2f} | {fmt(row['path'])} | {danger} | {reach} |"
            )
            lines.append(line)
            print(line, flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "table.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
