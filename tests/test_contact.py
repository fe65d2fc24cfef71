"""The elastic–plastic patch law (granular_mpc.terrain.contact, .granular, .rigid), driven
directly: the foot's kinematics are prescribed (or integrated here for a single rigid
foot carrying a point load), and the patch forces are compared with hand computations.

Kinematic input per foot (contact.N_KIN): p_W_F (3), R_W_F column-major (9), v_W_F (3),
ω_W (3); F is the centre of the sole arc, so a level foot's lowest point is R below it.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from granular_mpc.config import load_terrain
from granular_mpc.terrain import build_terrain
from granular_mpc.terrain import contact as contact_mod

DT = 5.0e-4
G = 9.81


def rot_y(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def set_kin(foot, p, R=None, v=(0.0, 0.0, 0.0), w=(0.0, 0.0, 0.0)):
    foot.kin[0:3] = p
    foot.kin[3:12] = (np.eye(3) if R is None else R).ravel("F")
    foot.kin[12:15] = v
    foot.kin[15:18] = w


def step_foot(data, p, R=None, v=(0.0, 0.0, 0.0), w=(0.0, 0.0, 0.0)):
    """One contact step of foot 0; returns (total force in W, per-patch state copy)."""
    f = data.feet[0]
    set_kin(f, p, R, v, w)
    data.evaluate(0)
    data.commit()
    return f.force.sum(axis=0).copy(), f.state.copy()


class PointLoadedFoot:
    """A level, non-rotating foot of mass M under gravity and an applied force, integrated
    with semi-implicit Euler — a plant-independent harness for the patch law."""

    def __init__(self, terrain, mass, *, z_low=0.0, params=None):
        self.data = terrain.new_data(DT)
        for k, val in (params or {}).items():
            self.data.set_param(k, val)
        self.R = terrain.foot.radius
        self.M = mass
        self.p = np.array([0.0, 0.0, terrain.surface_height + z_low + self.R])
        self.v = np.zeros(3)
        self.t = 0.0
        self.force = np.zeros(3)

    @property
    def depth(self) -> float:
        return float(self.data.feet[0].diag[:, 0].mean())

    def run(self, duration, applied=lambda t: np.zeros(3), record=False):
        rows = []
        for _ in range(int(round(duration / DT))):
            self.force, _ = step_foot(self.data, self.p, v=self.v)
            total = self.force + np.array([0.0, 0.0, -self.M * G]) + applied(self.t)
            self.v = self.v + DT * total / self.M
            self.p = self.p + DT * self.v
            self.t += DT
            if record:
                rows.append((self.t, *self.p, self.depth, *self.force))
        return np.array(rows)


def support_ramp(mass, t_ramp):
    """Upward support force going from M g to 0 over t_ramp (a quasi-static placement)."""
    return lambda t: np.array([0.0, 0.0, mass * G * max(0.0, 1.0 - t / t_ramp)])


@pytest.fixture(scope="module")
def half_weight_mass(biped):
    return biped.mass / 2.0


# ------------------------------------------------------------------ rolling vs sliding


class PressThenMove:
    """Press the level foot to ``depth``, hold, then roll (or slide) by θ_max·R forward."""

    def __init__(self, R, depth, theta_max=0.4, speed=0.05, t_move=0.4, slide=False):
        self.R, self.depth, self.th, self.slide = R, depth, theta_max, slide
        self.t_press = depth / speed
        self.speed = speed
        self.t_start = self.t_press + 0.05
        self.t_move = t_move
        self.duration = self.t_start + t_move

    def __call__(self, t):
        if t < self.t_press:
            return np.array([0, 0, self.R - self.speed * t]), rot_y(0.0), (0, 0, -self.speed), (0, 0, 0)
        if t < self.t_start:
            return np.array([0, 0, self.R - self.depth]), rot_y(0.0), (0, 0, 0), (0, 0, 0)
        s = t - self.t_start
        th = self.th * (1 - math.cos(math.pi * s / self.t_move)) / 2
        thd = self.th * math.pi / self.t_move * math.sin(math.pi * s / self.t_move) / 2
        # rolling without slip: the centre advances R·θ while the foot turns by θ about +y
        p = np.array([self.R * th, 0.0, self.R - self.depth])
        if self.slide:
            return p, rot_y(0.0), (self.R * thd, 0, 0), (0, 0, 0)
        return p, rot_y(th), (self.R * thd, 0, 0), (0, thd, 0)


@pytest.mark.parametrize("terrain_name,depth", [("sand", 0.010), ("rigid", 0.0003)])
def test_rolling_without_slip_loads_no_tangential_spring(request, terrain_name, depth):
    """Rolling the pressed foot by 0.4 rad (16.5 mm of travel) leaves the tangential
    elastic displacement and force at round-off, because the material point at the
    contact does not move; sliding the same distance loads them (the contrast shows
    the check can fail)."""
    terrain = request.getfixturevalue(terrain_name)
    results = {}
    for slide in (False, True):
        traj = PressThenMove(terrain.foot.radius, depth, slide=slide)
        data = terrain.new_data(DT)
        f_h, e_h, f_z = [], [], []
        for t in np.arange(0.0, traj.duration, DT):
            p, R, v, w = traj(t)
            force, state = step_foot(data, p, R, v, w)
            if t >= traj.t_start:
                f_h.append(force[0])
                f_z.append(force[2])
                e_h.append(np.abs(state[:, 0]).max())
        results[slide] = (np.abs(f_h).max(), max(e_h), min(f_z))
    f_roll, e_roll, fz_roll = results[False]
    assert fz_roll > 5.0                      # the foot stays loaded while it rolls
    assert f_roll < 1e-9 * fz_roll, results
    assert e_roll < 1e-12, results
    f_slide, e_slide, _ = results[True]
    assert f_slide > 5.0 and e_slide > 1e-6, results


# ------------------------------------------------------------------ resting, elastic, creep


def test_resting_loaded_foot_does_not_creep(sand, half_weight_mass):
    """Half the robot's weight released at rest on the surface: the foot sinks, rebounds
    elastically and stops; over the last second it moves < 0.1 µm and carries exactly M g.
    (Before the vertical-bound fix in terrain/granular.py the rebound let go of the load
    and the foot ratcheted down at ≈ 10 mm/s forever.)"""
    foot = PointLoadedFoot(sand, half_weight_mass)
    foot.run(1.0)
    rows = foot.run(1.0, record=True)
    z = rows[:, 3]
    assert z.max() - z.min() < 1e-7
    assert foot.force[2] == pytest.approx(half_weight_mass * G, rel=1e-6)
    # a step load (released at rest) overshoots the quasi-static depth, but stays finite
    d_qs = sand.quasi_static_depth(half_weight_mass * G)
    assert d_qs < foot.depth < 3.0 * d_qs


def test_foot_loaded_inside_the_yield_curve_holds_shear_without_creep(sand, half_weight_mass):
    """Placed quasi-statically, then 20 % of its vertical load relieved (the load is now
    strictly inside RFT's yield locus at that depth), then pushed forward with up to 50 % of
    the horizontal capacity: the static part of the yield curve holds it (< 1 µm in 1 s)."""
    M = half_weight_mass
    cap_h = sand.horizontal_capacity(sand.quasi_static_depth(M * G))[0]
    for frac in (0.1, 0.5):
        ramp = support_ramp(M, 1.0)

        def applied(t, push=frac * cap_h):
            relief = np.array([0.0, 0.0, 0.2 * M * G * min(max(t - 1.2, 0.0) / 0.2, 1.0)])
            return ramp(t) + relief + np.array([push * min(max(t - 1.5, 0.0) / 0.3, 1.0), 0, 0])

        rows = PointLoadedFoot(sand, M).run(3.5, applied, record=True)
        x = rows[rows[:, 0] >= 2.5, 1]
        assert x.max() - x.min() < 1e-6, f"{frac}: creep {1e3 * (x.max() - x.min()):.4f} mm"


@pytest.mark.xfail(strict=True, reason=(
    "known model limit (reported): a foot resting exactly at its vertical yield point (a "
    "quasi-static placement) has no static shear reserve; pushed sideways it should sink a "
    "fraction of a millimetre along RFT's flow and then hold, but the law's flow direction "
    "at rest (v + e/τ) stays near 84°, vertical flow stops after ~0.05 mm and the foot keeps "
    "creeping horizontally (0.56 mm/s at 10 % of the horizontal capacity)"))
def test_resting_foot_under_small_horizontal_load_does_not_creep(sand, half_weight_mass):
    """Placed quasi-statically (support ramped off over 1 s), then pushed forward with
    10 % of the horizontal capacity at its depth — a load well inside RFT's yield locus
    (the vertical load is half the vertical capacity there). A rate-independent plastic
    medium holds it: the foot must not keep moving (< 1 µm over 1 s after 0.7 s)."""
    M = half_weight_mass
    push = 0.1 * sand.horizontal_capacity(sand.quasi_static_depth(M * G))[0]
    ramp = support_ramp(M, 1.0)

    def applied(t):
        return ramp(t) + np.array([push * min(max(t - 1.5, 0.0) / 0.3, 1.0), 0.0, 0.0])

    foot = PointLoadedFoot(sand, M)
    rows = foot.run(3.5, applied, record=True)
    x = rows[rows[:, 0] >= 2.5, 1]
    assert x.max() - x.min() < 1e-6, f"horizontal creep {1e3 * (x.max() - x.min()):.3f} mm in 1 s"


def test_rigid_elastic_deflection_is_load_over_stiffness(rigid, half_weight_mass):
    """On rigid ground the rest penetration is M g / (n K), n patches in parallel."""
    foot = PointLoadedFoot(rigid, half_weight_mass)
    foot.run(1.0)
    n = rigid.contact.n_slices
    K = rigid.config.contact_stiffness
    assert foot.depth == pytest.approx(half_weight_mass * G / (n * K), rel=1e-3)


def test_sand_unloading_is_elastic(sand, half_weight_mass):
    """After settling, taking half the load off raises the foot by ΔF/(n K) — the elastic
    regularisation (≈ 0.07 mm here, far below the sinkage) — and nothing flows."""
    M = half_weight_mass
    foot = PointLoadedFoot(sand, M)
    foot.run(1.0)
    d0 = foot.depth
    relief = lambda t: np.array([0.0, 0.0, 0.5 * M * G * min(t / 0.2, 1.0)])   # noqa: E731
    foot.t = 0.0
    rows = foot.run(1.0, relief, record=True)
    n, K = sand.contact.n_slices, sand.config.contact_stiffness
    assert d0 - foot.depth == pytest.approx(0.5 * M * G / (n * K), rel=0.02)
    tail = rows[rows[:, 0] > 0.5, 4]
    assert tail.max() - tail.min() < 1e-8


# ------------------------------------------------------------------ penetration and extraction


def _press_and_pull(terrain, depth, pull, speed=0.05):
    """Smoothly press the level foot to ``depth``, hold 50 ms, smoothly raise it by ``pull``.
    Returns rows (t, depth of the lowest point, v_z, F_z) for the rising phase only."""
    R = terrain.foot.radius
    data = terrain.new_data(DT)
    t1 = math.pi * depth / (2 * speed)
    t2 = math.pi * pull / (2 * speed)
    rows = []
    for t in np.arange(0.0, t1 + 0.05 + t2, DT):
        if t < t1:
            z = -depth * (1 - math.cos(math.pi * t / t1)) / 2
            vz = -depth * math.pi / t1 * math.sin(math.pi * t / t1) / 2
        elif t < t1 + 0.05:
            z, vz = -depth, 0.0
        else:
            s = t - t1 - 0.05
            z = -depth + pull * (1 - math.cos(math.pi * s / t2)) / 2
            vz = pull * math.pi / t2 * math.sin(math.pi * s / t2) / 2
        force, _ = step_foot(data, [0.0, 0.0, R + z], v=(0.0, 0.0, vz))
        if t >= t1 + 0.05:
            rows.append((t, -z, vz, force[2]))
    return np.array(rows)


def test_shallow_extraction_has_no_suction(sand):
    """A level foot pulled straight up out of 10 mm of sand: once the elastic spring has
    unloaded, nothing pulls it down (its buried surfaces all face down, and RFT's
    extraction stress acts only on buried rear/top surfaces; no suction is added)."""
    rows = _press_and_pull(sand, 0.010, 0.005)
    cap = sand.vertical_capacity(0.010)
    assert rows[0, 3] == pytest.approx(cap, rel=0.01)           # still fully loaded at the start
    # the spring–damper unloads elastically (force falls continuously, no jump to zero) …
    n, K, D = sand.contact.n_slices, sand.config.contact_stiffness, sand.config.contact_damping
    rise = np.cumsum(rows[:, 2]) * DT        # the spring integrates the material velocity
    elastic = cap - n * K * rise - n * D * rows[:, 2]
    unloading = (rows[:, 3] > 0.05 * cap) & (rows[:, 3] < 0.95 * cap)
    assert unloading.sum() > 10
    np.testing.assert_allclose(rows[unloading, 3], elastic[unloading], atol=2e-3 * cap)
    # … then the foot rises free: ≈ zero force (only the wedge's added mass, ~0.02 N)
    assert rows[:, 3].min() > -1e-3 * cap


def test_deep_extraction_equals_rft_on_the_buried_top(sand):
    """Pulled up from 45 mm, the flat top of the sole (chord L = 75 mm, buried at depth
    d − 24 mm) is the only surface moving into sand: F_z = ζ α_z(0, −90°) W L (d − h)
    with α_z(0, −90°) = −0.25 (hand value from Li's coefficients)."""
    rows = _press_and_pull(sand, 0.045, 0.005)
    foot = sand.foot
    plastic = rows[rows[:, 1] < 0.045 - 0.001]
    expected = sand.config.zeta * 1e6 * (-0.25) * foot.width * foot.chord * (plastic[:, 1] - foot.height)
    np.testing.assert_allclose(plastic[:, 3], expected, rtol=0.01)


def test_steady_penetration_force_is_the_closed_form(sand):
    """Pushed straight down at 0.1 m/s, the patch law yields at the closed-form capacity of
    the whole foot, sample by sample (after the first millimetre of elastic loading)."""
    data = sand.new_data(DT)
    data.set_param("added_mass_scale", 0.0)
    R, speed = sand.foot.radius, 0.1
    for k in range(int(0.03 / speed / DT)):
        depth = speed * k * DT
        force, _ = step_foot(data, [0.0, 0.0, R - depth], v=(0.0, 0.0, -speed))
        if depth > 0.001:
            assert force[2] == pytest.approx(sand.vertical_capacity(depth), rel=1e-6), depth
            assert abs(force[0]) < 1e-9 * force[2]


def test_oblique_flow_force_is_the_closed_form_along_the_law_direction(sand):
    """Pushed down-forward (0.2, −0.2) m/s: each component sits at the closed form for the
    law's direction u = v + e/τ (e: the trial elastic displacement), computed here from the
    patch state — i.e. the law really uses the closed form as its yield bound. (The
    wedge's added mass is switched off here: its momentum flux ṁv is checked separately.)"""
    data = sand.new_data(DT)
    data.set_param("added_mass_scale", 0.0)
    foot = data.feet[0]
    R, tau = sand.foot.radius, sand.config.direction_time_constant
    v = np.array([0.2, 0.0, -0.2])
    p = np.array([0.0, 0.0, R])
    checked = 0
    for _ in range(100):
        e_prev = foot.state[:, 0:3].mean(axis=0).copy()
        force, _ = step_foot(data, p, v=v)
        depth = float(foot.diag[:, 0].mean())
        if depth > 0.004:
            u = v + (e_prev + v * DT) / tau
            ref = sand.foot_forces(depth, 0.0, u[0], u[2])
            assert force[2] == pytest.approx(ref.f_z, rel=1e-6)
            assert force[0] == pytest.approx(ref.f_h, rel=1e-6)
            checked += 1
        p = p + v * DT
    assert checked > 50


# ------------------------------------------------------------------ JIT vs VM


def test_jit_and_vm_give_identical_forces(sand, robot_config, monkeypatch):
    """The contact function compiled to C and the same function on CasADi's VM (what
    GRANULAR_MPC_JIT=0 uses) agree on random inputs."""
    jit_fn = sand.contact.function
    if not jit_fn.is_a("External"):
        pytest.skip("no C compiler: the terrain uses CasADi's VM already")
    monkeypatch.setenv("GRANULAR_MPC_JIT", "0")
    vm = build_terrain(load_terrain("dry_sand"), robot_config).contact
    assert not vm.function.is_a("External")
    assert vm.function.is_a("SXFunction") and sand.contact.symbolic.is_a("SXFunction")
    rng = np.random.default_rng(7)
    data = sand.new_data(DT)
    theta = data.feet[0].params.copy()
    n_in = sand.contact.n_in
    for _ in range(200):
        x = np.zeros(n_in)
        R = rot_y(rng.uniform(-0.5, 0.5))
        x[0:3] = [rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), rng.uniform(0.0, 0.08)]
        x[3:12] = R.ravel("F")
        x[12:18] = rng.normal(0.0, 0.3, 6)
        states = rng.normal(0.0, 1e-4, (sand.contact.n_slices, sand.contact.state_size))
        states[:, 6] = rng.integers(0, 2, sand.contact.n_slices)
        x[contact_mod.N_KIN: contact_mod.N_KIN + states.size] = states.ravel()
        x[sand.contact.dt_index] = DT
        x[sand.contact.foot_index] = rng.integers(0, 2)
        x[sand.contact.theta_start:] = theta
        a = np.array(jit_fn(x)).ravel()
        b = np.array(vm.function(x)).ravel()
        np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-11)


def test_added_mass_of_the_solidified_wedge(sand):
    """The wedge's grains move with the foot: F_am = −m_a a − ṁ_a⁺ v. By hand, the wedge
    cross-section is the kite between the arc centre and the tangent lines minus the
    sector: A = R²(tan φ − φ); m_full = ρ W A; m_a = m_full·f² with the submerged share
    f = min(d_apex / h_w, 1), d_apex = d + R/cos φ − R, h_w = R/cos φ − R cos φ.
    Checked as the difference between runs with added_mass_scale 1 and 0."""
    R, W = sand.foot.radius, sand.foot.width
    phi = math.radians(sand.config.phi_s_deg)
    m_full = sand.config.density * W * R * R * (math.tan(phi) - phi)
    h_w = R / math.cos(phi) - R * math.cos(phi)
    v0, decel = 0.2, 8.0           # sink at 0.2 m/s to 20 mm, then brake at 8 m/s²
    datas = [sand.new_data(DT), sand.new_data(DT)]
    datas[1].set_param("added_mass_scale", 0.0)
    depth, v, v_prev = 0.0, -v0, -v0
    checked_growth = checked_brake = 0
    while v < 0.0:
        a = 0.0 if depth < 0.020 else decel
        v_new = v + a * DT if depth >= 0.020 else v
        forces = [step_foot(d, [0.0, 0.0, R - depth], v=(0.0, 0.0, v_new))[0] for d in datas]
        diff = forces[0][2] - forces[1][2]
        frac = min((depth + R / math.cos(phi) - R) / h_w, 1.0)
        a_fd = (v_new - v_prev) / DT
        if 0.0005 < depth < 0.020 and frac < 1.0 and a_fd == 0.0:
            expected = -(m_full * 2.0 * frac / h_w * (-v_new)) * v_new     # −ṁ v
            assert diff == pytest.approx(expected, rel=1e-6)
            checked_growth += 1
        if depth >= 0.020 and a_fd > 0.0:
            assert diff == pytest.approx(-m_full * a_fd, rel=1e-6)          # −m_a a
            checked_brake += 1
        v_prev = v_new
        v = v_new
        depth += -v * DT
    assert checked_growth > 5 and checked_brake > 5
