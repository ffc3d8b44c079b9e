"""Stability of the flight in air (bench/stability_air.py, its docstring states the rules): the
quick subset of its corners in float32 and float64 (speeds 1e-3 to 1e4 m/s, level to straight up
and down, spin to the domain's limit, two drag and lift laws, still air and wind), a pellet at rest
in a wind and falls to the terminal speed. `python -m bench.stability_air` runs the full sweep."""

from bench import stability_air
from tests.test_stability import report


def test_air_corners(device):
    rows = report(stability_air.run_corners(device, quick=True))
    assert {r.precision for r in rows} == {"float32", "float64"} and sum(r.n for r in rows) >= 6 * 100
    by = {(r.case, r.precision): r.measured for r in rows}
    still = by[("loth2021, loth2008, d 2.5 mm", "float64")]
    assert still["energy change / slack"] < 0  # every flight lost energy to the drag
    assert 0 < by[("loth2021, loth2008, d 2.5 mm", "float32")]["compared"]


def test_air_limits(device):
    rows = report(stability_air.run_limits(device))
    measured = {(r.case.split(",")[0], r.precision): r.measured for r in rows}
    assert abs(measured[("at rest in a 20 m/s wind", "float64")]["speed across / wind - 1"]) < 1e-4  # reaches it
