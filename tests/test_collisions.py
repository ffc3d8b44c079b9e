"""Pellet-pellet collisions: the Warp pair law against the float64 reference, the time-stepped dense
phase against the event-driven reference, conservation, isolation of shots, determinism, output."""

import dataclasses

import h5py
import numpy as np
import pytest
import warp as wp
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.helpers import GROUND, make_scene, paper_raw
from warp_ricochet import api
from warp_ricochet.dense.phase import DenseOptions
from warp_ricochet.errors import ChaosWarning, PrecisionWarning
from warp_ricochet.physics.pair import make_pair_law
from warp_ricochet.reference.collisions import pair_law as reference_pair_law
from warp_ricochet.reference.collisions import simulate_collisions
from warp_ricochet.scene import COLLISION_FIELDS

wp.config.log_level = wp.LOG_WARNING

_pair_law64 = make_pair_law("float64")


@wp.kernel(enable_backward=False)
def _pair_kernel(
    xa: wp.array(dtype=wp.vec3d),
    va: wp.array(dtype=wp.vec3d),
    wa: wp.array(dtype=wp.vec3d),
    xb: wp.array(dtype=wp.vec3d),
    vb: wp.array(dtype=wp.vec3d),
    wb: wp.array(dtype=wp.vec3d),
    radius: wp.float64,
    mass_a: wp.float64,
    mass_b: wp.float64,
    restitution: wp.float64,
    mu_s: wp.float64,
    mu_d: wp.float64,
    va_out: wp.array(dtype=wp.vec3d),
    wa_out: wp.array(dtype=wp.vec3d),
    vb_out: wp.array(dtype=wp.vec3d),
    wb_out: wp.array(dtype=wp.vec3d),
):
    i = wp.tid()
    a, b, c, d, _collided, _slipped = _pair_law64(
        xa[i],
        va[i],
        wa[i],
        radius,
        mass_a,
        xb[i],
        vb[i],
        wb[i],
        radius,
        mass_b,
        wp.float64(0.4),
        restitution,
        mu_s,
        mu_d,
    )
    va_out[i] = a
    wa_out[i] = b
    vb_out[i] = c
    wb_out[i] = d


def warp_pair_law(xa, va, wa, xb, vb, wb, *, radius, mass_a, mass_b, restitution, mu_s, mu_d):
    arrays = [wp.array(np.asarray(a, np.float64), dtype=wp.vec3d, device="cpu") for a in (xa, va, wa, xb, vb, wb)]
    outs = [wp.empty(len(xa), dtype=wp.vec3d, device="cpu") for _ in range(4)]
    wp.launch(
        _pair_kernel, dim=len(xa), inputs=[*arrays, radius, mass_a, mass_b, restitution, mu_s, mu_d], outputs=outs, device="cpu"
    )
    return [o.numpy() for o in outs]


vectors = st.lists(st.floats(-50, 50), min_size=3, max_size=3)


@settings(max_examples=60, deadline=None)
@given(
    va=vectors,
    vb=vectors,
    wa=vectors,
    wb=vectors,
    direction=vectors,
    overlap=st.floats(0.7, 1.0),
    restitution=st.floats(0, 1),
    mu_s=st.floats(0, 2),
    ratio=st.floats(0, 1),
    mass_ratio=st.floats(0.2, 5),
)
def test_pair_law_matches_the_float64_reference(va, vb, wa, wb, direction, overlap, restitution, mu_s, ratio, mass_ratio):
    d = np.asarray(direction)
    if np.linalg.norm(d) < 1e-3:
        d = np.array([1.0, 0.0, 0.0])
    radius = 0.00125
    xa = np.zeros((1, 3))
    xb = (d / np.linalg.norm(d) * 2 * radius * overlap)[None]
    w_scale = 1e4  # rad/s: spins comparable to speeds / radius
    args = dict(radius=radius, mass_a=1e-4, mass_b=1e-4 * mass_ratio, restitution=restitution, mu_s=mu_s, mu_d=mu_s * ratio)
    got = warp_pair_law(xa, [va], np.asarray([wa]) * w_scale, xb, [vb], np.asarray([wb]) * w_scale, **args)
    ref = reference_pair_law(
        xa,
        np.asarray([va]),
        np.asarray([wa]) * w_scale,
        xb,
        np.asarray([vb]),
        np.asarray([wb]) * w_scale,
        mass_a=args["mass_a"],
        mass_b=args["mass_b"],
        radius_a=radius,
        radius_b=radius,
        restitution=restitution,
        mu_s=mu_s,
        mu_d=mu_s * ratio,
    )
    expected = [ref.velocity_a, ref.angular_velocity_a, ref.velocity_b, ref.angular_velocity_b]
    for g, e, scale in zip(got, expected, (1.0, 1 / radius, 1.0, 1 / radius)):
        np.testing.assert_allclose(g, e, rtol=1e-9, atol=1e-9 * 100 * scale)
    # momentum conserved, energy never rises
    ma, mb = args["mass_a"], args["mass_b"]
    np.testing.assert_allclose(ma * got[0] + mb * got[2], ma * np.asarray([va]) + mb * np.asarray([vb]), atol=1e-15)
    inertia_a, inertia_b = 0.4 * ma * radius**2, 0.4 * mb * radius**2
    before = ma * np.dot(va, va) + mb * np.dot(vb, vb) + (inertia_a * np.dot(wa, wa) + inertia_b * np.dot(wb, wb)) * w_scale**2
    after = (
        ma * np.sum(got[0] ** 2) + mb * np.sum(got[2] ** 2) + inertia_a * np.sum(got[1] ** 2) + inertia_b * np.sum(got[3] ** 2)
    )
    assert after <= before * (1 + 1e-12) + 1e-18


def _paper_collisions(count=120, precision="float64", shots=1, **collisions):
    raw = paper_raw()
    raw["shot"]["count"] = count
    raw["shot"]["shots"] = shots
    # these tests are about the dense phase on the paper's clouds as they were sampled: pellets may
    # overlap at launch (test_launch_overlaps.py tests the separated launch)
    raw["collisions"] = {"enabled": True, "separate": False, **collisions}
    return make_scene(raw, precision=precision)


def _write(scene, path, device="cpu", options=None):
    api.run(scene, output=str(path), device=device, dense_options=options)
    with h5py.File(path, "r") as f:
        pellets = {name: f[f"pellets/{name.replace('.', '/')}"][()] for name in scene.output.fields}
        stats = {k: ds[()] for k, ds in f["stats"].items() if isinstance(ds, h5py.Dataset)}
    return pellets, stats


def test_a_cloud_too_sparse_to_touch_gives_the_collisions_off_result(tmp_path, device):
    raw = paper_raw()
    raw["shot"].update(count=200, envelope_radius=20.0)  # pellets metres apart: no pair can meet
    off = make_scene(raw, precision="float64")
    raw["collisions"] = {"enabled": True}
    on = make_scene(raw, precision="float64")
    pellets_off, stats_off = _write(off, tmp_path / "off.h5", device)
    pellets_on, stats_on = _write(on, tmp_path / "on.h5", device)
    for name, value in pellets_off.items():
        np.testing.assert_array_equal(pellets_on[name], value, err_msg=name)  # bitwise, pellet by pellet
    assert stats_on["collided_fraction"] == 0.0 and stats_on["pair_energy_lost"] == 0.0
    for key in ("range_mean", "range_max", "range_min", "post_mean_vt", "range_std"):
        assert stats_on[key] == pytest.approx(stats_off[key], rel=1e-13, abs=1e-12)


def _two_pellets(tmp_path, position, velocity, spin=None, surfaces=(), gravity=(0.0, -9.81, 0.0), **collisions):
    path = tmp_path / "two.npz"
    np.savez(
        path,
        position=np.asarray(position, float),
        velocity=np.asarray(velocity, float),
        angular_velocity=np.zeros((len(position), 3)) if spin is None else np.asarray(spin, float),
    )
    raw = {
        "shot": {"file": str(path), "diameter": 0.0025, "density": 7000.0},
        "surfaces": list(surfaces),
        "physics": {"gravity": list(gravity), "bounces": 1},
        "collisions": {"enabled": True, **collisions},
        "numerics": {"precision": "float64"},
    }
    return make_scene(raw, precision="float64")


@pytest.mark.parametrize("spin", [False, True])
@pytest.mark.parametrize("oblique", [0.0, 0.6])
def test_two_pellets_against_the_event_driven_reference(tmp_path, device, spin, oblique):
    """Head-on and oblique, with and without spin: the pair collision mid-air, then the ground."""
    d = 0.0025
    position = [[0.0, 1.0, 0.0], [0.05, 1.0 + oblique * d, 0.0]]
    velocity = [[20.0, -5.0, 0.0], [-20.0, -5.0, 0.0]]
    spins = [[0.0, 0.0, 3000.0], [500.0, 0.0, -2000.0]] if spin else None
    scene = _two_pellets(tmp_path, position, velocity, spins, surfaces=[GROUND], restitution=0.8, mu_s=0.3, mu_d=0.2)
    pellets, stats = _write(scene, tmp_path / "two.h5", device)
    ref, ref_stats = simulate_collisions(
        scene, np.asarray(position), np.asarray(velocity), np.zeros((2, 3)) if spins is None else np.asarray(spins)
    )
    assert list(pellets["collisions.count"]) == list(ref["collisions.count"]) == [1, 1]
    np.testing.assert_allclose(pellets["collisions.last_time"], ref["collisions.last_time"], rtol=1e-12)
    for name in ("impact.velocity_before", "impact.velocity", "impact.angular_velocity", "landing.position", "landing.range"):
        np.testing.assert_allclose(pellets[name], ref[name], rtol=1e-9, atol=1e-9, err_msg=name)
    assert stats["pair_energy_lost"] == pytest.approx(ref_stats["pair_energy_lost"], rel=1e-9)


def test_dense_cloud_against_the_event_driven_reference(tmp_path, device):
    """A dense shot (60 pellets in the paper's envelope, 13 pair collisions): the time-stepped
    solver against the exact event-driven one, pellet by pellet. (Denser shots are chaotic: one
    event taken in another order changes everything after it; docs/collisions.md.)"""
    scene = _paper_collisions(60)
    pellets, stats = _write(scene, tmp_path / "dense.h5", device)
    ref, ref_stats = simulate_collisions(
        scene, pellets["initial.position"], pellets["initial.velocity"], pellets["initial.angular_velocity"]
    )
    assert stats["pair_collisions"] == ref_stats["pair_collisions"] >= 10
    assert stats["skin_overrun_max"] == 0.0  # no pellet left its skin between list builds
    np.testing.assert_array_equal(pellets["collisions.count"], ref["collisions.count"])
    np.testing.assert_allclose(pellets["landing.range"], ref["landing.range"], rtol=1e-9)
    assert stats["pair_energy_lost"] == pytest.approx(ref_stats["pair_energy_lost"], rel=1e-9)


def test_shots_only_meet_their_own_pellets(tmp_path, device):
    """Two shots occupying the same space: each gives what it gives alone."""
    rng = np.random.default_rng(3)
    position = np.array([0.0, 1.0, 0.0]) + rng.uniform(-0.01, 0.01, (30, 3))
    velocity = np.array([300.0, -300.0, 0.0]) + rng.uniform(-30, 30, (30, 3))
    alone = _two_pellets(tmp_path, position, velocity, surfaces=[GROUND])
    pellets_alone, _ = _write(alone, tmp_path / "alone.h5", device)
    assert pellets_alone["collisions.count"].sum() > 0
    path = tmp_path / "twice.npz"
    np.savez(path, position=np.concatenate([position, position]), velocity=np.concatenate([velocity, velocity]))
    raw = alone.to_dict()
    raw["shot"] = {"file": str(path), "diameter": 0.0025, "density": 7000.0, "shots": 2}
    twice = make_scene(raw, precision="float64")
    pellets_twice, _ = _write(twice, tmp_path / "twice.h5", device)
    for name, value in pellets_alone.items():
        np.testing.assert_array_equal(pellets_twice[name][:30], value, err_msg=name)
        np.testing.assert_array_equal(pellets_twice[name][30:], value, err_msg=name)


def test_same_results_run_after_run(tmp_path, device):
    """Same seed, same device: bitwise the same pellets and statistics in a second run (on CUDA
    too, where atomics could reorder). Chunk-size invariance needs more shots than fit one chunk
    (65,536 slots): test_resume_collisions.py runs one chunk against three."""
    scene = _paper_collisions(count=40, shots=5, precision="float32")
    (p0, s0), (p1, s1) = (_write(scene, tmp_path / f"r{k}.h5", device) for k in range(2))
    assert s0["pair_collisions"] > 0
    for name in p0:
        np.testing.assert_array_equal(p1[name], p0[name], err_msg=name)
    assert s1 == s0


def test_free_cloud_conserves_momentum_and_loses_energy_only_in_collisions(device):
    """No surfaces: the dense phase alone, a cloud dense enough that its lists must grow. Linear
    momentum (less M g t) and angular momentum about the centre of mass (gravity has no torque
    about it) are conserved; the kinetic energy lost equals the sum of the pair losses."""
    from warp_ricochet.dense.phase import DensePhase
    from warp_ricochet.launch.source import PelletSource
    from warp_ricochet.model import Model, State
    from warp_ricochet.spec import RunSpec

    raw = paper_raw()
    raw["shot"].update(count=80, envelope_radius=0.006, direction_jitter=[0.3, 0.3, 0.3])
    raw["surfaces"] = []
    raw["collisions"] = {"enabled": True, "restitution": 0.5, "mu_s": 0.5, "mu_d": 0.4, "separate": False}
    scene = make_scene(raw, precision="float64")
    model = Model.from_scene(scene, wp.get_device(device))
    state = State(model, 80, ("initial.position",))
    dense = DensePhase(model, scene, dataclasses.replace(RunSpec.of(scene), fields=("initial.position",)), 80)
    dense.run(0, 1, PelletSource(scene, "float64", model.device, 80).struct, state.outputs)
    c = dense.cloud
    assert c.lists.neighbours.shape[1] > 32  # grew
    g = np.asarray(scene.physics.gravity)
    now = float(c.clock.time.numpy()[0])
    age = (now - c.state.time.numpy())[:, None]
    x = c.state.position.numpy() + c.state.velocity.numpy() * age + 0.5 * g * age**2
    v = c.state.velocity.numpy() + g * age
    w = c.state.angular_velocity.numpy()
    x0, v0, w0 = (
        state.arrays["initial.position"].numpy(),
        c.state.launch_velocity.numpy(),
        c.state.launch_angular_velocity.numpy(),
    )
    assert c.collisions.count.numpy().sum() > 20
    m, inertia = model.mass, model.inertia
    np.testing.assert_allclose(v.sum(0), v0.sum(0) + len(v) * g * now, rtol=0, atol=1e-10 * np.abs(v0).sum())

    def angular_momentum(pos, vel, spin):
        return m * np.cross(pos - pos.mean(0), vel - vel.mean(0)).sum(0) + inertia * spin.sum(0)

    scale = m * np.abs(x0 - x0.mean(0)).max() * np.abs(v0).max() * len(v0)
    np.testing.assert_allclose(angular_momentum(x, v, w), angular_momentum(x0, v0, w0), rtol=0, atol=1e-10 * scale)
    lost = c.collisions.energy_lost.numpy().sum()
    assert lost > 0

    def energy(vel, spin):
        return 0.5 * m * (vel**2).sum() + 0.5 * inertia * (spin**2).sum()

    work = len(v) * m * (g @ (v0.mean(0) * now + 0.5 * g * now**2))  # gravity's work on the centre of mass
    assert energy(v, w) == pytest.approx(energy(v0, w0) + work - lost, rel=1e-10)
    # no pair ends closer than contact, unless it was sampled overlapping (it then only separates)
    d = np.linalg.norm(x[:, None] - x[None], axis=2) + np.eye(len(x))
    d0 = np.linalg.norm(x0[:, None] - x0[None], axis=2) + np.eye(len(x))
    assert np.all(d >= np.minimum(0.0025, d0) * (1 - 1e-9))


def test_energy_never_rises_and_no_pellet_ends_inside_a_plane(tmp_path, device):
    """The cloud's books, launch to release: mechanical energy at launch = at release + pair losses
    + plane-impact losses (each impact before release, from its recorded velocities), every loss
    >= 0; and no centre ends below the ground."""
    from warp_ricochet.model import Model

    scene = _paper_collisions(120, restitution=0.3)
    pellets, stats = _write(scene, tmp_path / "e.h5", device)
    model = Model.from_scene(scene, wp.get_device("cpu"))
    m, inertia, g = model.mass, model.inertia, 9.81

    def energy(v, w, y):
        return 0.5 * m * np.sum(v**2, axis=-1) + 0.5 * inertia * np.sum(w**2, axis=-1) + m * g * y

    launch = energy(pellets["initial.velocity"], pellets["initial.angular_velocity"], pellets["initial.position"][:, 1])
    release = energy(pellets["release.velocity"], pellets["release.angular_velocity"], pellets["release.position"][:, 1])
    before = pellets["impact.time"] <= pellets["release.time"][:, None]  # (NaN: no impact, False)
    plane_losses = (
        energy(pellets["impact.velocity_before"], pellets["impact.angular_velocity_before"], 0.0)
        - energy(pellets["impact.velocity"], pellets["impact.angular_velocity"], 0.0)
    )[before]
    assert before.any() and stats["pair_energy_lost"] > 0
    assert plane_losses.min() >= -1e-12 * launch.max()
    books = launch.sum() - release.sum() - stats["pair_energy_lost"] - plane_losses.sum()
    assert abs(books) <= 1e-10 * launch.sum()
    landed = np.isfinite(pellets["landing.position"][:, 1])
    assert np.all(pellets["landing.position"][landed, 1] >= 0.00125 - 1e-9)


def test_h5md_frames(tmp_path):
    scene = _paper_collisions(30, frame_every=8)
    path = tmp_path / "frames.h5"
    api.run(scene, output=str(path), device="cpu")
    with h5py.File(path, "r") as f:
        assert list(f["h5md"].attrs["version"]) == [1, 1]
        pos = f["particles/pellets/position"]
        assert pos["value"].shape[1:] == (30, 3) and pos["value"].shape[0] == pos["step"].shape[0] == pos["time"].shape[0] > 1
        assert pos["value"].attrs["unit"] == "m" and pos["time"].attrs["unit"] == "s"
        assert np.all(np.diff(pos["step"][()]) == 8) and np.all(np.diff(pos["time"][()]) > 0)
        np.testing.assert_allclose(pos["value"][0], f["pellets/initial/position"][()], atol=1e-12)


def test_no_object_is_created_once_the_file_is_readable_while_written(tmp_path, monkeypatch):
    """A run file goes SWMR (readable while written) once every object exists: SWMR writers may
    not create objects. The H5MD frames' groups and datasets were created after the switch."""
    created_in_swmr = []
    for name in ("create_group", "create_dataset", "require_group", "require_dataset"):
        original = getattr(h5py.Group, name)

        def checked(self, *a, _original=original, _name=name, **k):
            path = a[0] if a else k.get("name")
            if self.file.swmr_mode and (_name.startswith("create") or path not in self):  # (require_*: a new one)
                created_in_swmr.append((_name, path))
            return _original(self, *a, **k)

        monkeypatch.setattr(h5py.Group, name, checked)
    api.run(_paper_collisions(30, frame_every=8), output=str(tmp_path / "frames.h5"), device="cpu")
    with h5py.File(tmp_path / "frames.h5", "r") as f:
        assert f["particles/pellets/position/step"].shape[0] > 1
    assert created_in_swmr == []


def test_collision_fields_need_collisions():
    from warp_ricochet.errors import SceneError

    raw = paper_raw()
    raw["output"] = {"fields": ["release"]}
    with pytest.raises(SceneError, match="output.fields.*collisions.enabled"):
        make_scene(raw)
    # one pellet per shot: nothing to meet, no dense phase (it used to end in a KeyError traceback)
    raw["shot"].update(count=1, shots=3)
    raw["collisions"] = {"enabled": True}
    with pytest.raises(SceneError, match="output.fields.*shot.count > 1"):
        make_scene(raw)
    raw.pop("output")
    assert not any(f in make_scene(raw).output.fields for f in COLLISION_FIELDS)


def test_no_tunnelling_with_a_step_far_beyond_the_pellet_size(tmp_path, device):
    """Head-on at 1e3 m/s closing speed with a fixed step of 1 ms (0.5 m of relative travel per
    step, 200 diameters): the contact time is exact, so the pair still collides, at the right time."""
    position = [[0.0, 1.0, 0.0], [0.3, 1.0, 0.0]]
    velocity = [[500.0, 0.0, 0.0], [-500.0, 0.0, 0.0]]
    scene = _two_pellets(tmp_path, position, velocity, surfaces=[GROUND], time_step=1e-3, restitution=0.5)
    pellets, _ = _write(scene, tmp_path / "fast.h5", device)
    ref, _ = simulate_collisions(scene, np.asarray(position), np.asarray(velocity), np.zeros((2, 3)))
    assert list(pellets["collisions.count"]) == [1, 1]
    np.testing.assert_allclose(pellets["collisions.last_time"], (0.3 - 0.0025) / 1000.0, rtol=1e-12)
    np.testing.assert_allclose(pellets["landing.position"], ref["landing.position"], rtol=1e-9, atol=1e-9)


def test_a_rebound_faster_than_the_step_allowed_for_ends_the_step_at_the_skin(tmp_path, device):
    """Pellets moving together (nothing moves relative to the shot: the longest step) straight
    down onto an elastic ground: the lower one rebounds into the one above, which was beyond the
    lists' reach. The step could not foresee the rebound's speed: it ends where the rebounding
    pellet would leave its skin, the lists are rebuilt, and the pair meets as in the event-driven
    reference (before, the rebound flew through the pellet above)."""
    position = [[0.0, 0.01, 0.0], [0.0, 0.02, 0.0], [0.05, 0.01, 0.0]]
    velocity = [[0.0, -10.0, 0.0]] * 3
    elastic = {**GROUND, "restitution": 1.0, "mu_s": 0.0, "mu_d": 0.0}
    scene = _two_pellets(tmp_path, position, velocity, surfaces=[elastic], gravity=(0.0, 0.0, 0.0), restitution=0.5)
    pellets, stats = _write(scene, tmp_path / "rebound.h5", device)
    ref, ref_stats = simulate_collisions(scene, np.asarray(position), np.asarray(velocity), np.zeros((3, 3)))
    assert list(pellets["collisions.count"]) == list(ref["collisions.count"]) == [1, 1, 0]
    np.testing.assert_allclose(pellets["collisions.last_time"][:2], ref["collisions.last_time"][:2], rtol=1e-12)
    assert stats["skin_overrun_max"] <= 1.0 + 1e-9


def test_a_pellet_found_beyond_its_skin_is_reported(tmp_path, device, monkeypatch):
    """The check before each step measures how far each pellet has moved since its list was
    built: a pellet found beyond half the skin (planted here by moving its build point) is
    reported in the statistics and in a one-line warning, and the lists are rebuilt."""
    from warp_ricochet.dense.phase import DensePhase

    block = DensePhase._block
    planted = []

    def plant(self, commands):
        if not planted:
            offsets = self.cloud.lists.build_offset.numpy().copy()
            offsets[0, 0] += 3.0 * float(self.cloud.lists.half_skin.numpy()[0])
            self.cloud.lists.build_offset.assign(offsets)
            planted.append(True)
        block(self, commands)

    monkeypatch.setattr(DensePhase, "_block", plant)
    scene = _paper_collisions(count=60)
    with pytest.warns(PrecisionWarning, match="half skins between neighbour-list builds"):
        stats = api.run(scene, device=device, dense_options=DenseOptions(cpu_steps="block"))  # (a _block a block)
    assert 2.9 < stats["skin_overrun_max"] < 3.1


def test_a_pellet_pressed_between_the_ground_and_another_ends(tmp_path, device):
    """E = 0 between pellets, one pellet falling onto another that rests just above the ground:
    the lower one is driven into the plane, rebounds, meets the upper one again (TC model keeps
    that from collapsing). The run ends, no pellet ends below the ground, and it agrees with the
    event-driven reference."""
    ground = dict(GROUND, restitution=0.5)
    position = [[0.0, 0.00125 + 1e-4, 0.0], [0.0, 0.02, 0.0]]
    velocity = [[0.0, -0.1, 0.0], [0.0, -3.0, 0.0]]
    scene = _two_pellets(
        tmp_path, position, velocity, surfaces=[ground], restitution=0.0, mu_s=0.5, mu_d=0.4, contact_duration=1e-4
    )
    pellets, _ = _write(scene, tmp_path / "squeeze.h5", device)
    ref, _ = simulate_collisions(scene, np.asarray(position), np.asarray(velocity), np.zeros((2, 3)))
    assert pellets["collisions.count"].sum() >= 2
    np.testing.assert_array_equal(pellets["collisions.count"], ref["collisions.count"])
    landed = np.isfinite(pellets["landing.position"][:, 1])
    assert np.all(pellets["landing.position"][landed, 1] >= 0.00125 - 1e-12)
    np.testing.assert_allclose(pellets["landing.position"], ref["landing.position"], rtol=1e-9, atol=1e-12)


def test_single_shot_collision_runs_warn_of_chaos_and_ensembles_do_not(device):
    """One shot with collisions is one sample of a chaotic cloud (docs/collisions.md: measured over
    200 shots, float32 and float64 alike): such a run says so; a run of several shots, which
    reports intervals over shots, and a float32 ensemble do not."""
    import warnings

    for precision in ("float32", "float64"):
        with pytest.warns(ChaosWarning, match="shot.shots = 200"):
            api.run(_paper_collisions(20, precision=precision), device=device)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PrecisionWarning)
        api.run(_paper_collisions(20, precision="float32", shots=2), device=device)


def test_lists_that_overflow_grow_before_any_step_and_change_nothing(tmp_path, device):
    """Neighbour lists hold candidates only: lists far too short for the cloud (they overflow at
    the first build and again as it converges) give bitwise the results of lists long enough."""
    raw = paper_raw()
    raw["shot"].update(count=120, envelope_radius=0.006)
    raw["collisions"] = {"enabled": True, "separate": False}  # denser than launches without overlaps allow
    raw["output"] = {"fields": ["landing", "collisions", "release"]}
    runs = []
    for cap in (1, 256):
        raw["collisions"]["max_neighbours"] = cap
        runs.append(_write(make_scene(raw, precision="float64"), tmp_path / f"cap{cap}.h5", device))
    (short, short_stats), (long, long_stats) = runs
    assert long_stats["pair_collisions"] > 50
    for name, value in long.items():
        np.testing.assert_array_equal(short[name], value, err_msg=name)
    assert short_stats == long_stats


@pytest.mark.parametrize("max_neighbours", [32, 2])
def test_the_cpu_one_launch_is_the_host_loop_and_the_per_step_kernels(tmp_path, monkeypatch, max_neighbours):
    """On the CPU the dense phase of a group of shots is one launch of phase_kernel (again
    after a list overflowed: max_neighbours 2). A launch a shot, the host loop of checkpoints,
    rebuilds and blocks (one launch of block_kernel each), and the per-step kernels (those CUDA
    runs) in their order, give bitwise the same results, on several shots; so do the per-step
    kernels with the launch separation and the horizon in pieces (as CUDA launches a large shot's)."""
    from warp_ricochet.dense import phase
    from warp_ricochet.dense.phase import DensePhase

    scene = _paper_collisions(count=60, shots=3, precision="float64", max_neighbours=max_neighbours, separate=True)
    launched = []  # the kernels each run launched (or recorded), by name
    launch = DensePhase._launch
    monkeypatch.setattr(DensePhase, "_launch", lambda self, name, *a, **k: launched.append(name) or launch(self, name, *a, **k))

    def run(name, **options):
        launched.clear()
        return _write(scene, tmp_path / f"{name}.h5", "cpu", DenseOptions(**options)), list(launched)

    one_launch, kernels = run("one-launch")
    assert 1 <= kernels.count("phase_kernel") <= 2 and "block_kernel" not in kernels  # (a second after an overflow)
    shot_by_shot, kernels = run("shot-by-shot", phase_pellets=1)  # a launch a shot
    assert kernels.count("phase_kernel") >= 3
    host_loop, kernels = run("host-loop", cpu_steps="block")
    assert "block_kernel" in kernels and "phase_kernel" not in kernels
    per_step, kernels = run("per-step", cpu_steps="kernels")
    assert "choose_kernel" in kernels and "block_kernel" not in kernels
    monkeypatch.setattr(phase, "HORIZON_PAIRS_PER_LAUNCH", 4 * 180)  # 180 pellets: 4 partners a piece, 8 pieces
    monkeypatch.setattr(phase, "SEPARATION_PELLETS_PER_LAUNCH", 7)  # 9 pieces of a 60-pellet shot
    in_pieces, kernels = run("pieces", cpu_steps="kernels")
    assert kernels.count("separate_kernel") == 9 and kernels.count("horizon_kernel") >= 8
    assert one_launch[1]["pair_collisions"] > 10
    for other in (shot_by_shot, host_loop, per_step, in_pieces):
        for name, value in one_launch[0].items():
            np.testing.assert_array_equal(other[0][name], value, err_msg=name)
        assert other[1] == one_launch[1]


def _lists_at_every_rebuild(scene, monkeypatch, cell_lists):
    """Run `scene` on the CPU with its lists from cell_lists_kernel or from wp.HashGrid, and
    return each rebuild's lists (each pellet's sorted list)."""
    from warp_ricochet.dense.phase import DensePhase

    lists = []
    monkeypatch.undo()  # (the DensePhase of an earlier call)
    rebuild = DensePhase._rebuild

    def recording(self, pellets):
        grew = rebuild(self, pellets)
        count = self.cloud.lists.neighbour_count.numpy()[:pellets]
        table = self.cloud.lists.neighbours.numpy()[:pellets]
        lists.append([tuple(sorted(table[i, : count[i]])) for i in range(pellets)])
        return grew

    monkeypatch.setattr(DensePhase, "_rebuild", recording)
    options = DenseOptions(cpu_steps="block", cpu_lists="cells" if cell_lists else "hashgrid")  # (a _rebuild a rebuild)
    api.run(scene, device="cpu", dense_options=options)
    return lists


@pytest.mark.parametrize("max_neighbours", [32, 2])
def test_the_cpu_cell_lists_are_the_hash_grid_lists(monkeypatch, max_neighbours):
    """On the CPU the lists come from a cell list (wp.HashGrid's CPU build has a fixed cost of a
    few tenths of a millisecond); at every rebuild of a run, every pellet's list holds the same
    pellets as wp.HashGrid's: three shots from one muzzle (they overlap in space: each must see
    only its own), pellets that ended, shots that stopped, lists that overflow and grow."""
    scene = _paper_collisions(count=60, shots=3, max_neighbours=max_neighbours)
    cell = _lists_at_every_rebuild(scene, monkeypatch, True)
    grid = _lists_at_every_rebuild(scene, monkeypatch, False)
    assert len(cell) == len(grid) > 20
    assert max(len(n) for rebuild in grid for n in rebuild) > 5  # dense at first
    for number, (a, b) in enumerate(zip(cell, grid)):
        assert a == b, f"rebuild {number}"


@wp.kernel(enable_backward=False)
def _all_stale(stale: wp.array(dtype=wp.int32)):
    stale[wp.tid()] = 1


def test_kept_events_are_those_a_new_search_finds(tmp_path, device, monkeypatch):
    """Each pellet keeps its earliest event until it or a neighbour changes. Searching every
    pellet's event again at every step (all pellets stale) gives bitwise the same results: a
    kept event is never out of date."""
    from warp_ricochet.dense.phase import DensePhase

    raw = paper_raw()
    raw["shot"].update(count=120, envelope_radius=0.006)
    raw["collisions"] = {"enabled": True, "separate": False}  # denser than launches without overlaps allow
    raw["output"] = {"fields": ["landing", "collisions", "release"]}
    scene = make_scene(raw, precision="float64")
    kept_pellets, kept_stats = _write(scene, tmp_path / "kept.h5", device)
    step_commands = DensePhase._step_commands

    def search_every_step(self, pellets, shots, outputs):
        stale = wp.launch(_all_stale, dim=pellets, inputs=[self.cloud.event.stale], device=self.device, record_cmd=True)
        return [stale, *step_commands(self, pellets, shots, outputs)]

    monkeypatch.setattr(DensePhase, "_step_commands", search_every_step)
    options = DenseOptions(cpu_steps="kernels")  # (the CPU's block kernel is one launch a block)
    searched_pellets, searched_stats = _write(scene, tmp_path / "searched.h5", device, options)
    assert kept_stats["pair_collisions"] > 50
    for name, value in kept_pellets.items():
        np.testing.assert_array_equal(searched_pellets[name], value, err_msg=name)
    assert searched_stats == kept_stats


def test_frames_of_a_run_in_several_chunks_are_refused_before_any_file(tmp_path):
    """H5MD frames hold every pellet of the run at each frame: a run that takes more than one
    chunk is refused in one line (its frames were silently cut to the last chunk's pellets)."""
    from warp_ricochet.errors import SceneError

    raw = paper_raw()
    raw["shot"].update(count=2, shots=40_000, envelope_radius=0.05)
    raw["collisions"] = {"enabled": True, "frame_every": 8}
    raw["numerics"] = {"chunk_size": 65_536}  # 32,768 shots per chunk: two chunks
    path = tmp_path / "frames.h5"
    with pytest.raises(SceneError, match="collisions.frame_every.*one chunk"):
        api.run(make_scene(raw), output=str(path), device="cpu")
    assert not list(tmp_path.iterdir())


def test_a_shot_stops_only_when_no_pair_at_all_can_meet(tmp_path, device):
    """Two pellets flying together at 100 m/s, 8 diameters apart (beyond the lists' reach of
    3 diameters) and closing at 0.1 m/s: they meet 0.18 s later, long after the cloud's arrival
    window (0.4 ms). A stopping rule that looked at listed pairs only let them pass unseen."""
    d = 0.0025
    position = [[0.0, 1.0, 0.0], [8 * d + d, 1.0, 0.0]]
    velocity = [[100.05, 0.0, 0.0], [99.95, 0.0, 0.0]]
    scene = _two_pellets(tmp_path, position, velocity, gravity=(0.0, 0.0, 0.0))
    pellets, stats = _write(scene, tmp_path / "far.h5", device)
    ref, _ref_stats = simulate_collisions(scene, np.asarray(position), np.asarray(velocity), np.zeros((2, 3)))
    assert list(ref["collisions.count"]) == list(pellets["collisions.count"]) == [1, 1]
    np.testing.assert_allclose(pellets["collisions.last_time"], ref["collisions.last_time"], rtol=1e-12)
    assert stats["dense_steps_max"] < 100  # jumped to the contact, not stepped there


def test_only_runs_with_pair_collisions_have_collision_statistics(tmp_path):
    """Collision statistics exist where a dense phase ran: not in a run without collisions, nor
    in one with collisions on but one pellet a shot (nothing to meet), neither returned nor written."""
    from warp_ricochet.tallies.sums import COLLISION_STATS

    raw = paper_raw()
    raw["shot"]["count"] = 20
    cases = {
        "off": make_scene(raw),
        "one-a-shot": make_scene(dict(raw, shot=dict(raw["shot"], count=1, shots=20)), collisions={"enabled": True}),
    }
    cases["on"] = make_scene(raw, collisions={"enabled": True})
    for name, scene in cases.items():
        path = tmp_path / f"{name}.h5"
        stats = api.run(scene, output=str(path), device="cpu")
        with h5py.File(path, "r") as f:
            written = {k for k, ds in f["stats"].items() if isinstance(ds, h5py.Dataset)}
        has = name == "on"
        assert all((k in stats) == has and (k in written) == has for k in COLLISION_STATS), name
        assert set(stats) == written, name


def test_a_shot_in_several_frame_blocks_takes_its_mean_and_the_same_bits_on_every_schedule(tmp_path, monkeypatch):
    """A shot larger than a block of the frame's sums (dense.frame: FRAME_BLOCK, set to 16 pellets
    here, so a shot of 60 has 4 blocks, the last short): its frame at the launch is the mean state
    of its pellets (float64 NumPy), and the CPU's one-launch phase and the per-step kernels (CUDA's
    path: a thread a block) give the same bits."""
    from warp_ricochet.dense import state
    from warp_ricochet.dense.constants import SHOT_FRAME
    from warp_ricochet.dense.phase import DensePhase, start_shots
    from warp_ricochet.launch.source import PelletSource
    from warp_ricochet.model import Model, State
    from warp_ricochet.spec import RunSpec

    monkeypatch.setattr(state, "FRAME_BLOCK", 16)
    scene = _paper_collisions(count=60, shots=3, precision="float64", separate=True)
    model = Model.from_scene(scene, wp.get_device("cpu"))
    dense = DensePhase(model, scene, RunSpec.of(scene, with_output=False), 180)
    assert dense.pair.frame_blocks == 4
    dense.launch_shots(0, 3, PelletSource(scene, "float64", model.device, 180).struct, State(model, 180, ()).outputs)
    start_shots(dense, 3)
    x, v = dense.cloud.state.position.numpy().reshape(3, 60, 3), dense.cloud.state.velocity.numpy().reshape(3, 60, 3)
    np.testing.assert_allclose(dense.cloud.frame.drift_origin.numpy(), x.mean(axis=1), rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(dense.cloud.frame.drift_velocity.numpy(), v.mean(axis=1), rtol=1e-14, atol=1e-12)
    assert np.all(dense.cloud.shot_flags.numpy()[:, SHOT_FRAME] == 0)  # taken
    one = _write(scene, tmp_path / "one.h5", "cpu", DenseOptions())
    kernels = _write(scene, tmp_path / "kernels.h5", "cpu", DenseOptions(cpu_steps="kernels"))
    assert one[1]["pair_collisions"] > 10
    for name, value in one[0].items():
        np.testing.assert_array_equal(kernels[0][name], value, err_msg=name)
    assert kernels[1] == one[1]


@pytest.mark.parametrize("block", [16, 1 << 14])
def test_a_shots_collision_totals_are_its_blocks_summed_in_order(monkeypatch, block):
    """A shot's totals (dense.ends.shot_totals) are taken a frame block at a time: counts exactly
    NumPy's, the energy lost each block's float64 sum in pellet order, added in block order (with
    one block, the whole shot's sum in pellet order: as before the blocks)."""
    from warp_ricochet.dense import state
    from warp_ricochet.dense.phase import DensePhase
    from warp_ricochet.launch.source import PelletSource
    from warp_ricochet.model import Model, State
    from warp_ricochet.spec import RunSpec

    monkeypatch.setattr(state, "FRAME_BLOCK", block)
    scene = _paper_collisions(count=60, shots=3, precision="float64")
    model = Model.from_scene(scene, wp.get_device("cpu"))
    dense = DensePhase(model, scene, RunSpec.of(scene, with_output=False), 180)
    assert dense.pair.frame_blocks == (4 if block == 16 else 1)
    dense.run(0, 3, PelletSource(scene, "float64", model.device, 180).struct, State(model, 180, ()).outputs)
    assert dense.cloud.collisions.count.numpy().sum() > 10
    # then totals of counts and energies of every magnitude (sums whose rounding depends on their order)
    rng = np.random.default_rng(7)
    dense.cloud.collisions.count.assign(rng.integers(0, 4, 180).astype(np.int32))
    dense.cloud.collisions.energy_lost.assign(rng.random(180) * 10.0 ** rng.uniform(-9, 0, 180))
    dense._launch("block_totals_kernel", 3 * dense.pair.frame_blocks, [dense.pair, dense.cloud, dense.block_totals])
    dense._launch("shot_totals_kernel", 3, [dense.pair, dense.cloud, dense.block_totals, dense.totals])
    counts = dense.cloud.collisions.count.numpy().reshape(3, 60)
    lost = dense.cloud.collisions.energy_lost.numpy().astype(np.float64).reshape(3, 60)
    totals = dense.totals.numpy()
    np.testing.assert_array_equal(totals[:, 0], (counts > 0).sum(axis=1))
    np.testing.assert_array_equal(totals[:, 1], counts.sum(axis=1))
    for s in range(3):
        blocks = []
        for first in range(0, 60, block):
            total = 0.0
            for x in lost[s, first : first + block]:
                total += float(x)
            blocks.append(total)
        expected = blocks[0]
        for x in blocks[1:]:
            expected += x
        assert totals[s, 2] == expected
    clock = dense.cloud.clock
    clock = np.stack([clock.steps.numpy(), clock.end.numpy(), clock.overrun.numpy()], axis=1)
    np.testing.assert_array_equal(totals[:, 3:], clock)
