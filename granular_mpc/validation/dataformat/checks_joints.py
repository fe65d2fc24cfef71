"""Checks of the joint columns against the robot's URDF: angles in radians within the
limits, plausible velocities and torques, velocities consistent with the angles."""

from __future__ import annotations

import math

import numpy as np

from .checks_rates import midpoints, rate_consistency
from .robot_facts import RobotFacts
from .tolerances import FormatTolerances
from .trial_check import RAD_PER_DEG, TrialCheck


def check_joints(t: TrialCheck, facts: RobotFacts, time_ok: bool, tol: FormatTolerances) -> None:
    """Joint angles in radians within the URDF limits, velocities and torques plausible."""
    time = t.values.get("time")
    for j in facts.joints:
        qc, dqc, tauc = f"q_{j}", f"dq_{j}", f"tau_{j}"
        if qc in t.values:
            v = t.values[qc]
            fin = np.isfinite(v)
            # a revolute joint without finite URDF limits still turns within ±2π
            lower = facts.q_lower[j] if np.isfinite(facts.q_lower[j]) else -2 * math.pi
            upper = facts.q_upper[j] if np.isfinite(facts.q_upper[j]) else 2 * math.pi
            lo, hi = lower - tol.joint_limit_margin, upper + tol.joint_limit_margin
            out = fin & ((v < lo) | (v > hi))
            if out.any():
                vr = v[fin] * RAD_PER_DEG
                span = f"values in [{np.min(v[fin]):.4g}, {np.max(v[fin]):.4g}]"
                limits = f"[{lower:g}, {upper:g}] rad"
                # degrees only if the angles are far outside the limits as radians (by more
                # than the joint's whole range) and inside them once converted: small angles
                # fit any range containing 0 after conversion, so that alone proves nothing
                excursion = float(max(lo - np.min(v[fin]), np.max(v[fin]) - hi))
                joint_range = upper - lower
                if excursion > joint_range and vr.min() >= lo and vr.max() <= hi:
                    t.add(f"{span} exceed the joint limits {limits} of robot {facts.name!r} but "
                          "fit them after a degree→radian conversion: degrees? (format v1 wants "
                          "radians)",
                          qc, int(t.rows[np.flatnonzero(out)[0]]))
                    t.degrees.add(qc)
                else:
                    extra = (" — beyond ±2π, so not radians" if np.max(np.abs(v[fin])) > 2 * math.pi
                             else " — zero offset, sign convention or unit?")
                    t.add_rows(qc, f"angle outside the joint limits {limits} (± "
                               f"{tol.joint_limit_margin:g} rad) of robot {facts.name!r}", out,
                               f"; {span}{extra}")
                t.flagged.add(qc)
        if dqc in t.values:
            v = t.values[dqc]
            limit = tol.velocity_limit_factor * facts.dq_max[j]
            out = np.isfinite(v) & (np.abs(v) > limit)
            if out.any() and np.isfinite(limit):
                peak = float(np.max(np.abs(v[out])))
                hint = " — degrees per second?" if peak * RAD_PER_DEG <= limit else ""
                t.add_rows(dqc, f"|dq| exceeds {tol.velocity_limit_factor:g}× the URDF velocity "
                           f"limit {facts.dq_max[j]:g} rad/s", out, f"; largest {peak:.4g}{hint}")
                t.flagged.add(dqc)
        if tauc in t.values:
            v = t.values[tauc]
            limit = tol.torque_limit_factor * facts.tau_max[j]
            out = np.isfinite(v) & (np.abs(v) > limit)
            if out.any() and np.isfinite(limit):
                peak = float(np.max(np.abs(v[out])))
                hint = " — N·mm?" if peak / 1000 <= limit else ""
                t.add_rows(tauc, f"|tau| exceeds {tol.torque_limit_factor:g}× the URDF effort "
                           f"limit {facts.tau_max[j]:g} N·m", out, f"; largest {peak:.4g}{hint}")
                t.flagged.add(tauc)
        in_degrees = qc in t.degrees and qc in t.clean
        if time_ok and t.ok(dqc) and (t.ok(qc) or in_degrees):
            # an angle already reported in degrees is compared after conversion, so that a
            # velocity in deg/s is found in the same pass
            angle = t.values[qc] * (RAD_PER_DEG if in_degrees else 1.0)
            source = f"{qc} (converted to radians)" if in_degrees else qc
            rate_consistency(t, dqc, midpoints(t.values[dqc]), np.diff(angle) / np.diff(time),
                             source, True, tol)


__all__ = ["check_joints"]
