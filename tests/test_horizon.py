"""The MPC's horizon set-up (:func:`granular_mpc.control.horizon.plan_horizon`, run by
``WalkingController`` at each MPC tick): the references and supports handed to
:meth:`CentroidalMPC.solve` equal a plain step-by-step evaluation of their definitions
(written here from public names), on sand and on rigid ground.

The set-up is written for speed (Python floats, each support group evaluated once); this
test keeps it honest against the definitions: contact plan at each step's mid-point, the
weight shared by the feet down, stance feet's points sunk by the sinkage still to come,
landing feet at their swing target (or one stride on) at the sinkage of their load, the
inverted-pendulum roll-out over the supports and the capacity at the sinkage allowed by
each step's end.
"""

import math

import numpy as np
import pytest

from granular_mpc.config import CommandConfig, ControllerConfig, SimConfig
from granular_mpc.control.controller import WalkingController
from granular_mpc.control.mpc import CentroidalMPC
from granular_mpc.dynamics import Plant
from granular_mpc.robot.kinematics import balanced_stance
from granular_mpc.rotations import rot_z


def reference_horizon(ctrl, cd, t, x0, feet, v_x):
    """The horizon's inputs from their definitions, one step and one foot at a time."""
    sched, ground, cfg = ctrl.schedule, ctrl.ground, ctrl.config.mpc
    N, dt, mg = ctrl.mpc.N, cfg.dt, ctrl.biped.weight
    stance = sched.contacts(t)
    yaw = float(cd.origin[2])
    contacts = np.zeros((N, 2), dtype=bool)
    load = np.zeros((N, 2))
    points = np.zeros((N, 2, ctrl.mpc.n_points, 3))
    capacity = np.zeros((N, 2))
    depth_now = [ground.surface_height - f.points[:, 2].mean() for f in feet]
    offsets = np.array([[0.0, y, 0.0] for y in ctrl.biped.slice_offsets]) @ rot_z(yaw).T
    for k in range(N):
        tk = (k + 0.5) * dt
        c = sched.contacts(t + tk)
        contacts[k] = c
        for i in range(2):
            if not c[i]:
                continue
            load[k, i] = mg / sum(c)
            z_load = ground.sinkage(load[k, i])
            if stance[i] and sched.time_to_liftoff(t, i) >= tk:     # stays down
                pts = feet[i].points.copy()
                if ground.granular:
                    pts[:, 2] -= max(z_load - depth_now[i], 0.0)
                depth = depth_now[i] + cfg.max_sink_rate * (k + 1) * dt
            else:                                                    # lands in the horizon
                if cd.target[i] is not None and not stance[i]:
                    xy = cd.target[i][:2]
                else:
                    xy = feet[i].points.mean(axis=0)[:2] + np.array([v_x * sched.period, 0.0])
                pts = np.array([[xy[0] + o[0], xy[1] + o[1], ground.surface_height - z_load]
                                for o in offsets])
                depth = cfg.max_sink_rate * max((k + 1) * dt - sched.time_to_touchdown(t, i), 0)
            points[k, i] = pts
            capacity[k, i] = ground.capacity(depth)
    # the inverted pendulum over the supports' centres
    w = ctrl.omega
    p, vel = x0[3:5].copy(), x0[9:11].copy()
    x_ref = np.zeros((N, 12))
    for k in range(N):
        down = [points[k, i, :, :2].mean(axis=0) for i in range(2) if contacts[k, i]]
        if down:
            s = np.mean(down, axis=0)
            r = p - s
            p, vel = (s + r * math.cosh(w * dt) + vel / w * math.sinh(w * dt),
                      r * w * math.sinh(w * dt) + vel * math.cosh(w * dt))
        else:
            p = p + vel * dt
        x_ref[k, [3, 4]], x_ref[k, [9, 10]] = p, vel
    x_ref[:, 2] = yaw
    x_ref[:, 5] = ground.surface_height + ctrl.com_height_ref
    return dict(contacts=contacts, nominal_load=load, points=points, x_ref=x_ref,
                capacity=capacity if ground.granular else None)


@pytest.mark.parametrize("terrain_name", ["sand", "rigid"])
def test_horizon_inputs_equal_their_definitions(biped, sand, rigid, terrain_name, monkeypatch):
    terrain = {"sand": sand, "rigid": rigid}[terrain_name]
    plant = Plant(biped, terrain, SimConfig(dt=5e-4))
    ctrl = WalkingController.build(ControllerConfig(), CommandConfig(speed=0.3, start_delay=0.6),
                                   biped, terrain)
    q0 = balanced_stance(biped, clearance=0.0 if terrain.kind == "rigid" else -0.005)
    d, cd = plant.new_data(q0), ctrl.new_data(q0)
    seen = []
    solve = CentroidalMPC.solve

    def checked(self, data, *, t, x0, x_ref, contacts, points, nominal_load, capacity, **kw):
        feet = ctrl.foot_points(cd.wbc.pin)          # this tick's kinematics
        v_x = float(cd.ramp.reference(t)[1][0])
        want = reference_horizon(ctrl, cd, t, x0, feet, v_x)
        np.testing.assert_array_equal(contacts, want["contacts"])
        np.testing.assert_allclose(nominal_load, want["nominal_load"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(points, want["points"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(x_ref, want["x_ref"], rtol=0, atol=1e-12)
        if want["capacity"] is None:
            assert capacity is None
        else:
            np.testing.assert_allclose(capacity, want["capacity"], rtol=0, atol=1e-9)
        stance = ctrl.schedule.contacts(t)
        # (a foot landing within the horizon?, a step in double support?)
        seen.append((any(contacts[:, i].any() and not stance[i] for i in range(2)),
                     bool(contacts.all(axis=1).any())))
        return solve(self, data, t=t, x0=x0, x_ref=x_ref, contacts=contacts, points=points,
                     nominal_load=nominal_load, capacity=capacity, **kw)

    monkeypatch.setattr(CentroidalMPC, "solve", checked)
    tau = None
    for k in range(int(1.4 / plant.dt)):
        if k % 4 == 0:
            tau = ctrl.compute(cd, d.t, d.q, d.v)
        plant.step(d, tau)
    # 0.9 s of stepping at 40 Hz: ≈ 36 MPC ticks, each checked
    assert len(seen) >= 30
    # horizons with a foot landing in them were checked
    assert any(lands for lands, _ in seen)
    if terrain_name == "sand":
        # the load transfer plans double support steps in the horizon
        assert any(both for _, both in seen)
