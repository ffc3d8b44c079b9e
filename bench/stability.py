"""Stability sweep (no collisions): the impact law and the whole pipeline driven through corners, in
float32 and float64 on a Warp device, each case checked against the rules below. Prints a table of
what was tried and what held. `python -m bench.stability [--device cpu] [--quick]`; the CI subset
is tests/test_stability.py, which uses the same cases and checks (`quick=True`).

Rules, per case (all SI, energies per unit mass, k = I / (m R^2) = 2/5):

- finite: no NaN or inf in any result that exists (an impact that happened, a pellet that landed);
- energy: the impact never adds kinetic energy |v|^2/2 + k R^2 |w|^2/2 beyond rounding
  (ENERGY_ROUNDING eps of the energy); along a whole trajectory the mechanical energy
  (kinetic - g . r) at landing never exceeds the launch's beyond rounding of its terms;
- not inside a plane: at every impact and at the landing, the centre is in front of the plane it
  touches by R within INSIDE_ROUNDING eps of the position's scale (|r| + R + the flight's extent),
  and no landed pellet overlaps any plane it is in front of by more than that;
- float32 against float64: the same branch (stick/slip) and surfaces, and results within F32_TOLERANCE
  of the case's scale, except where a rule below says float32 cannot (the table says which and why).

The measured largest values of each quantity are printed beside the limits, so docs/stability.md
can quote them.
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

K = 0.4  # I / (m R^2) of a solid sphere
EPS = {"float32": float(np.finfo(np.float32).eps), "float64": float(np.finfo(np.float64).eps)}
ENERGY_ROUNDING = 16  # eps of the energy: an impact may "gain" no more than this (rounding of |v|^2 sums)
INSIDE_ROUNDING = 256  # eps of the position scale: how far a centre may sit inside R of a plane
F32_TOLERANCE = 1e-5  # float32 against float64, relative to the case's scale (velocities, ranges)
F64_TOLERANCE = 1e-12  # float64 on the device against the NumPy float64 reference
MAX_SPIN = 1e8  # rad/s per component, the physical domain (warp_ricochet.scene.MAX_SPIN)


@dataclass
class Row:
    """One line of the table: a group of cases, what was measured, what held."""

    group: str
    case: str
    precision: str
    n: int
    measured: dict = field(default_factory=dict)  # name -> largest value seen
    failures: list = field(default_factory=list)  # rule texts that did not hold
    known: list = field(default_factory=list)  # defects found, reported, not fixed here (docs/stability.md)
    notes: list = field(default_factory=list)  # where float32 cannot, and what the code does

    @property
    def held(self) -> bool:
        return not self.failures


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _frame(normal):
    """Two unit tangents of a plane with unit normal n."""
    n = _unit(normal)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    t = _unit(np.cross(n, helper))
    return t, np.cross(t, n)


NORMALS = {"floor": (0.0, 1.0, 0.0), "tilted": (0.3, 1.0, 0.2), "vertical wall": (-1.0, 0.0, 0.0),
           "overhang": (0.2, -1.0, 0.4)}
GRAVITIES = {"g = 0": (0.0, 0.0, 0.0), "g -y": (0.0, -9.81, 0.0), "g +x": (9.81, 0.0, 0.0), "g -z": (0.0, 0.0, -9.81),
             "g oblique": (5.66, -5.66, 5.66)}


# ---------------------------------------------------------------------------------------------- impact law

def impact_states(speeds, normal, radius, rng):
    """(velocity, angular velocity, label) arrays: for each speed, incidences from normal to grazing
    and spins: none, about the normal, topspin, backspin that reverses the slip, random."""
    n = _unit(normal)
    t, o = _frame(n)
    rows = []
    incidences = {"normal incidence": (0.0, -1.0), "45 deg": (1.0, -1.0), "grazing 1e-2": (1.0, -1e-2),
                  "grazing 1e-4": (1.0, -1e-4), "grazing 1e-7": (1.0, -1e-7), "grazing 1e-12": (1.0, -1e-12)}
    for speed in speeds:
        for name, (a, b) in incidences.items():
            v = speed * _unit(a * t + b * n) if a else -speed * n
            vt = speed * a / math.hypot(a, b) if a else 0.0
            spins = {"no spin": np.zeros(3), "spin about n": speed / radius * n,
                     "topspin": -vt / radius * o if vt else np.zeros(3),  # rolling already: no slip
                     "backspin reversing slip": 3.0 * vt / radius * o if vt else speed / radius * o,
                     "random spin": rng.normal(0.0, speed / radius, 3)}
            for spin_name, w in spins.items():
                top = np.abs(w).max()
                if top > MAX_SPIN:  # the domain's bound (scene.MAX_SPIN): the corner is on it
                    w = w * (0.999 * MAX_SPIN / top)
                rows.append((v, w, f"{name}, {spin_name}"))
    v = np.array([r[0] for r in rows])
    w = np.array([r[1] for r in rows])
    return v, w, [r[2] for r in rows]


def kinetic(v, w, radius):
    return 0.5 * (v * v).sum(-1) + 0.5 * K * radius**2 * (w * w).sum(-1)


def impact_cases(quick: bool):
    """Groups of impact-law cases: dict(name, radius, restitution, mu_s, mu_d, gravity, duration, normal)."""
    diameters = (1e-4, 2.5e-3, 2e-2)
    restitutions = (0.0, 0.5, 1.0)
    frictions = ((0.0, 0.0), (0.5, 0.5), (0.5, 0.45), (10.0, 10.0), (10.0, 2.0))
    gravity = (("g = 0", 0.0), ("g -y", 0.0), ("g -y", 1e-3), ("g +x", 1e-3), ("g -z", 1e-3), ("g oblique", 1e-3))
    normals = list(NORMALS)
    combos = itertools.product(diameters, restitutions, frictions, gravity, normals)
    if quick:  # every value of every axis, not every combination
        combos = [(diameters[i % 3], restitutions[(i // 3) % 3], frictions[i % 5], gravity[i % 6],
                   normals[(i // 2) % 4]) for i in range(30)]
    for d, e, (mu_s, mu_d), (gname, dt), nname in combos:
        yield dict(name=f"D {d * 1e3:g} mm, E {e:g}, mu {mu_s:g}/{mu_d:g}, {gname}, dt {dt:g} s, {nname}",
                   radius=d / 2, restitution=e, mu_s=mu_s, mu_d=mu_d, gravity=GRAVITIES[gname], duration=dt,
                   normal=_unit(NORMALS[nname]))


def run_impact_law(device="cpu", quick=False, seed=0):
    """Rows of the impact-law table: each group of cases in float32 and float64."""
    import warp_ricochet as wr
    from warp_ricochet import reference

    rng = np.random.default_rng(seed)
    speeds = (1e-6, 1e-2, 1.0, 1e2, 1e4) if not quick else (1e-6, 1.0, 1e4)
    rows = {p: Row("impact law", "corners: speeds 1e-6..1e4 m/s, normal to grazing, spins", p, 0) for p in EPS}
    for case in impact_cases(quick):
        v, w, labels = impact_states(speeds, case["normal"], case["radius"], rng)
        kw = dict(radius=case["radius"], density=7000.0, restitution=case["restitution"], mu_s=case["mu_s"],
                  mu_d=case["mu_d"], gravity=case["gravity"], duration=case["duration"])
        ref_v, ref_w, _ = reference.impact_law(v, w, case["normal"], radius=case["radius"],
                                               restitution=case["restitution"], mu_s=case["mu_s"],
                                               mu_d=case["mu_d"], gravity=case["gravity"], duration=case["duration"])
        out = {p: wr.impact(v, w, case["normal"], device=device, precision=p, **kw) for p in EPS}
        scale = np.maximum(np.linalg.norm(v, axis=1), case["radius"] * np.linalg.norm(w, axis=1))
        before = kinetic(v, w, case["radius"])
        edges = knife_edges(case, v, w, scale)
        for p, (v2, w2, _slipped) in out.items():
            row = rows[p]
            row.n += len(v)
            v2, w2 = v2.astype(float), w2.astype(float)
            if not (np.isfinite(v2).all() and np.isfinite(w2).all()):
                row.failures.append(f"non-finite result: {case['name']}")
                continue
            gain = (kinetic(v2, w2, case["radius"]) - before) / before
            _record(row, "energy gain / (eps E)", gain.max() / EPS[p])
            if gain.max() > ENERGY_ROUNDING * EPS[p]:
                i = int(gain.argmax())
                row.failures.append(f"energy gain {gain[i]:.2e}: {case['name']}, {labels[i]}")
            # against the NumPy float64 reference, allowing the law's jump at the knife edges this
            # precision cannot resolve
            err = np.maximum(np.abs(v2 - ref_v).max(axis=1), case["radius"] * np.abs(w2 - ref_w).max(axis=1)) / scale
            tolerance = F64_TOLERANCE if p == "float64" else F32_TOLERANCE
            on_edge = edges[p]["approach"] | edges[p]["threshold"]
            allowed = tolerance + np.where(on_edge, edges[p]["jump"], 0.0)
            _record(row, "error off the edges", err[~on_edge].max() if (~on_edge).any() else 0.0)
            _count(row, "states on a knife edge", on_edge.sum())
            if on_edge.any():
                _record(row, "error on an edge / (its jump + tolerance)", (err[on_edge] / allowed[on_edge]).max())
            bad = err > allowed
            if bad.any():
                i = int(np.where(bad, err, 0).argmax())
                row.failures.append(f"{p} off the float64 reference by {err[i]:.1e} (allowed {allowed[i]:.1e}): "
                                    f"{case['name']}, {labels[i]}")
    for p, row in rows.items():
        row.notes.append(EDGE_NOTE.format(eps=ROUNDING * EPS[p]))
    return list(rows.values()) + run_threshold(device)


ROUNDING = 64  # the flight's rounding-noise rule (warp_ricochet.flight.ROUNDING): closing speeds within 64 eps |v| are 0
EDGE_NOTE = ("Knife edges, where rounding decides and the law jumps: an approach |v_n| < {eps:.1e} |v| (the impact "
             "happens or not: it changes v_t by up to mu_s N*/m, N* including g_n dt) and k/(1+k)|v_pt| within "
             "rounding of mu_s N* (stick or slip: they differ by (mu_s - mu_d) N*/m); there the allowed error is the jump.")


def knife_edges(case, v, w, scale):
    """Per precision: states whose branch rounding decides (`approach`: |v_n| within ROUNDING eps of
    |v|; `threshold`: the sticking impulse within rounding of mu_s N*) and the law's jump there
    relative to the scale (`jump`)."""
    n, R, E = case["normal"], case["radius"], case["restitution"]
    vn = v @ n
    N = np.maximum(-(1 + E) * vn - np.dot(case["gravity"], n) * case["duration"], 0.0)
    vp = v + np.cross(w, -R * n)
    vpt = np.linalg.norm(vp - np.outer(vp @ n, n), axis=1)
    stick = K / (1 + K) * vpt
    speed = np.linalg.norm(v, axis=1)
    out = {}
    for p, eps in EPS.items():
        approach = np.abs(vn) <= ROUNDING * eps * speed
        threshold = np.abs(stick - case["mu_s"] * N) <= ROUNDING * eps * (stick + case["mu_s"] * N + speed)
        # skipping the impact: the normal change (1 + E)|v_n| and the friction, at most mu_s N* (and R w: / k)
        jump = np.where(approach, (1 + E) * np.abs(vn) + case["mu_s"] * N / K, 0.0)
        jump = jump + np.where(threshold, (case["mu_s"] - case["mu_d"]) * N / K, 0.0)
        out[p] = {"approach": approach, "threshold": threshold, "jump": jump / scale}
    return out


def run_threshold(device="cpu"):
    """Impacts exactly at the stick-slip threshold of eq. (22), k/(1+k) |v_pt| = mu_s N* (float64):
    a knife edge that rounding decides. With mu_d = mu_s the law is continuous there, so float32
    and float64 agree whichever branch they take; with mu_d < mu_s the two branches differ by
    (mu_s - mu_d) N* / m in v_t, and float32 may take the other branch."""
    import warp_ricochet as wr

    rows = []
    n = np.array([0.0, 1.0, 0.0])
    vts = np.geomspace(1e-3, 1e4, 36)
    v = np.stack([vts, -0.7 * vts, np.zeros_like(vts)], axis=1)
    w = np.zeros_like(v)
    E = 0.3
    for mu_ratio in (1.0, 0.9):
        # per state its own threshold; wr.impact takes one mu_s, so one launch per state
        results = {p: [] for p in EPS}
        for i in range(len(v)):
            normal_impulse = (1 + E) * 0.7 * vts[i]
            mu_s = K / (1 + K) * vts[i] / normal_impulse
            for p in EPS:
                results[p].append(wr.impact(v[i:i + 1], w[i:i + 1], n, radius=0.00125, density=7000.0, restitution=E,
                                            mu_s=mu_s, mu_d=mu_ratio * mu_s, gravity=(0, 0, 0), device=device,
                                            precision=p))
        row = Row("impact law", f"exact stick-slip threshold, mu_d = {mu_ratio:g} mu_s", "float32", len(v))
        v32 = np.concatenate([r[0] for r in results["float32"]]).astype(float)
        v64 = np.concatenate([r[0] for r in results["float64"]])
        s32 = np.concatenate([r[2] for r in results["float32"]])
        s64 = np.concatenate([r[2] for r in results["float64"]])
        err = np.abs(v32 - v64).max(axis=1) / np.linalg.norm(v, axis=1)
        _count(row, "branch differs from float64", (s32 != s64).sum())
        _record(row, "float32 error", err.max())
        jump = (1 - mu_ratio) * K / (1 + K)  # (mu_s - mu_d) N* / |v| at the threshold, relative
        limit = F32_TOLERANCE + (jump * 1.5 if mu_ratio < 1 else 0.0)
        if err.max() > limit:
            row.failures.append(f"float32 off float64 by {err.max():.1e} > {limit:.1e}")
        if mu_ratio < 1:
            row.notes.append(f"at the threshold rounding picks the branch: the two differ by (mu_s - mu_d) N*/m "
                             f"= {jump:.3f} |v|; float32 took the other branch in {int((s32 != s64).sum())} of "
                             f"{len(v)} (the code compares k/(1+k)|v_pt| with mu_s N* as eq. 22 does: no tie rule "
                             "can make a discontinuous law agree across precisions)")
        rows.append(row)
    return rows


def _record(row, name, value):
    """The largest value of `name` seen in the row."""
    value = float(value)
    row.measured[name] = max(row.measured.get(name, -math.inf), value)


def _count(row, name, n):
    """How many of `name` in the row, over all its cases."""
    row.measured[name] = row.measured.get(name, 0) + int(n)


# ---------------------------------------------------------------------------------------------- whole pipeline

# pellet kinds relative to the first plane: (height of the centre in R units or m, direction)
KINDS = ("above", "touching, 17 deg in", "on, moving along", "overlapping, moving out", "on, moving straight in",
         "touching, grazing 1e-3", "touching, grazing 1e-7")
EDGE_KINDS = {"touching, grazing 1e-7"}  # |v_n| below float32's rounding rule: float32 may see no impact
GRAZING = {"touching, grazing 1e-3": 1e-3}  # |v_n| / |v|: float32 resolves v_n to eps |v|, so the hop to eps / 1e-3


def pipeline_cases(quick: bool):
    """Scenes of explicit pellets (a pellet file): dict(name, surfaces, gravity, diameter, position,
    velocity, spin, bounces, kind (per pellet), far (the plane's point 1e4 m from the pellets))."""
    rng = np.random.default_rng(7)
    diameters = (1e-4, 2.5e-3, 2e-2)
    speeds = (1e-6, 1e-3, 1.0, 30.0, 1e3, 1e4)
    gravities = list(GRAVITIES)
    planes = {
        "floor": [dict(point=[0, 0, 0], normal=[0, 1, 0])],
        "tilted floor": [dict(point=[0, 0, 0], normal=list(_unit(NORMALS["tilted"])))],
        "floor and vertical wall": [dict(point=[0, 0, 0], normal=[0, 1, 0]), dict(point=[5, 0, 0], normal=[-1, 0, 0])],
        "box of 4 tilted planes": [dict(point=[0, 0, 0], normal=list(_unit([0.1, 1, 0]))),
                                   dict(point=[4, 0, 0], normal=list(_unit([-1, 0.2, 0]))),
                                   dict(point=[-4, 0, 0], normal=list(_unit([1, 0.1, 0.1]))),
                                   dict(point=[0, 0, -3], normal=list(_unit([0, 0.3, 1])))],
    }
    laws = ((0.0, 0.0, 0.0), (0.5, 0.3, 0.25), (1.0, 0.0, 0.0), (0.2, 10.0, 10.0))
    combos = list(itertools.product(diameters, gravities, planes, laws, (False,)))
    if quick:  # every value of every axis, not every combination
        combos = [(diameters[i % 3], gravities[i % 5], list(planes)[(i // 3) % 4], laws[(i // 2) % 4], False)
                  for i in range(12)]
    else:
        combos += [(d, "g -y", "tilted floor", laws[1], True) for d in diameters]
    for d, gname, pname, (E, mu_s, mu_d), far in combos:
        g = np.array(GRAVITIES[gname])
        radius = d / 2
        surfaces = [dict(p, restitution=E, mu_s=mu_s, mu_d=mu_d) for p in planes[pname]]
        n0 = np.array(surfaces[0]["normal"], float)
        t0, _ = _frame(n0)
        origin = np.array(surfaces[0]["point"], float)
        if far:  # the plane's point 1e4 m away along the plane: positions are resolved relative to it
            surfaces[0] = dict(surfaces[0], point=list(origin - 1e4 * t0))
        position, velocity, spin, kinds = [], [], [], []
        for speed in speeds:
            for kind in KINDS:
                height = 1.0 if kind == "above" else 0.4 * radius if kind.startswith("overlapping") else radius
                direction = {"above": _unit(t0 - n0 + 0.1 * rng.normal(size=3)),
                             "touching, 17 deg in": _unit(t0 - 0.3 * n0), "on, moving along": t0,
                             "overlapping, moving out": _unit(t0 + 0.2 * n0), "on, moving straight in": -n0,
                             "touching, grazing 1e-3": _unit(t0 - 1e-3 * n0),
                             "touching, grazing 1e-7": _unit(t0 - 1e-7 * n0)}[kind]
                position.append(origin + height * n0 + rng.uniform(-0.5, 0.5) * t0)
                velocity.append(speed * direction)
                spin.append(np.clip(rng.normal(0.0, speed / radius / 3, 3), -MAX_SPIN, MAX_SPIN))
                kinds.append(kind)
        yield dict(name=f"D {d * 1e3:g} mm, {gname}, {pname}{', point 1e4 m away' if far else ''}, E {E:g}, "
                        f"mu {mu_s:g}/{mu_d:g}", surfaces=surfaces, gravity=g, diameter=d, position=np.array(position),
                   velocity=np.array(velocity), spin=np.array(spin), bounces=3, kind=np.array(kinds), far=far)


def run_pipeline(device="cpu", quick=False, workdir=None):
    """Rows of the pipeline table: each scene in float32 and float64, checked per pellet."""
    import h5py

    import warp_ricochet as wr
    from warp_ricochet.scene import scene_from_dict

    workdir = Path(workdir or tempfile.mkdtemp(prefix="stability-"))
    rows = {p: Row("pipeline", "speeds 1e-6..1e4 m/s, D 0.1..20 mm, planes, gravity, on/touching/in a plane", p, 0)
            for p in EPS}
    far = Row("pipeline", "the plane's point 1e4 m from the pellets (tilted floor, g -y)", "float32", 0)
    for ci, case in enumerate(pipeline_cases(quick)):
        pellet_file = workdir / f"p{ci}.npz"
        np.savez(pellet_file, position=case["position"], velocity=case["velocity"], angular_velocity=case["spin"])
        out = {}
        for p in EPS:
            raw = {"shot": {"file": str(pellet_file), "diameter": case["diameter"], "density": 7000.0},
                   "surfaces": case["surfaces"], "physics": {"gravity": list(case["gravity"]), "bounces": case["bounces"]},
                   "numerics": {"precision": p}}
            path = workdir / f"r{ci}-{p}.h5"
            wr.run(scene_from_dict(raw), path, device=device, overwrite=True)
            with h5py.File(path, "r") as f:
                out[p] = {k.replace("/", "."): v[()] for k, v in _datasets(f["pellets"])}
        for p in EPS:
            _check_pellets(rows[p], case, out[p], p)
        if case["far"]:
            far.n += len(case["position"])
        _compare(far if case["far"] else rows["float32"], case, out["float32"], out["float64"])
    rows["float32"].notes.append(
        f"Grazing contacts with |v_n| below {ROUNDING * EPS['float32']:.1e} |v| ({', '.join(sorted(EDGE_KINDS))}): "
        "float32's rounding rule counts v_n as 0, so the pellet slides/rests on the plane where float64 ricochets "
        "with a hop of about E |v_n|; these pellets are counted, not held to the float32 tolerance. Grazing "
        "contacts with |v_n| = 1e-3 |v|: float32 resolves v_n to eps |v|, so the hop's time and range carry "
        "errors up to eps |v| / |v_n| (held to 1e-5 + 64 eps / 1e-3 = 7.6e-3). Flights "
        f"longer than {LONG_FLIGHT:g} m (1e3 and 1e4 m/s under gravity): positions are resolved to eps |r| "
        "(0.24 m at 4e6 m), so the time and velocity of a later impact on another plane follow that; measured, "
        "not held to the tolerance.")
    out = list(rows.values())
    if far.n:
        far.notes.append("float32 resolves positions to about 64 eps |r - plane point| = 7.6e-2 m here: gaps, "
                         "contacts and short ranges are not resolved; keep plane points near the pellets or use float64.")
        out.append(far)
    return out


def _datasets(group):
    items = []
    group.visititems(lambda name, obj: items.append((name, obj)) if hasattr(obj, "dtype") else None)
    return items


def _started_inside(case, j):
    """Per pellet, how deep (m) it was launched inside plane j (0 if not: a pellet launched inside
    a plane and moving out slowly, without gravity along the normal, stays inside)."""
    R = case["diameter"] / 2
    start = (case["position"] - np.array(case["surfaces"][j]["point"], float)) @ np.array(case["surfaces"][j]["normal"], float)
    return np.where(start >= 0, np.maximum(R - start, 0.0), 0.0)


def _check_pellets(row, case, o, precision):
    """The rules that hold in each precision on its own: finite, no energy gain, not inside a plane,
    no impact at a speed that is rounding residue."""
    eps = EPS[precision]
    R = case["diameter"] / 2
    g = case["gravity"]
    points = np.array([s["point"] for s in case["surfaces"]], float)
    normals = np.array([s["normal"] for s in case["surfaces"]], float)
    row.n += len(case["position"])
    hit = o["impact.surface"] >= 0  # (N, B)
    landed = o["landing.surface"] >= 0
    for name in ("impact.time", "impact.position", "impact.velocity", "impact.angular_velocity",
                 "impact.velocity_before", "impact.angular_velocity_before"):
        if not np.isfinite(o[name][hit]).all():
            row.failures.append(f"non-finite {name}: {case['name']}")
    for name in ("landing.time", "landing.position", "landing.velocity", "landing.range"):
        if not np.isfinite(o[name][landed]).all():
            row.failures.append(f"non-finite {name}: {case['name']}")
    # energy: impacts never add kinetic energy; mechanical energy never rises along the trajectory
    before = kinetic(o["impact.velocity_before"][hit].astype(float), o["impact.angular_velocity_before"][hit].astype(float), R)
    after = kinetic(o["impact.velocity"][hit].astype(float), o["impact.angular_velocity"][hit].astype(float), R)
    if before.size:
        gain = (after - before) / np.maximum(before, 1e-300)
        _record(row, "impact energy gain / (eps E)", gain.max() / eps)
        if gain.max() > ENERGY_ROUNDING * eps:
            row.failures.append(f"impact energy gain {gain.max():.1e}: {case['name']}")
    r0, v0, w0 = case["position"], case["velocity"], case["spin"]
    last = np.where(hit.any(axis=1), hit.shape[1] - 1 - np.argmax(hit[:, ::-1], axis=1), 0)
    w_last = np.where(hit.any(axis=1)[:, None], o["impact.angular_velocity"][np.arange(len(last)), last], w0).astype(float)
    rl, vl = o["landing.position"][landed].astype(float), o["landing.velocity"][landed].astype(float)
    e0 = kinetic(v0[landed], w0[landed], R) - r0[landed] @ g
    e1 = kinetic(vl, w_last[landed], R) - rl @ g
    terms = kinetic(v0[landed], w0[landed], R) + np.abs(r0[landed] @ g) + np.abs(rl @ g) + kinetic(vl, w_last[landed], R)
    if e1.size:
        rise = (e1 - e0) / np.maximum(terms, 1e-300)
        _record(row, "trajectory energy rise / (eps terms)", rise.max() / eps)
        if rise.max() > INSIDE_ROUNDING * eps:
            row.failures.append(f"mechanical energy rose by {rise.max():.1e} of its terms: {case['name']}")
    # at each impact and at the landing the centre is R in front of the plane touched, and a landed
    # pellet is nowhere inside a plane it is in front of, within rounding of the terms that make up
    # the position (r_start - p, v t, g t^2 / 2) and beyond how deep it was launched inside
    inside_at_start = np.stack([_started_inside(case, j) for j in range(len(points))], axis=1)
    for b in range(hit.shape[1] + 1):
        if b < hit.shape[1]:
            k, m = o["impact.surface"][:, b], hit[:, b]
            pos = o["impact.position"][:, b].astype(float)
        else:
            k, m = o["landing.surface"], landed
            pos = o["landing.position"].astype(float)
        if not m.any():
            continue
        terms = flight_terms(case, o, b)[m]
        offset = pos[m] - points[k[m]]
        scale = terms + np.abs(offset).sum(axis=1) + R
        gap = np.einsum("ij,ij->i", offset, normals[k[m]]) - R
        started = inside_at_start[m, k[m]]
        off = np.maximum(gap, np.maximum(-gap - started, 0.0)) / scale
        what = "impacts" if b < hit.shape[1] else "landing"
        _record(row, f"|gap - R| at {what} / (eps scale)", off.max() / eps)
        if off.max() > INSIDE_ROUNDING * eps:
            row.failures.append(f"centre {off.max():.1e} of its scale off the plane at {what}: {case['name']}")
        if b == hit.shape[1]:
            for j in range(len(points)):
                offset = pos[m] - points[j]
                height = offset @ normals[j]
                inside = np.where(height >= 0, R - height - inside_at_start[m, j], -np.inf) / scale
                _record(row, "overlap at landing / (eps scale)", max(inside.max() / eps, 0.0))
                if inside.max() > INSIDE_ROUNDING * eps:
                    row.failures.append(f"landed {inside.max():.1e} of its scale inside plane {j}: {case['name']}")
    # rounding decides nothing: no second impact or escape decided on a velocity that is residue
    residue = _residue_decisions(case, o, precision)
    _count(row, "decisions on a residue velocity", residue.sum())
    if residue.any():
        i = int(np.argmax(residue))
        row.known.append(f"{int(residue.sum())} pellets impacted again or escaped on a residue velocity after an "
                         f"E = 0 impact ({case['kind'][i]}): {case['name']}")


def flight_terms(case, o, b):
    """Per pellet, the size of the terms of the flight that ends at impact b (b = bounces: the
    landing): |r_start| + |v_start| t + |g| t^2 / 2, from the launch or the previous impact."""
    if b == 0:
        r, v, t0 = case["position"], case["velocity"], np.zeros(len(case["position"]))
    else:
        r = np.nan_to_num(o["impact.position"][:, b - 1].astype(float))
        v = np.nan_to_num(o["impact.velocity"][:, b - 1].astype(float))
        t0 = np.nan_to_num(o["impact.time"][:, b - 1].astype(float))
        none = o["impact.surface"][:, b - 1] < 0  # no impact b-1: the flight started earlier
        if none.any():
            earlier = flight_terms(case, o, b - 1)
            return np.where(none, earlier, _terms(r, v, case["gravity"], t0, o, b))
    return _terms(r, v, case["gravity"], t0, o, b)


def _terms(r, v, g, t0, o, b):
    end = o["impact.time"][:, b] if b < o["impact.time"].shape[1] else o["landing.time"]
    t = np.nan_to_num(np.where(np.isfinite(end), end.astype(float) - t0, 0.0))
    return np.abs(r).sum(axis=1) + np.abs(v).sum(axis=1) * t + 0.5 * np.abs(g).sum() * t * t


def _speed_scale(case, o):
    """Per pellet, the fastest it goes: launch, before any impact, R w."""
    before = np.linalg.norm(np.nan_to_num(o["impact.velocity_before"].astype(float)), axis=2).max(axis=1)
    return np.maximum.reduce([before, np.linalg.norm(case["velocity"], axis=1),
                              0.5 * case["diameter"] * np.linalg.norm(case["spin"], axis=1)])


def _residue_decisions(case, o, precision):
    """Per pellet: a decision taken on a velocity that is rounding residue. After an E = 0 impact at
    normal incidence the velocity is such residue (below ROUNDING eps of the speed before); the
    kernels test whether it leaves or closes against its own size, so rounding decides whether the
    pellet rests (as it should), impacts the same plane again at once, or escapes (flies off with
    ~1e-16 m/s, never to land: counted as escaped, range NaN)."""
    k = o["impact.surface"]
    t = o["impact.time"].astype(float)
    before = np.linalg.norm(np.nan_to_num(o["impact.velocity_before"].astype(float)), axis=2)
    after = np.linalg.norm(np.nan_to_num(o["impact.velocity"].astype(float)), axis=2)
    residue = (k >= 0) & (after <= ROUNDING * EPS[precision] * before)  # the impact left residue
    again = (k[:, 1:] >= 0) & (k[:, 1:] == k[:, :-1]) & (t[:, 1:] == t[:, :-1]) & residue[:, :-1]
    last = np.where((k >= 0).any(axis=1), k.shape[1] - 1 - np.argmax((k >= 0)[:, ::-1], axis=1), 0)
    escaped = (o["landing.surface"] < 0) & residue[np.arange(len(last)), last]
    return again.any(axis=1) | escaped


LONG_FLIGHT = 1e4  # m: beyond this extent float32 resolves positions to worse than a millimetre


def _knife_edge_divergence(case, a, b):
    """Per pellet: float32 (a) and float64 (b) part ways at a contact that rounding decides: at the
    first bounce where their surfaces or branches differ, one of them met the plane with a normal
    speed within ROUNDING eps32 of the pellet's speed (it rested where the other ricocheted, or the
    reverse), or took the stick/slip branch with the sticking impulse within rounding of mu_s N*."""
    B = a["impact.surface"].shape[1]
    differ = (a["impact.surface"] != b["impact.surface"]) | (a["impact.slipped"] != b["impact.slipped"])
    first = np.where(differ.any(axis=1), np.argmax(differ, axis=1), B)
    normals = np.array([s["normal"] for s in case["surfaces"]], float)
    scale = _speed_scale(case, b)
    out = np.zeros(len(first), bool)
    for i in np.where(first < B)[0]:
        j = first[i]
        for o in (a, b):
            k = o["impact.surface"][i, j]
            if k < 0:  # rested or escaped here: decided by the normal speed at the contact
                vn = 0.0
            else:
                vn = float(np.dot(o["impact.velocity_before"][i, j], normals[k]))
            if abs(vn) <= 4 * ROUNDING * EPS["float32"] * scale[i]:
                out[i] = True
        out[i] |= (a["impact.surface"][i, j] == b["impact.surface"][i, j])  # same plane, other branch: eq. 22's edge
    # the same impacts, but one meets the next plane at once where the other hops first: the gap to
    # it was below float32's touching rule (64 eps of the distance to the plane's point), e.g. in a corner
    points = np.array([s["point"] for s in case["surfaces"]], float)
    R = case["diameter"] / 2
    ta, tb = np.nan_to_num(a["impact.time"].astype(float)), np.nan_to_num(b["impact.time"].astype(float))
    for j in range(1, B):
        k = b["impact.surface"][:, j]
        at_once = (ta[:, j] == ta[:, j - 1]) != (tb[:, j] == tb[:, j - 1])
        offset = np.nan_to_num(b["impact.position"][:, j - 1].astype(float)) - points[np.maximum(k, 0)]
        gap = np.abs(np.einsum("ij,ij->i", offset, normals[np.maximum(k, 0)]) - R)
        out |= (first == B) & (k >= 0) & at_once & (gap <= 4 * ROUNDING * EPS["float32"] * (np.abs(offset).sum(axis=1) + R))
    # the same impacts, then one rests on the last plane and the other hops: the leaving speed decided
    hit = b["impact.surface"] >= 0
    last = np.where(hit.any(axis=1), B - 1 - np.argmax(hit[:, ::-1], axis=1), 0)
    rows = np.arange(len(last))
    rested = [np.nan_to_num(o["landing.time"].astype(float)) == np.nan_to_num(o["impact.time"][rows, last].astype(float))
              for o in (a, b)]
    # (on the plane just hit or on another it touches, e.g. the floor of a corner), or a gap to
    # another plane below float32's touching rule (64 eps of the distance to the plane's point)
    leaving = np.abs(np.nan_to_num(b["impact.velocity"][rows, last]) @ normals.T).min(axis=1)
    offset = np.nan_to_num(b["impact.position"][rows, last].astype(float))[:, None, :] - points[None]
    gap = np.abs(np.einsum("ijk,jk->ij", offset, normals) - case["diameter"] / 2)
    touching = (gap <= 4 * ROUNDING * EPS["float32"] * (np.abs(offset).sum(axis=2) + case["diameter"] / 2)).any(axis=1)
    decided = (leaving <= 4 * ROUNDING * EPS["float32"] * scale) | touching
    out |= (first == B) & hit.any(axis=1) & (rested[0] != rested[1]) & decided
    return out


def _compare(row, case, a, b):
    """float32 (a) against float64 (b): the same outcomes (surfaces, branches) and, per pellet, values
    within F32_TOLERANCE of the pellet's own scale, except for pellets that part ways at a knife edge,
    ill-conditioned grazing hops, flights longer than LONG_FLIGHT and the far case (measured only)."""
    same = (a["impact.surface"] == b["impact.surface"]).all(axis=1) & (a["landing.surface"] == b["landing.surface"])
    same &= (a["impact.slipped"] == b["impact.slipped"]).all(axis=1)
    by_kind = np.isin(case["kind"], list(EDGE_KINDS))
    edge = by_kind | _knife_edge_divergence(case, a, b)
    residue = _residue_decisions(case, a, "float32") | _residue_decisions(case, b, "float64")
    edge |= residue  # the known defect: counted in its own rule
    terms = flight_terms(case, b, b["impact.surface"].shape[1])
    extent = np.maximum(np.nan_to_num(terms), np.abs(case["position"]).sum(axis=1))
    long = extent > LONG_FLIGHT
    grazing = np.array([GRAZING.get(k, 1.0) for k in case["kind"]])  # |v_n| / |v| at the first contact
    strict = ~edge & ~long & (not case["far"])
    _count(row, "outcome differs: grazing 1e-7", (~same & by_kind).sum())
    _count(row, "outcome differs: other knife edges", (~same & edge & ~by_kind).sum())
    _count(row, "outcome differs: elsewhere", (~same & ~edge).sum())
    if (~same & strict).any():
        kinds = sorted(set(case["kind"][~same & strict]))
        row.failures.append(f"float32 outcome differs from float64 for {int((~same & strict).sum())} pellets "
                            f"({', '.join(kinds)}): {case['name']}")
    # scales: the pellet's fastest speed for velocities, the flight's terms for ranges (a difference of
    # two positions, each rounded to eps of them), the time for times
    times = np.nan_to_num(np.abs(b["landing.time"]), posinf=0.0) + 1e-9
    for name, scale in (("impact.velocity", _speed_scale(case, b)), ("landing.range", extent + 1e-9),
                        ("landing.time", times)):
        x, y = a[name].astype(float), b[name]
        with np.errstate(invalid="ignore"):
            diff = np.abs(np.where(np.isfinite(y), x - y, 0.0)).reshape(len(y), -1).max(axis=1)
        err = np.where(same & ~edge, diff / scale, 0.0)
        bands = ((("", strict & (grazing == 1)), (" (grazing 1e-3)", strict & (grazing < 1)),
                  (" (flights > 1e4 m)", long & same & ~edge)) if not case["far"] else (("", same & ~edge),))
        for band, mask in bands:
            if mask.any():
                _record(row, f"float32 {name} error{band}", err[mask].max())
        # ill-conditioned grazing hops: v_n is resolved to eps |v|, so relative errors grow as |v| / |v_n|
        allowed = F32_TOLERANCE + ROUNDING * EPS["float32"] / grazing
        if (err[strict] > allowed[strict]).any():
            i = int(np.where(strict, err - allowed, -1).argmax())
            row.failures.append(f"float32 {name} off float64 by {err[i]:.1e} ({case['kind'][i]}, "
                                f"{np.linalg.norm(case['velocity'][i]):g} m/s): {case['name']}")


# ---------------------------------------------------------------------------------------------- table

def table(rows) -> str:
    lines = ["| group | cases | precision | n | held | largest measured | notes |", "|---|---|---|---:|---|---|---|"]
    for r in rows:
        measured = "; ".join(f"{k} {int(v) if v == int(v) and abs(v) >= 1 else f'{v:.3g}'}" for k, v in r.measured.items())
        held = "yes" if r.held else "NO: " + "; ".join(r.failures[:3]) + (f" (+{len(r.failures) - 3})" if len(r.failures) > 3 else "")
        if r.known:
            held += f"; known defect in {len(r.known)} scenes (docs/stability.md), e.g. {r.known[0]}"
        lines.append(f"| {r.group} | {r.case} | {r.precision} | {r.n} | {held} | {measured} | {' '.join(r.notes)} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--quick", action="store_true", help="the CI subset")
    args = ap.parse_args(argv)
    rows = run_impact_law(args.device, args.quick) + run_pipeline(args.device, args.quick)
    print(f"device {args.device}; limits: energy {ENERGY_ROUNDING} eps, inside {INSIDE_ROUNDING} eps of the scale, "
          f"float32 {F32_TOLERANCE:g}, float64 {F64_TOLERANCE:g}")
    print(table(rows))
    return 0 if all(r.held for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
