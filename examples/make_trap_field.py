"""Writes the synthetic elevation raster of the trap-field example (issue 27, part 5):
warp_ricochet/examples/terrain/trap_field.asc, an ESRI ASCII grid of 5 m cells, 300 m east by 100 m
north, its south-west corner at UTM-scale coordinates (500000, 4200000) (local origin: docs/geometry.md,
"Terrain"). Ground falling 2% eastward (downrange) from elevation 120 m, a berm across it 150 m
down range (a trapezoid of 4 m crest, 1:2 slopes, a 20 m base: sampled every 5 m, a ridge 4 m
high), and a ditch 2 m deep and 30 m wide along its north-east beyond 200 m. Deterministic: running it again writes the same bytes.

    python examples/make_trap_field.py [--out PATH]
"""

import argparse
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
OUT = HERE.parent / "warp_ricochet" / "examples" / "terrain" / "trap_field.asc"
CELL = 5.0  # m
COLS, ROWS = 61, 21  # samples: 300 m x 100 m between the first and last centres
CORNER = (500000.0, 4200000.0)  # (x, y) of the south-west corner, m (a UTM-like map)


def elevation(east, north):
    """Elevation (m) at local (east, north) from the south-west corner (m)."""
    ground = 120.0 - 0.02 * east
    berm = np.clip(4.0 - 0.5 * (np.abs(east - 152.5) - 2.0), 0.0, 4.0)  # crest at 152.5 m, a sample's centre
    ditch = -2.0 * np.clip(1.0 - np.abs(north - 85.0) / 15.0, 0.0, 1.0) * (east > 200.0)
    return ground + berm + ditch


def grid_text() -> str:
    east = CELL * (np.arange(COLS) + 0.5)
    north = CELL * (np.arange(ROWS) + 0.5)[::-1]  # first row: the northernmost
    z = elevation(east[None, :], north[:, None])
    head = [f"ncols {COLS}", f"nrows {ROWS}", f"xllcorner {CORNER[0]:.1f}", f"yllcorner {CORNER[1]:.1f}"]
    head += [f"cellsize {CELL:.1f}", "NODATA_value -9999"]
    return "\n".join(head + [" ".join(f"{v:.2f}" for v in row) for row in z]) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    out = parser.parse_args().out
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(grid_text())
    print(f"wrote {out} ({out.stat().st_size:,} bytes)")


if __name__ == "__main__":
    main()
