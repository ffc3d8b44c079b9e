import sys, time, tomllib
from pathlib import Path
import warp_ricochet as wr
from warp_ricochet.scene import scene_from_dict
root = Path(sys.argv[1]); n = int(float(sys.argv[2]))
raw = tomllib.loads((root / "examples" / "hazard.toml").read_text())
raw["shot"]["shots"] = max(1, n // 280)
raw["physics"] = {**raw["physics"], "until": "rest"}
raw["output"] = {"fields": []}
raw.pop("hazard")
post = {"name": "post", "kind": "cylinder", "point": [20.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "radius": 0.1, "length": 1.2, "material": "concrete"}
for label, surf in (("turf", raw["surfaces"]), ("post", raw["surfaces"] + [post])):
    sc = scene_from_dict({**raw, "surfaces": surf})
    wr.run(scene_from_dict({**raw, "surfaces": surf, "shot": {**raw["shot"], "shots": 1}}), None, device="cpu")
    best = 1e9
    for _ in range(2):
        t = time.process_time(); s = wr.run(sc, None, device="cpu"); best = min(best, time.process_time() - t)
    print(f"{root.name} {label}: {best:.2f} CPU s for {raw['shot']['shots']*280} pellets, {s['rest_steps_mean']:.2f} steps, rest mean {s['rest_distance_mean']:.4f} m", flush=True)
