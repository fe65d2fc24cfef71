"""Drop tests of the full plant: the robot, joints held at the standing pose by stiff PD,
trunk on a vertical guide rig (springs and dampers on trunk x, y and orientation, vertical
free — emulated with PlantData.base_wrench), released with its soles 2 cm above the ground.

On the semi-cylindrical (rolling) soles PD-held standing is an unstable equilibrium, hence
the rig. Numbers measured at the time of writing (rig and PD at the GuideRigConfig /
DropConfig defaults: 1e5 N/m, 1500 N·s/m, 800 N·m/rad, 30 N·m·s/rad; 150 N·m/rad,
3 N·m·s/rad) are quoted in the docstrings and in docs/model.md §5.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from granular_mpc.config import DropConfig, GuideRigConfig, SimConfig, load_terrain
from granular_mpc.dynamics import Plant
from granular_mpc.terrain import build_terrain

DROP = DropConfig()            # 2 cm, kp 150 N·m/rad, kd 3 N·m·s/rad
RIG = GuideRigConfig()         # the project's drop-test rig (springs/dampers on x, y, orientation)


class GuideRig:
    """World wrench on the trunk: springs/dampers on x, y and orientation; z free except
    an optional support force ``support(t)`` [N] (for a quasi-static placement)."""

    def __init__(self, d, q0, support=None):
        self.d, self.p0, self.support = d, q0[0:3].copy(), support

    def __call__(self, q, v):
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        v_w, w_w = R @ v[0:3], R @ v[3:6]
        f = np.zeros(3)
        f[0:2] = -RIG.stiffness * (q[0:2] - self.p0[0:2]) - RIG.damping * v_w[0:2]
        if self.support is not None:
            f[2] = self.support(self.d.t)
        m = -RIG.rot_stiffness * pin.log3(R) - RIG.rot_damping * w_w
        return np.concatenate([f, m])

    def power(self, q, v):
        """Power of the rig wrench on the trunk [W]."""
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        w = self(q, v)
        return float(w[0:3] @ (R @ v[0:3]) + w[3:6] @ (R @ v[3:6]))


@dataclass
class DropRun:
    terrain: object
    t: np.ndarray
    depth: np.ndarray            # (N, 2) mean patch depth of each foot [m]
    pitch: np.ndarray            # (N, 2) foot pitch ψ_c [rad]
    fz: np.ndarray               # (N, 2) vertical terrain force on each foot [N]
    foot_xy: np.ndarray          # (N, 2, 2) horizontal contact point of each foot [m]
    com_z: np.ndarray            # (N,) whole-body CoM height [m]
    work_pd: float               # ∫ τ_PDᵀ q̇ dt [J]
    work_rig: float              # ∫ rig wrench · trunk twist dt [J]
    kinetic_end: float
    extra: dict = field(default_factory=dict)


def run_drop(biped, terrain, duration, *, height=DROP.height, support=None):
    plant = Plant(biped, terrain, SimConfig())
    q0 = biped.standing_configuration(height)
    d = plant.new_data(q0)
    rig = GuideRig(d, q0, support)
    d.base_wrench = rig
    qs = np.array(biped.config.standing_joints)
    iq, iv = biped.idx_q, biped.idx_v
    pdata = biped.create_data()
    n = int(round(duration / plant.dt))
    t = np.empty(n)
    depth, pitch, fz = np.zeros((n, 2)), np.zeros((n, 2)), np.zeros((n, 2))
    foot_xy, com_z = np.zeros((n, 2, 2)), np.empty(n)
    work_pd = work_rig = 0.0
    for k in range(n):
        tau = DROP.kp * (qs - d.q[iq]) - DROP.kd * d.v[iv]
        p_pd0, p_rig0 = tau @ d.v[iv], rig.power(d.q, d.v)
        plant.step(d, tau)
        work_pd += 0.5 * plant.dt * (p_pd0 + tau @ d.v[iv])          # torque held over the step
        work_rig += 0.5 * plant.dt * (p_rig0 + rig.power(d.q, d.v))
        t[k] = d.t
        for i in range(2):
            if d.foot_in_contact(i):
                diag = d.foot_diag(i)
                depth[k, i], pitch[k, i] = diag[0], diag[5]
                foot_xy[k, i] = d.foot_point(i)[0:2]
            fz[k, i] = d.foot_force(i)[2]
        com_z[k] = pin.centerOfMass(biped.model, pdata, d.q)[2]
    com0 = pin.centerOfMass(biped.model, pdata, q0)[2]
    return DropRun(terrain, t, depth, pitch, fz, foot_xy, com_z, work_pd, work_rig,
                   plant.energy(d)[0], {"com0": com0})


@pytest.fixture(scope="module")
def sand_drop(biped, sand):
    return run_drop(biped, sand, 2.0)


@pytest.fixture(scope="module")
def rigid_drop(biped, rigid):
    return run_drop(biped, rigid, 1.5)


def _last(run, seconds):
    return run.t >= run.t[-1] - seconds + 1e-9


# ------------------------------------------------------------------ sand


def test_sand_drop_settles_and_carries_the_weight(biped, sand_drop):
    """Depth changes < 1 µm over the last 0.5 s; Σ F_z = m g; each foot carries half
    (symmetric drop). Measured: both feet at 31.75 mm, still to 2e-16 m; Σ F_z and each
    half to 4e-16 and 2e-15 relative (no solver in the loop: a deterministic plant).
    Bounds 1e-6 (m, relative): a creeping foot (1 µm per 0.5 s) or a trunk still
    accelerating fails them. (Were 1e-4 m, 1 % and 5 %.)"""
    run = sand_drop
    tail = _last(run, 0.5)
    for i in range(2):
        assert np.ptp(run.depth[tail, i]) < 1e-6
    total = run.fz[-1].sum()
    assert total == pytest.approx(biped.weight, rel=1e-6)
    np.testing.assert_allclose(run.fz[-1], biped.weight / 2, rtol=1e-6)
    assert 0.02 < run.depth[-1].mean() < 0.05


def test_sand_drop_capacity_bears_each_foot(sand, sand_drop):
    """The closed-form vertical capacity at the settled depth (and pitch) is at least each
    foot's load: the sand is below yield at rest. Measured: 148 N ≥ 52 N."""
    run = sand_drop
    for i in range(2):
        cap = sand.vertical_capacity(run.depth[-1, i], run.pitch[-1, i])
        assert cap >= run.fz[-1, i]


def test_sand_drop_overshoots_quasi_static_depth(biped, sand, sand_drop):
    """A rate-independent plastic medium does not give back the impact energy: the drop
    settles well below the quasi-static depth of W/2 (measured 31.75 vs 12.59 mm, ×2.5)."""
    d_qs = sand.quasi_static_depth(biped.weight / 2)
    ratio = sand_drop.depth[-1].mean() / d_qs
    assert 1.5 < ratio < 4.0


def test_sand_drop_energy_balance(biped, sand, sand_drop):
    """Independent energy balance. The drop energy m g Δz_CoM equals the work of the sand —
    computed from the closed-form capacity along the recorded depth path, the sand yielding
    at that force whenever a foot goes deeper — plus the PD and rig dissipation (their work
    integrated from the recorded torques/velocities). Solving the same balance for the
    final depth d_E, with ∫₀^d cap(z) dz per foot and the recorded leg compression,
    predicts the simulated settled depth within 10 %.
    Measured: E = 5.79 J = 4.61 (sand) + 1.17 (PD) + 0.06 (rig), residual −0.8 %;
    d_E = 31.93 mm vs 31.75 mm simulated (+0.6 %)."""
    run = sand_drop
    mg = biped.weight
    e_drop = mg * (run.extra["com0"] - run.com_z[-1])
    w_sand = 0.0
    for i in range(2):
        dep, psi = run.depth[:, i], run.pitch[:, i]
        prev_d = prev_p = 0.0
        for dk, pk in zip(dep, psi):
            if dk > prev_d:
                w_sand += sand.vertical_capacity(0.5 * (dk + prev_d), 0.5 * (pk + prev_p)) * (dk - prev_d)
            prev_d, prev_p = max(dk, 0.0), pk
    dissipated = -run.work_pd - run.work_rig
    residual = e_drop - run.kinetic_end - w_sand - dissipated
    # measured −0.8 % (the work sums over 0.5 ms steps); bound 2 % (was 5 %)
    assert abs(residual) < 0.02 * e_drop, (e_drop, w_sand, -run.work_pd, -run.work_rig)
    # the balance solved for the depth
    d_sim = run.depth[-1].mean()
    compression = (run.extra["com0"] - run.com_z[-1]) - DROP.height - d_sim
    pitch = run.pitch[-1].mean()
    assert abs(pitch) < 0.05

    def balance(d):
        sand_work = 2.0 * quad(lambda z: sand.vertical_capacity(z, pitch), 0.0, d, limit=200)[0]
        return mg * (DROP.height + compression + d) - dissipated - sand_work

    d_energy = brentq(balance, 1e-5, sand.config.layer_depth)
    # measured +0.6 %; bound 2 % (was 10 %)
    assert d_energy == pytest.approx(d_sim, rel=0.02)


def test_quasi_static_placement_matches_closed_form(biped, sand):
    """Support force on the trunk ramped from m g to 0 over 1.5 s from touching the
    surface: each foot settles within 6 % of quasi_static_depth(its load). Measured:
    13.07 mm vs 12.58–12.61 mm (+3.8 %: the robot's momentum at the end of the ramp and
    the 0.13 mm elastic deflection; see test_terrain for the ramp-rate dependence); bound
    6 % (was 10 %). Loads: measured 2.3e-5 from m g/2 (bound 1e-3, was 5 %), Σ 3e-7
    (bound 1e-4, was 1 %); depth still to 1.1e-7 m over 0.3 s (bound 1e-6 m, was 1e-4)."""
    mg = biped.weight
    run = run_drop(biped, sand, 2.0, height=0.0, support=lambda t: mg * max(0.0, 1.0 - t / 1.5))
    tail = _last(run, 0.3)
    for i in range(2):
        assert np.ptp(run.depth[tail, i]) < 1e-6
        load = run.fz[-1, i]
        assert load == pytest.approx(mg / 2, rel=1e-3)
        d_qs = sand.quasi_static_depth(load, run.pitch[-1, i])
        assert run.depth[-1, i] == pytest.approx(d_qs, rel=0.06)
        assert run.depth[-1, i] > d_qs            # the momentum pushes it deeper, never less
    assert run.fz[-1].sum() == pytest.approx(mg, rel=1e-4)


def test_larger_zeta_sinks_less_in_the_drop(biped, robot_config, sand_drop):
    """ζ = 2.72 (twice dry sand) settles shallower than ζ = 1.36. Measured 18.2 vs 31.7 mm."""
    stiff = build_terrain(load_terrain("dry_sand", zeta=2.72), robot_config)
    run = run_drop(biped, stiff, 1.0)
    assert run.depth[-1].mean() < 0.8 * sand_drop.depth[-1].mean()
    assert run.fz[-1].sum() == pytest.approx(biped.weight, rel=0.01)


# ------------------------------------------------------------------ rigid


def test_rigid_drop_barely_penetrates_and_does_not_drift(biped, rigid, rigid_drop):
    """Penetration < 1 mm (measured 0.26 mm = (W/2)/(2K)); the contact points do not
    drift horizontally over the last 1 s; Σ F_z = m g. Measured: depth = W/K_total to
    1.3e-13, drift 1.9e-8 m, Σ F_z to 6e-15 (deterministic plant); bounds 1e-6 (relative,
    m, relative; were 5 %, 5e-4 m, 1 %)."""
    run = rigid_drop
    assert run.depth[-1].max() < 1e-3
    k_total = 2 * rigid.contact.n_slices * rigid.config.contact_stiffness
    assert run.depth[-1].mean() == pytest.approx(biped.weight / k_total, rel=1e-6)
    tail = _last(run, 1.0)
    for i in range(2):
        xy = run.foot_xy[tail, i]
        assert np.hypot(*(xy.max(axis=0) - xy.min(axis=0))) < 1e-6
    assert run.fz[-1].sum() == pytest.approx(biped.weight, rel=1e-6)


def test_sand_sinks_much_more_than_rigid(sand_drop, rigid_drop):
    """Measured 31.75 mm against 0.26 mm (×121); bound ×20: the claim is 'much more'."""
    assert sand_drop.depth[-1].mean() > 20 * rigid_drop.depth[-1].mean()
