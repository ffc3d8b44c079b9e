"""Flight in air: the integrator's run time against its error, throughput beside the vacuum path,
SciPy and NumPy, the dense phase's splitting against a fine-step reference, and Journee's rule.
Every subcommand flies the paper's scene (examples/paper.toml) in sea-level air unless it says
otherwise, and names the device it ran on.

    python -m bench.air tradeoff [--device cpu] [--checked 200] [--timed 200000] [--out DIR]
    python -m bench.air errors DIR                      (the errors of a tradeoff run without SciPy)
    python -m bench.air cpu [--timed 200000] [--compared 100] [--out DIR]
    python -m bench.air throughput [--device cuda:0] [--sizes 1e6,1e8] [--out DIR]
    python -m bench.air collisions [--device cuda:0] [--shots 10000] [--cases vacuum,air] [--out DIR]
    python -m bench.air ensemble [--shots 200] [--out DIR]  (the same shots in air, leaps on and off)
    python -m bench.air dense [--out DIR]
    python -m bench.air journee [--device cpu] [--out DIR]

`tradeoff`: for each precision and numerics.flight_tolerance, a statistics-only run of --timed
pellets (median of --repeats) and a run of --checked pellets whose flights are compared with the
float64 SciPy reference (`warp_ricochet.reference.air`: DOP853, rtol 1e-12): the first flight from
the launch state, and the flight after the impact from the kernel's own post-impact state, so the
integrator alone is measured. The error of a flight is |landing - reference| / distance flown.
It writes air-tradeoff.csv and air-tradeoff.png (error against pellets/s). Without SciPy, or with
--no-errors (to spend no GPU time on the reference), it writes the checked runs' states
(air-tradeoff-states.h5) and the timings; `errors DIR` then finishes the CSV and PNG elsewhere.

`cpu`: one CPU core (Warp's CPU backend runs a kernel on one thread): pellets/s of the package in
air and in vacuum, of SciPy solve_ivp per pellet, and of a vectorised NumPy RK4 (bench/air_numpy.py),
each with its landing error against the reference, on the same launch states.
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import numpy as np

from bench.__main__ import ROOT, _timed, _wr, device_info

PAPER = ROOT / "examples" / "paper.toml"
SEA_LEVEL = ("air.density=1.225",)  # an [air] table with every default (docs/air.md)
TOLERANCES = {"float32": (1e-2, 1e-3, 1e-4, 1e-5, 1e-6), "float64": (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-10)}
CHECKED_FIELDS = ("initial", "impact", "landing")


def paper_scene(n, precision="float32", *, air=True, tolerance=None, mu_s=0.28, fields=(), extra=()):
    """The paper's scene with n pellets, mu_d = 0.9 mu_s (0.28: stick and slip both occur), in
    sea-level air (air=True) or vacuum; `extra`: more KEY=VALUE settings."""
    from warp_ricochet.scene import load_scene

    sets = [
        f"shot.count={n}",
        f'numerics.precision="{precision}"',
        f"surfaces.0.mu_s={mu_s}",
        f"surfaces.0.mu_d={0.9 * mu_s}",
        "output.fields=" + json.dumps(list(fields)),
    ]
    if air:
        sets += list(SEA_LEVEL)
    if tolerance is not None:
        sets.append(f"numerics.flight_tolerance={tolerance}")
    return load_scene(PAPER, sets + list(extra))


# The scenes of the tradeoff: (mu_s, more settings). The paper's shot with stick and slip (short
# ricochets under Magnus lift), frictionless (the longest ricochets, about 50 m), and a field shot
# (400 m/s, 0-35 degrees up from 1.5 m with backspin: flights of about 200 m, then a ricochet).
TRADEOFF_SCENES = {
    "paper": (0.28, ()),
    "frictionless": (0.0, ()),
    "field": (
        0.3,
        (
            "shot.speed=400.0",
            "shot.direction=[1.0, 0.3, 0.0]",
            "shot.direction_jitter=[0.05, 0.3, 0.1]",
            "shot.envelope_center=[0.0, 1.5, 0.0]",
            "shot.spin=[0.0, 0.0, 3000.0]",
        ),
    ),
}


def _planes(scene):
    return [(np.array(s.point, float), np.array(s.normal, float)) for s in scene.surfaces]


def read_states(path, group="pellets"):
    """The checked fields of a run file as float64 arrays, keyed by their dataset path."""
    import h5py

    with h5py.File(path, "r") as f:
        out = {}
        f[group].visititems(
            lambda name, obj: out.__setitem__(name, obj[()].astype(np.float64)) if hasattr(obj, "shape") else None
        )
    return out


def flight_errors(scene, states, first_cache=None):
    """Per pellet: (first-flight error, landing-flight error), each |x - reference| / distance
    flown, NaN where the reference or the run has no such flight. first_cache: {launch-state
    bytes: contacts} shared between runs with the same launch states."""
    from warp_ricochet.reference import air as ref

    pellet = ref.Pellet(0.5 * scene.shot.diameter, scene.shot.density)
    g, planes = scene.physics.gravity, _planes(scene)
    x0, v0, w0 = states["initial/position"], states["initial/velocity"], states["initial/angular_velocity"]
    key = (x0.tobytes(), v0.tobytes(), w0.tobytes())
    if first_cache is not None and key in first_cache:
        firsts = first_cache[key]
    else:
        firsts = [ref.fly_to_planes(x0[i], v0[i], w0[i], pellet, scene.air, g, planes) for i in range(len(x0))]
        if first_cache is not None:
            first_cache[key] = firsts
    hit_x, hit_v, hit_w = (states[f"impact/{k}"][:, 0] for k in ("position", "velocity", "angular_velocity"))
    surface, landing = states["impact/surface"][:, 0], states["landing/position"]
    first_err, landing_err = np.full(len(x0), np.nan), np.full(len(x0), np.nan)
    for i, first in enumerate(firsts):
        if first is None or not np.isfinite(hit_x[i]).all():
            continue
        first_err[i] = np.linalg.norm(hit_x[i] - first.x) / np.linalg.norm(first.x - x0[i])
        after = ref.fly_to_planes(hit_x[i], hit_v[i], hit_w[i], pellet, scene.air, g, planes, touching=int(surface[i]))
        if after is not None and np.isfinite(landing[i]).all():
            flown = np.linalg.norm(after.x - hit_x[i])
            landing_err[i] = np.linalg.norm(landing[i] - after.x) / max(flown, scene.shot.diameter)
    return first_err, landing_err


def _summary(first_err, landing_err):
    """Max, 99th percentile and median over all flights; the max of first and landing flights apart
    (a short ricochet far from the origin meets float32's position resolution, ulp(|x|) / flown)."""
    both = np.concatenate([first_err[np.isfinite(first_err)], landing_err[np.isfinite(landing_err)]])
    return {
        "error_max": float(both.max()),
        "error_p99": float(np.quantile(both, 0.99)),
        "error_median": float(np.median(both)),
        "first_error_max": float(np.nanmax(first_err)),
        "landing_error_max": float(np.nanmax(landing_err)),
        "flights_checked": int(both.size),
    }


def _have_scipy():
    try:
        import scipy  # noqa: F401
    except ImportError:
        return False
    return True


def _write_csv(rows, path):
    keys = list(dict.fromkeys(k for row in rows for k in row))
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {path}")


def _tradeoff_scene(name, n, precision, tolerance, fields=()):
    mu_s, extra = TRADEOFF_SCENES[name]
    return paper_scene(n, precision, tolerance=tolerance, mu_s=mu_s, fields=fields, extra=extra)


def tradeoff(device, checked, timed, repeats, out_dir, scenes=tuple(TRADEOFF_SCENES), with_errors=True):
    """Run time (statistics only) and states of the checked runs for each scene, precision and
    tolerance."""
    wr, wp = _wr()
    out_dir.mkdir(parents=True, exist_ok=True)
    states_path = out_dir / "air-tradeoff-states.h5"
    states_path.unlink(missing_ok=True)
    rows = []
    for name in scenes:
        for precision, tolerances in TOLERANCES.items():
            for tol in tolerances:
                label = f"{name}/{precision}/{tol:g}"
                run_path = out_dir / "checked.h5"
                wr.run(_tradeoff_scene(name, checked, precision, tol, CHECKED_FIELDS), run_path, device=device, overwrite=True)
                _append_states(states_path, label, run_path)
                run_path.unlink()
                scene = _tradeoff_scene(name, timed, precision, tol)
                stats = wr.run(scene, device=device)  # warm-up: compiles the kernel

                def go(scene=scene):
                    wr.run(scene, device=device)
                    wp.synchronize_device(device)

                t, _ = _timed(go, repeats)
                rows.append(
                    {
                        "scene": name,
                        "precision": precision,
                        "tolerance": tol,
                        "pellets_per_s": timed / t,
                        "N_timed": timed,
                        "steps_per_flight": stats["flight_steps_mean"],
                        "range_mean_m": stats["range_mean"],
                        "flights_unfinished": stats["flights_unfinished"],
                    }
                )
                print(
                    f"air tradeoff {label:26s} {timed / t:.3e} pellets/s, {stats['flight_steps_mean']:.2f} steps "
                    f"per flight, mean range {stats['range_mean']:.4f} m",
                    flush=True,
                )
    _write_csv(rows, out_dir / "air-tradeoff-timings.csv")
    if with_errors and _have_scipy():
        errors(out_dir)
    else:
        print("errors not computed here: run `python -m bench.air errors DIR` (needs SciPy)")
    return rows


def _append_states(path, label, run_path):
    import h5py

    with h5py.File(path, "a") as dst, h5py.File(run_path, "r") as src:
        src.copy(src["pellets"], dst, name=label.replace("/", "|"))


def errors(out_dir):
    """The errors of a tradeoff run's checked states against the reference: the CSV and PNG."""
    import h5py

    out_dir = Path(out_dir)
    with open(out_dir / "air-tradeoff-timings.csv") as f:
        rows = list(csv.DictReader(f))
    cache = {}
    with h5py.File(out_dir / "air-tradeoff-states.h5", "r") as f:
        labels = list(f)
    for row in rows:
        label = f"{row['scene']}|{row['precision']}|{float(row['tolerance']):g}"
        if label not in labels:
            continue
        states = read_states(out_dir / "air-tradeoff-states.h5", label)
        scene = _tradeoff_scene(row["scene"], len(states["initial/position"]), row["precision"], float(row["tolerance"]))
        row.update(_summary(*flight_errors(scene, states, cache)))
        print(
            f"air tradeoff {label:26s} error per flight: max {row['error_max']:.2e} (first flights "
            f"{row['first_error_max']:.2e}, after the impact {row['landing_error_max']:.2e}), p99 {row['error_p99']:.2e}, "
            f"median {row['error_median']:.2e} ({row['flights_checked']} flights)",
            flush=True,
        )
    _write_csv(rows, out_dir / "air-tradeoff.csv")
    _plot_tradeoff(rows, out_dir / "air-tradeoff.png")


def _plot_tradeoff(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    fig, axes = plt.subplots(1, len(scenes), figsize=(5.2 * len(scenes), 4.4), squeeze=False)
    for ax, name in zip(axes[0], scenes):
        for precision, marker in (("float32", "o"), ("float64", "s")):
            mine = [r for r in rows if r["scene"] == name and r["precision"] == precision and "error_max" in r]
            x = [float(r["pellets_per_s"]) for r in mine]
            for key, style in (("error_max", "-"), ("error_median", ":")):
                ax.plot(
                    x, [float(r[key]) for r in mine], style, marker=marker, label=f"{precision}, {key.split('_')[1]} over flights"
                )
            for r in mine:
                ax.annotate(
                    f"{float(r['tolerance']):g}",
                    (float(r["pellets_per_s"]), float(r["error_max"])),
                    textcoords="offset points",
                    xytext=(4, 4),
                    fontsize=7,
                )
        ax.axhline(1e-4, color="grey", lw=0.8, ls="--", label="1e-4 of the distance flown")
        ax.set(xscale="log", yscale="log", xlabel="pellets/s (statistics only)", title=f"{name} scene")
    axes[0][0].set_ylabel("|landing - reference| / distance flown")
    axes[0][0].legend(fontsize=7)
    fig.suptitle("Flight in air: run time against error (point labels: numerics.flight_tolerance)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    print(f"wrote {path}")


# ------------------------------------------------------------------------------------------ cpu


def scipy_ricochet(scene, x0, v0, w0, rtol=1e-12, method="DOP853"):
    """Launch -> contact -> impact law -> landing per pellet with SciPy (one bounce); returns
    landing positions (N, 3), NaN where a flight finds no plane."""
    from warp_ricochet.reference import air as ref
    from warp_ricochet.reference.ballistic import impact_law

    pellet = ref.Pellet(0.5 * scene.shot.diameter, scene.shot.density)
    g, planes = scene.physics.gravity, _planes(scene)
    out = np.full((len(x0), 3), np.nan)
    for i in range(len(x0)):
        first = ref.fly_to_planes(x0[i], v0[i], w0[i], pellet, scene.air, g, planes, rtol=rtol, method=method)
        if first is None:
            continue
        s = scene.surfaces[first.plane]
        v2, w2, _ = impact_law(
            first.v[None],
            first.omega[None],
            planes[first.plane][1],
            radius=pellet.radius,
            restitution=s.restitution,
            mu_s=s.mu_s,
            mu_d=s.mu_d,
            gravity=g,
            duration=scene.physics.impact_duration,
        )
        after = ref.fly_to_planes(
            first.x, v2[0], w2[0], pellet, scene.air, g, planes, touching=first.plane, rtol=rtol, method=method
        )
        if after is not None:
            out[i] = after.x
    return out


def _ricochet_error(landing, reference, x0):
    """|landing - reference| / distance from the launch to the reference landing, per pellet."""
    flown = np.linalg.norm(reference - x0, axis=1)
    ok = np.isfinite(flown) & np.isfinite(landing).all(1)
    err = np.linalg.norm(landing[ok] - reference[ok], axis=1) / flown[ok]
    return {
        "error_max": float(err.max()),
        "error_median": float(np.median(err)),
        "error_p99": float(np.quantile(err, 0.99)),
        "compared": int(ok.sum()),
    }


def cpu(timed, compared, numpy_n, repeats, out_dir, mu_s, h=1e-3):
    """One core, the paper's scene at mu_s: the package (air, vacuum; both precisions), SciPy per
    pellet, NumPy RK4 vectorised; each method's landing error on the same launch states."""
    from bench import air_numpy

    wr, wp = _wr()
    rows = []
    for precision in ("float32", "float64"):
        for air in (True, False):
            scene = paper_scene(timed, precision, air=air, mu_s=mu_s)
            stats = wr.run(scene, device="cpu")
            t, _ = _timed(lambda scene=scene: wr.run(scene, device="cpu"), repeats)
            rows.append(
                {
                    "mu_s": mu_s,
                    "method": f"warp-ricochet {precision}, {'air' if air else 'vacuum'}",
                    "pellets_per_s": timed / t,
                    "N": timed,
                    "steps_per_pellet": stats.get("flight_steps_mean", 0.0),
                }
            )
            print(f"cpu mu_s {mu_s}: {rows[-1]['method']:32s} {timed / t:.3e} pellets/s", flush=True)
    # the same launch states for every method: those the package drew (float64)
    path = out_dir / "cpu-compared.h5"
    for precision in ("float32", "float64"):
        scene = paper_scene(compared, precision, mu_s=mu_s, fields=CHECKED_FIELDS)
        wr.run(scene, path, device="cpu", overwrite=True)
        states = read_states(path)
        x0, v0, w0 = states["initial/position"], states["initial/velocity"], states["initial/angular_velocity"]
        reference = scipy_ricochet(scene, x0, v0, w0)
        row = next(r for r in rows if r["method"] == f"warp-ricochet {precision}, air")
        row.update(_ricochet_error(states["landing/position"], reference, x0))  # (float64 launch states last)
    for method, rtol in (("RK45", 1e-6), ("DOP853", 1e-8)):
        t0 = time.perf_counter()
        landing = scipy_ricochet(scene, x0, v0, w0, rtol=rtol, method=method)
        t = time.perf_counter() - t0
        rows.append(
            {
                "mu_s": mu_s,
                "method": f"SciPy solve_ivp {method} rtol {rtol:g}, per pellet",
                "pellets_per_s": compared / t,
                "N": compared,
                **_ricochet_error(landing, reference, x0),
            }
        )
        print(f"cpu mu_s {mu_s}: {rows[-1]['method']:32s} {compared / t:.3e} pellets/s", flush=True)
    big = paper_scene(numpy_n, "float64", mu_s=mu_s, fields=("initial",))
    wr.run(big, path, device="cpu", overwrite=True)
    launch = read_states(path)
    x, v, w = (launch[f"initial/{k}"] for k in ("position", "velocity", "angular_velocity"))
    assert np.array_equal(x[:compared], x0), "the first pellets of a bigger run are not the same pellets"
    t0 = time.perf_counter()
    _contact, landing = air_numpy.ricochet(big, x, v, w, h)
    t = time.perf_counter() - t0
    rows.append(
        {
            "mu_s": mu_s,
            "method": f"NumPy RK4 vectorised, h = {h:g} s",
            "pellets_per_s": numpy_n / t,
            "N": numpy_n,
            **_ricochet_error(landing[:compared, :3], reference, x0),
        }
    )
    print(f"cpu mu_s {mu_s}: {rows[-1]['method']:32s} {numpy_n / t:.3e} pellets/s", flush=True)
    path.unlink()
    for row in rows:
        if "error_max" in row:
            print(
                f"    {row['method']:40s} landing error / distance flown: max {row['error_max']:.1e}, "
                f"median {row['error_median']:.1e} ({row['compared']} pellets)"
            )
    return rows


# ------------------------------------------------------------------------------ device throughput


def throughput(device, sizes, repeats, precision):
    """Statistics only, the paper's scene (mu_s 0.5 as published, and 0.05: long slip flights) in
    air at the default tolerance beside the same scene in vacuum, in one run."""
    wr, wp = _wr()
    from warp_ricochet.model import State

    rows = []
    for n in sizes:
        for mu_s in (0.5, 0.05):
            for air in (False, True):
                scene = paper_scene(n, precision, air=air, mu_s=mu_s)
                stats = wr.run(scene, device=device)  # warm-up (compiles)

                def go(scene=scene):
                    wr.run(scene, device=device)
                    wp.synchronize_device(device)

                t, times = _timed(go, repeats)
                row = {
                    "N": n,
                    "precision": precision,
                    "mu_s": mu_s,
                    "air": air,
                    "seconds": t,
                    "pellets_per_s": n / t,
                    "steps_per_pellet": stats.get("flight_steps_mean", 0.0),
                    "range_mean_m": stats["range_mean"],
                    "device_bytes_per_pellet": State.bytes_per_pellet(precision, (), scene.physics.bounces),
                }
                rows.append(row)
                print(
                    f"N={n:.0e} {precision} mu_s={mu_s} {'air   ' if air else 'vacuum'} {n / t:.3e} pellets/s "
                    f"({t * 1e3:.1f} ms, runs {', '.join(f'{x * 1e3:.1f}' for x in times)}), "
                    f"{row['steps_per_pellet']:.2f} steps per flight, {row['device_bytes_per_pellet']:.3f} device "
                    f"B/pellet, mean range {stats['range_mean']:.3f} m",
                    flush=True,
                )
    return rows


def air_shots(count, shots, precision, air=True, **collisions):
    """The paper's shot, `shots` times, collisions on, in sea-level air or vacuum."""
    extra = [f"shot.shots={shots}", "collisions.enabled=true", "output.fields=[]"]
    extra += [f"collisions.{k}={v}" for k, v in collisions.items() if v is not None]
    return paper_scene(count, precision, air=air, mu_s=0.5, extra=extra)


COLLISION_CASES = {"vacuum": (False, None), "air": (True, True), "air-no-leaps": (True, False)}


def collisions(device, count, shots, repeats, precisions, cases=tuple(COLLISION_CASES)):
    """The whole run with pellet-pellet collisions in vacuum, in air, and in air without leaps
    (collisions.air_leaps = false: every shot steps to its end), in one run (`cases`: which)."""
    import warnings

    wr, wp = _wr()
    rows = []
    for precision in precisions:
        for air, leaps in (COLLISION_CASES[case] for case in cases):
            scene = air_shots(count, shots, precision, air, air_leaps=None if leaps is None else str(leaps).lower())
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # float32 collisions: the PrecisionWarning is known here
                stats = wr.run(scene, device=device)
                t, times = _timed(lambda scene=scene: (wr.run(scene, device=device), wp.synchronize_device(device)), repeats)
            row = {
                "shots": shots,
                "count": count,
                "precision": precision,
                "air": air,
                "leaps": leaps,
                "seconds": t,
                "dense_steps_max": stats["dense_steps_max"],
                "dense_steps_mean": stats["dense_steps_mean"],
                "collided_fraction": stats["collided_fraction"],
                "range_mean_m": stats["range_mean"],
            }
            rows.append(row)
            label = "vacuum" if not air else ("air" if leaps else "air, no leaps")
            print(
                f"{shots} shots x {count} {precision} {label:14s}: {t:.3f} s (runs "
                f"{', '.join(f'{x:.3f}' for x in times)}), dense steps max {stats['dense_steps_max']:.0f} mean "
                f"{stats['dense_steps_mean']:.0f}, collided {stats['collided_fraction']:.4f}, mean range "
                f"{stats['range_mean']:.3f} m",
                flush=True,
            )
    return rows


def ensemble(device, count, shots, out_dir):
    """The same shots in air with leaps and without (collisions.air_leaps): run time and each
    statistic's mean over shots with its 95% interval (Student t), from /stats/shots."""
    import warnings

    import h5py

    wr, _ = _wr()
    rows = []
    for leaps in ("true", "false"):
        scene = air_shots(count, shots, "float32", True, air_leaps=leaps)
        path = out_dir / f"ensemble-leaps-{leaps}.h5"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            start = time.perf_counter()
            wr.run(scene, path, device=device, overwrite=True, sidecar=False)
            seconds = time.perf_counter() - start
        row = {"leaps": leaps, "shots": shots, "count": count, "seconds": seconds}
        with h5py.File(path, "r") as f:
            for name in (
                "collided_fraction",
                "pair_collisions",
                "range_mean",
                "range_max",
                "landing_mean_WT",
                "pair_energy_lost",
                "dense_steps_mean",
            ):
                x = f["stats/shots/" + name][()]
                row[name] = (float(x.mean()), float(1.972 * x.std(ddof=1) / np.sqrt(len(x))))
        path.unlink()
        rows.append(row)
        print(
            f"{shots} shots x {count}, leaps {leaps}: {seconds:.1f} s | "
            + " | ".join(f"{k} {v[0]:.4g} +- {v[1]:.2g}" for k, v in row.items() if isinstance(v, tuple)),
            flush=True,
        )
    return rows


# ------------------------------------------------------------------------------------- dense phase

LONE = ("shot.envelope_radius=15.0", "shot.spin=[0.0, 0.0, 2000.0]", "physics.bounces=2")  # metres apart: none meets


def _landings(scene, device, path):
    wr, _ = _wr()
    t0 = time.perf_counter()
    stats = wr.run(scene, path, device=device, overwrite=True)
    seconds = time.perf_counter() - t0
    return read_states(path), stats, seconds


def _lattice(count, out_dir, collisions):
    """`count` identical pellets 1 m apart across the shot, each launched as the paper's mean
    pellet with a sideways spin: no relative motion, so the air alone bounds the adaptive step."""
    from warp_ricochet.scene import scene_from_dict

    z = np.arange(count, dtype=float)
    one = np.ones_like(z)
    np.savez(
        out_dir / "lattice.npz",
        position=np.stack([0 * z, one, z], 1),
        velocity=np.stack([290.96 * one, -290.96 * one, 0 * z], 1),
        angular_velocity=np.stack([0 * z, 0 * z, -3e3 * one], 1),
    )
    raw = {
        "shot": {"file": str(out_dir / "lattice.npz"), "diameter": 0.0025, "density": 7000.0},
        "surfaces": [{"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.01, "mu_s": 0.28, "mu_d": 0.252}],
        "physics": {"bounces": 2},
        "air": {},
        "numerics": {"precision": "float64", "flight_tolerance": 1e-12},
        "output": {"fields": ["initial", "landing"]},
        "collisions": {"enabled": collisions is not None, **(collisions or {})},
    }
    return scene_from_dict(raw)


def _dense_rows(label, cases, reference, device, path):
    flown = np.linalg.norm(reference["landing/position"] - reference["initial/position"], axis=1)
    landed = np.isfinite(flown)
    rows = []
    for key, value, scene in cases:
        states, stats, seconds = _landings(scene, device, path)
        err = np.linalg.norm(states["landing/position"] - reference["landing/position"], axis=1)[landed] / flown[landed]
        rows.append(
            {
                "case": label,
                key: value,
                "error_max": float(err.max()),
                "error_median": float(np.median(err)),
                "dense_steps_mean": stats["dense_steps_mean"],
                "pair_collisions": stats["pair_collisions"],
                "seconds": seconds,
                "pellets": int(landed.sum()),
            }
        )
        print(
            f"dense {label}, {key} = {value}: landing error / distance flown max {err.max():.2e}, median "
            f"{np.median(err):.2e}; {stats['dense_steps_mean']:.0f} dense steps; {seconds:.2f} s "
            f"({int(landed.sum())} pellets, {stats['pair_collisions']:.0f} pair collisions)",
            flush=True,
        )
    return rows


def dense(device, count, fractions, steps, out_dir):
    """Pellets that never meet, through the dense phase (exact flight, the air as Strang kicks),
    against the core's integrated flight at flight_tolerance 1e-12 (float64): the landing error
    per pellet over the distance flown. A cloud metres apart (its step is set by the pellets'
    relative speeds) at fixed steps and the default adaptive step; a rigid lattice (no relative
    motion: the step is set by air_step_fraction) over air_step_fraction."""
    sets = list(LONE) + ['output.fields=["initial", "landing"]']
    path = out_dir / "dense.h5"

    def cloud(*extra):
        return paper_scene(count, "float64", tolerance=1e-12, mu_s=0.28, extra=sets + list(extra))

    reference, _, _ = _landings(cloud(), device, path)
    cases = [("time_step", h, cloud("collisions.enabled=true", f"collisions.time_step={h}")) for h in steps]
    cases.append(("time_step", "adaptive", cloud("collisions.enabled=true")))
    rows = _dense_rows("cloud", cases, reference, device, path)
    reference, _, _ = _landings(_lattice(count, out_dir, None), device, path)
    cases = [("air_step_fraction", f, _lattice(count, out_dir, {"air_step_fraction": f})) for f in fractions]
    rows += _dense_rows("lattice", cases, reference, device, path)
    path.unlink()
    (out_dir / "lattice.npz").unlink()
    _write_csv(rows, out_dir / "air-dense.csv")
    return rows


# ---------------------------------------------------------------------------------------- Journee

# US shot sizes (lead): diameter in inches (nominal); Journee's rule: longest range (yards) ~ 2200 x d (inches)
SHOT_SIZES = (("#9", 0.08), ("#7.5", 0.095), ("#6", 0.11), ("#4", 0.13), ("#2", 0.15), ("BB", 0.18), ("00 buck", 0.33))
LEAD = 11340.0  # kg/m^3
YARD, INCH = 0.9144, 0.0254


def journee(device, speed, angles, out_dir, drags=("loth2021", "braun")):
    """Longest range of lead shot fired from flat ground at `speed` over launch angles, with the
    package (one pellet per angle, its first contact), against Journee's rule and the vacuum."""
    wr, _ = _wr()
    from warp_ricochet.scene import scene_from_dict

    rows = []
    for drag in drags:
        for name, inches in SHOT_SIZES:
            d = inches * INCH
            a = np.radians(angles)
            position = np.stack([np.zeros_like(a), np.full_like(a, 0.5 * d), np.zeros_like(a)], 1)
            velocity = speed * np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], 1)
            np.savez(out_dir / "journee.npz", position=position, velocity=velocity, angular_velocity=0 * velocity)
            air = {} if drag == "loth2021" else {"drag": "table", "drag_table": drag}
            raw = {
                "shot": {"file": str(out_dir / "journee.npz"), "diameter": d, "density": LEAD},
                "surfaces": [{"point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "restitution": 0.0, "mu_s": 0.5}],
                "air": air,
                "numerics": {"precision": "float64"},
                "output": {"fields": ["impact.position"]},
            }
            wr.run(scene_from_dict(raw), out_dir / "journee.h5", device=device, overwrite=True)
            x = read_states(out_dir / "journee.h5")["impact/position"][:, 0, 0]
            best = int(np.nanargmax(x))
            rule = 2200.0 * inches * YARD
            rows.append(
                {
                    "drag": drag,
                    "shot": name,
                    "diameter_mm": d * 1e3,
                    "max_range_m": float(x[best]),
                    "best_angle_deg": float(angles[best]),
                    "journee_m": rule,
                    "ratio": float(x[best]) / rule,
                    "vacuum_m": speed**2 / 9.81,
                    "fraction_of_vacuum": float(x[best]) / (speed**2 / 9.81),
                }
            )
            print(
                f"journee {drag:8s} {name:8s} d = {d * 1e3:5.2f} mm: longest range {x[best]:7.1f} m at "
                f"{angles[best]:.1f} deg; Journee {rule:7.1f} m (model/rule {x[best] / rule:.2f}); "
                f"{100 * x[best] / (speed**2 / 9.81):.1f}% of the vacuum's {speed**2 / 9.81:,.0f} m",
                flush=True,
            )
    for p in ("journee.npz", "journee.h5"):
        (out_dir / p).unlink()
    _write_csv(rows, out_dir / "air-journee.csv")
    return rows


# ------------------------------------------------------------------------------------------- main


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m bench.air", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("what", choices=("tradeoff", "errors", "cpu", "throughput", "collisions", "ensemble", "dense", "journee"))
    parser.add_argument("dir", nargs="?", help="errors: the tradeoff run's folder")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--precision", default="float32")
    parser.add_argument("--checked", type=int, default=200, help="tradeoff: pellets compared with the reference")
    parser.add_argument("--timed", type=float, default=1e5, help="tradeoff, cpu: pellets in the timed runs")
    parser.add_argument("--compared", type=int, default=100, help="cpu: pellets run by SciPy")
    parser.add_argument("--numpy", type=float, default=1e4, help="cpu: pellets run by NumPy RK4")
    parser.add_argument("--sizes", default="1e6", help="throughput: pellet counts")
    parser.add_argument("--shots", type=int, default=10000, help="collisions, ensemble: shots of 450 pellets")
    parser.add_argument("--precisions", default="float32,float64", help="collisions")
    parser.add_argument("--cases", default=",".join(COLLISION_CASES), help="collisions: which runs")
    parser.add_argument("--count", type=int, default=40, help="dense: pellets")
    parser.add_argument("--speed", type=float, default=411.48, help="journee: launch speed, m/s")
    parser.add_argument(
        "--mu-s",
        dest="mu_s",
        type=float,
        nargs="+",
        default=[0.5, 0.28, 0.0],
        help="cpu: the paper's scene at these mu_s (0.5 as published; 0: the longest ricochets)",
    )
    parser.add_argument("--no-errors", action="store_true", help="tradeoff: timings and states only (errors later)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", default="bench-air", help="folder for the CSV, PNG and JSON")
    args = parser.parse_args(argv)
    if args.what == "errors":
        errors(Path(args.dir or args.out))
        return 0
    wr, wp = _wr()
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    record = {"info": device_info(wp, args.device), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}
    print(json.dumps(record["info"]), flush=True)
    if args.what == "tradeoff":
        record[args.what] = tradeoff(
            args.device, args.checked, int(args.timed), args.repeats, out_dir, with_errors=not args.no_errors
        )
    elif args.what == "cpu":
        record[args.what] = [
            row for mu_s in args.mu_s for row in cpu(int(args.timed), args.compared, int(args.numpy), args.repeats, out_dir, mu_s)
        ]
        _write_csv(record[args.what], out_dir / "air-cpu.csv")
    elif args.what == "throughput":
        sizes = [int(float(s)) for s in args.sizes.split(",")]
        record[args.what] = throughput(args.device, sizes, args.repeats, args.precision)
    elif args.what == "collisions":
        record[args.what] = collisions(
            args.device, 450, args.shots, args.repeats, args.precisions.split(","), args.cases.split(",")
        )
    elif args.what == "ensemble":
        record[args.what] = ensemble(args.device, 450, args.shots, out_dir)
    elif args.what == "dense":
        record[args.what] = dense(
            args.device,
            args.count,
            (0.16, 0.08, 0.04, 0.02, 0.01, 0.005, 0.0025),
            (4e-4, 1e-4, 2.5e-5, 6.25e-6, 1.5625e-6),
            out_dir,
        )
    elif args.what == "journee":
        record[args.what] = journee(args.device, args.speed, np.arange(5.0, 45.01, 0.25), out_dir)
    path = out_dir / f"air-{args.what}-{args.device.replace(':', '')}.json"
    path.write_text(json.dumps(record, indent=1, default=float))
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
