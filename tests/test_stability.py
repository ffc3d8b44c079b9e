"""Stability stress suite: the impact law, the whole pipeline and pellet-pellet collisions driven
through corners, in float32 and float64, with the rules and the quick subset of bench/stability.py
(its docstrings state them; `python -m bench.stability` runs the full sweep).

Corners: grazing impacts (v_n -> 0 from below, to 1e-12 |v|), normal incidence, the exact stick-slip
threshold, incoming spin that reverses the slip direction, restitution 0 and 1, mu 0 and 10; speeds
1e-6 to 1e4 m/s, diameters 0.1 to 20 mm, tilted and vertical planes and an overhang, gravity zero,
along each axis or oblique, pellets launched on, touching or inside a plane. Each case: no NaN or
inf, no energy gain beyond rounding, no pellet inside a plane beyond rounding, float32 within 1e-5
of float64 except at the knife edges where rounding decides (the table says where and why).

The table of what was tried and what held is printed (`pytest -s` or `-rP` shows it) and appended to
the file named by WARP_RICOCHET_STABILITY_TABLE when that is set; a failure shows it too.
"""

import os

import numpy as np

import warp_ricochet as wr
from bench import stability


def report(rows):
    text = stability.table(rows)
    print(text)
    path = os.environ.get("WARP_RICOCHET_STABILITY_TABLE")
    if path:
        with open(path, "a") as f:
            f.write(text + "\n")
    failed = [f"{r.group} / {r.case} / {r.precision}: {f}" for r in rows for f in r.failures]
    assert not failed, "\n".join([text, *failed])
    return rows


def test_impact_law_corners(device):
    rows = report(stability.run_impact_law(device, quick=True))
    assert sum(r.n for r in rows if r.precision == "float32") >= 2700  # the grid really ran
    by = {(r.case, r.precision): r for r in rows}
    corners = by[("corners: speeds 1e-6..1e4 m/s, normal to grazing, spins", "float32")].measured
    assert corners["error off the edges"] <= stability.F32_TOLERANCE  # measured, not just "no failure"
    assert corners["energy gain / (eps E)"] <= stability.ENERGY_ROUNDING


def test_pipeline_corners(device, tmp_path):
    rows = report(stability.run_pipeline(device, quick=True, workdir=tmp_path))
    f64 = next(r for r in rows if r.precision == "float64")
    assert f64.n >= 500 and f64.measured["|gap - R| at landing / (eps scale)"] <= stability.INSIDE_ROUNDING


def test_the_rules_catch_a_law_that_adds_energy_or_drifts(monkeypatch):
    """The checks can fail: an impact law that returns 1e-5 too much speed in float64 breaks the
    energy rule and the agreement with the NumPy reference."""
    real = wr.impact

    def leaky(*args, **kwargs):
        v, w, s = real(*args, **kwargs)
        return v * (1 + 1e-5), w, s

    monkeypatch.setattr(wr, "impact", leaky)
    rows = stability.run_impact_law("cpu", quick=True)
    f64 = next(r for r in rows if r.precision == "float64" and r.case.startswith("corners"))
    assert any("energy gain" in f for f in f64.failures)
    assert any("off the float64 reference" in f for f in f64.failures)


def test_collision_corners(device, tmp_path):
    """Pellets touching, overlapping or coincident at launch; a cloud at volume fraction 0.5 with
    and without a plane; pairs at 1e3 m/s each; a chain pressed onto the ground; fixed steps of 1,
    10 and 100 D / v_rel. Each in float32 and float64 through wr.run, against the rules of
    stability.run_collisions and, where small, the event-driven reference."""
    rows = report(stability.run_collisions(device, quick=True, workdir=tmp_path))
    assert len(rows) == 2 * 11 and sum(r.n for r in rows) >= 2 * 400  # every case ran in both precisions
    by = {(r.case, r.precision): r.measured for r in rows}
    cloud = next(k for k in by if k[0].startswith("cloud") and "on the ground" in k[0] and k[1] == "float64")
    assert by[cloud]["reference pair collisions error"] <= stability.REFERENCE["chaotic"]  # held, not only measured
    pairs = next(k for k in by if k[0].startswith("pairs touching") and k[1] == "float64")
    assert by[pairs]["reference pellet by pellet error (of the speed scale)"] <= stability.REFERENCE["exact"]


def test_the_collision_rules_catch_energy_gain_overlap_and_a_pellet_inside_the_plane(tmp_path):
    """The checks can fail: the head-on case's outputs with 1e-5 more speed at release, one pellet
    moved onto another, or one moved into the ground, break the rules."""
    case = next(c for c in stability.collision_cases(quick=True) if c["name"].startswith("head-on"))
    _scene, o, stats, times, frames = stability.run_collision_case(case, "float64", "cpu", tmp_path, "h")

    def failures(change):
        broken = {k: v.copy() for k, v in o.items()}
        change(broken)
        row = stability.Row("collisions", case["name"], "float64", 0)
        stability._check_collisions(row, case, broken, stats, times, frames, "float64")
        return row.failures

    assert failures(lambda b: None) == []
    assert any("energy" in f for f in failures(lambda b: b["release.velocity"].__imul__(1 + 1e-5)))
    flying = np.nonzero(o["release.time"] >= stats["dense_time_max"])[0]
    assert len(flying) >= 2

    def overlap(b):
        b["release.position"][flying[1]] = b["release.position"][flying[0]] + [0.9 * stability.COLLISION_D, 0, 0]

    assert any("overlap" in f for f in failures(overlap))

    def sink(b):
        b["landing.position"][:, 1] = np.where(np.isfinite(b["landing.position"][:, 1]), 0.5e-3, np.nan)

    assert any("inside R of plane" in f for f in failures(sink))


def test_an_e0_impact_at_normal_incidence_rests_on_the_plane(tmp_path, device):
    """E = 0, no gravity, a tilted plane, pellets moving straight into it: one impact, then at rest
    on the plane (landed at once, range 0), whatever the speed."""
    from warp_ricochet.scene import scene_from_dict

    normal = np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2])
    speeds = np.geomspace(1e-6, 1e4, 41)
    R = 0.00125
    path = tmp_path / "p.npz"
    np.savez(
        path,
        position=np.tile(R * normal, (len(speeds), 1)) + np.outer(np.linspace(0, 1, len(speeds)), [1, -0.3, 0]),
        velocity=-speeds[:, None] * normal,
    )
    for precision in ("float32", "float64"):
        scene = scene_from_dict(
            {
                "shot": {"file": str(path), "diameter": 2 * R, "density": 7000.0},
                "surfaces": [{"point": [0, 0, 0], "normal": list(normal), "restitution": 0.0, "mu_s": 0.3}],
                "physics": {"gravity": [0, 0, 0], "bounces": 3},
                "numerics": {"precision": precision},
            }
        )
        stats = wr.run(scene, tmp_path / f"{precision}.h5", device=device)
        import h5py

        with h5py.File(tmp_path / f"{precision}.h5", "r") as f:
            surfaces = f["pellets/impact/surface"][()]
        assert (surfaces[:, 0] == 0).all() and (surfaces[:, 1:] == -1).all(), (precision, surfaces.tolist())
        assert stats["landed"] == len(speeds) and stats["range_max"] == 0.0, precision


def test_reference_keeps_a_normal_impact_normal_on_a_tilted_plane():
    """The NumPy reference built e_t from the rounding residue of a normal impact's slip velocity,
    which is not tangential on a tilted plane, and turned the impact into a sideways one (|v'| of
    0.94 |v| with E = 0 at 1 m/s): its frame is now orthogonal to rounding."""
    from warp_ricochet.reference import ballistic as reference

    n = np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2])
    for speed in (1e-6, 1.0, 1e4):
        v, w, _ = reference.impact_law(
            -speed * n[None],
            np.zeros((1, 3)),
            n,
            radius=0.00125,
            restitution=0.0,
            mu_s=0.5,
            mu_d=0.5,
            gravity=(0, -9.81, 0),
            duration=1e-3,
        )
        assert np.abs(v).max() <= 1e-14 * speed and np.abs(w).max() <= 1e-14 * speed / 0.00125
