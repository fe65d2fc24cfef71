"""Drop the robot 2 cm onto dry sand and onto rigid ground; print how deep it settles.

The joints are held at the standing pose by a stiff PD (``DropConfig``: 150 N·m/rad,
3 N·m·s/rad). On semi-cylindrical soles that pose cannot stand by itself (the feet roll),
so the trunk rides a vertical guide rig, as in a drop tower: springs and dampers on the
trunk's x, y and orientation (``GuideRigConfig``), vertical motion free. The rig is a
callable ``base_wrench`` on the plant data — the plant's hook for any external wrench on
the trunk (world frame, at the trunk origin).

    python examples/drop_on_sand.py

Headless, about a second. The last two lines are ``sinkage_sand_mm: X`` and
``sinkage_rigid_mm: Y`` (mean depth of the soles' lowest points below the surface at the
end). Why the sand value is ≈ 2.5× the quasi-static sinkage: docs/model.md §5.
"""

import numpy as np
import pinocchio as pin

from granular_mpc.config import DropConfig, GuideRigConfig, SimConfig, load_robot, load_terrain
from granular_mpc.dynamics import Plant
from granular_mpc.robot import Biped
from granular_mpc.terrain import build_terrain

DROP, RIG = DropConfig(), GuideRigConfig()


def guide_rig(q0):
    """World wrench (f, m) on the trunk holding x, y and orientation; z is free."""
    p0 = q0[0:3].copy()

    def wrench(q, v):
        R_W_B = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        v_W, w_W = R_W_B @ v[0:3], R_W_B @ v[3:6]       # v is in the trunk frame
        f = np.zeros(3)
        f[0:2] = -RIG.stiffness * (q[0:2] - p0[0:2]) - RIG.damping * v_W[0:2]
        m = -RIG.rot_stiffness * pin.log3(R_W_B) - RIG.rot_damping * w_W
        return np.concatenate([f, m])

    return wrench


def drop(biped, terrain, duration=1.5):
    """Release the held robot DROP.height above ``terrain``; return the final sole depth [m]."""
    plant = Plant(biped, terrain, SimConfig())
    q0 = biped.standing_configuration(clearance=DROP.height)
    d = plant.new_data(q0)
    d.base_wrench = guide_rig(q0)
    q_hold = biped.actuated(q0)
    print(f"{terrain.name}\n   t [s]   depth L / R [mm]   F_z L + R [N]")
    for k in range(int(round(duration / plant.dt))):
        tau = DROP.kp * (q_hold - biped.actuated(d.q)) - DROP.kd * biped.actuated(d.v, velocity=True)
        plant.step(d, tau)
        if k % 300 == 299:
            depth = [d.foot_diag(i)[0] * 1e3 if d.foot_in_contact(i) else 0.0 for i in (0, 1)]
            fz = d.foot_force(0)[2] + d.foot_force(1)[2]
            print(f"  {d.t:6.2f}   {depth[0]:6.2f} / {depth[1]:6.2f}   {fz:13.1f}")
    return float(np.mean([d.foot_diag(i)[0] for i in (0, 1)]))


robot = load_robot("yobogo10s")
biped = Biped.from_config(robot, with_visuals=False)
sand = build_terrain(load_terrain("dry_sand"), robot)
rigid = build_terrain(load_terrain("rigid"), robot)

print(f"robot {biped.mass:.2f} kg, weight {biped.weight:.1f} N; quasi-static sinkage of W/2 "
      f"on one foot: {sand.quasi_static_depth(biped.weight / 2) * 1e3:.1f} mm")
depth_sand = drop(biped, sand)
depth_rigid = drop(biped, rigid, duration=1.0)
print(f"sinkage_sand_mm: {depth_sand * 1e3:.3f}")
print(f"sinkage_rigid_mm: {depth_rigid * 1e3:.3f}")
