"""Checks of the trunk columns: unit quaternion, upright and facing +x, position in
metres, plausible velocities consistent with the pose."""

from __future__ import annotations

import numpy as np

from ...columns import BASE_ANGULAR_VELOCITY, BASE_LINEAR_VELOCITY, BASE_POSITION, BASE_QUATERNION
from ...rotations import quat_mul_rows_wxyz
from .checks_rates import midpoints, rate_consistency
from .tolerances import FormatTolerances
from .trial_check import TrialCheck


def check_orientation(t: TrialCheck, tol: FormatTolerances) -> bool:
    """Unit quaternion, trunk upright and facing +x. Returns True if the quaternion is usable."""
    cols = BASE_QUATERNION
    if not all(c in t.values for c in cols):
        return False
    quat = np.column_stack([t.values[c] for c in cols])
    fin = np.isfinite(quat).all(axis=1)
    norm = np.linalg.norm(quat, axis=1)
    bad = fin & (np.abs(norm - 1.0) > tol.quaternion_norm)
    name = ",".join(cols)
    if bad.any():
        t.add_rows(name, f"quaternion (base_qw, base_qx, base_qy, base_qz) is not unit "
                   f"(|‖q‖ − 1| > {tol.quaternion_norm:g})", bad,
                   f"; ‖q‖ ranges over [{norm[bad].min():.4g}, {norm[bad].max():.4g}]")
    good = fin & ~bad
    if good.sum() == 0:
        return False
    w, x, y, z = (quat[good] / norm[good, None]).T
    heading = np.median(1 - 2 * (y * y + z * z))      # x-component of the trunk x axis in W
    upright = np.median(1 - 2 * (x * x + y * y))      # z-component of the trunk z axis in W
    if upright < 0.5:
        t.add(f"the trunk is tilted by more than 60° from upright in most rows (median "
              f"z-axis component {upright:.2f}): quaternion order must be (w, x, y, z)", name)
        t.flagged.update(cols)
    elif heading < 0.0:
        t.add(f"the trunk x axis points backwards (toward world −x) in most rows (median "
              f"x-axis component {heading:.2f}): world x must be the walking direction and the "
              "quaternion order (w, x, y, z) — written as (x, y, z, w)?", name)
        t.flagged.update(cols)
    return bool(fin.all()) and not bad.any() and not (t.flagged & set(cols))


def check_base(t: TrialCheck, time_ok: bool, quat_ok: bool, tol: FormatTolerances) -> None:
    """Trunk position in metres, velocities plausible and consistent with the pose."""
    time = t.values.get("time")
    if "base_z" in t.values:
        z = t.values["base_z"]
        fin = np.isfinite(z)
        if fin.any() and np.median(np.abs(z[fin])) > tol.max_base_height:
            big = fin & (np.abs(z) > tol.max_base_height)
            t.add_rows("base_z", f"trunk height above {tol.max_base_height:g} m (median "
                       f"{np.median(z[fin]):.4g})", big, " — millimetres instead of metres?")
            t.flagged.add("base_z")
    if time_ok:
        dt = np.diff(time)
        for col in BASE_POSITION:
            if t.ok(col):
                speed = np.abs(np.diff(t.values[col])) / dt
                p95 = float(np.percentile(speed, 95))
                if p95 > tol.max_base_speed:
                    fast = np.r_[False, speed > tol.max_base_speed]
                    t.add_rows(col, f"changes faster than {tol.max_base_speed:g} m/s if in metres "
                               f"(95th percentile {p95:.4g} m/s)", fast,
                               " — millimetres instead of metres?")
                    t.flagged.add(col)
    for cols, limit, unit, hint in ((BASE_LINEAR_VELOCITY, tol.max_base_speed, "m/s",
                                     " — mm/s instead of m/s?"),
                                    (BASE_ANGULAR_VELOCITY, tol.max_base_rate, "rad/s",
                                     " — degrees per second?")):
        for col in cols:
            if col in t.values:
                v = t.values[col]
                fin = np.isfinite(v)
                if fin.sum() and np.percentile(np.abs(v[fin]), 95) > limit:
                    t.add_rows(col, f"|{col}| above {limit:g} {unit} (95th percentile "
                               f"{np.percentile(np.abs(v[fin]), 95):.4g})",
                               fin & (np.abs(v) > limit), hint)
                    t.flagged.add(col)
    if not time_ok:
        return
    dt = np.diff(time)
    for pos, vel in zip(BASE_POSITION, BASE_LINEAR_VELOCITY):
        if t.ok(pos, vel):
            rate_consistency(t, vel, midpoints(t.values[vel]), np.diff(t.values[pos]) / dt,
                             pos, False, tol)
    if quat_ok and t.ok(*BASE_QUATERNION):
        quat = np.column_stack([t.values[c] for c in BASE_QUATERNION])
        conj = quat[:-1] * np.array([1.0, -1.0, -1.0, -1.0])
        rel = quat_mul_rows_wxyz(conj, quat[1:])        # q_i⁻¹ ⊗ q_{i+1}: body-frame increment
        rel *= np.sign(rel[:, :1] + (rel[:, :1] == 0))
        omega = 2.0 * rel[:, 1:] / dt[:, None]          # ω_B ≈ 2 vec(Δq) / Δt
        for k, col in enumerate(BASE_ANGULAR_VELOCITY):
            if t.ok(col):
                rate_consistency(t, col, midpoints(t.values[col]), omega[:, k],
                                 "the trunk quaternion (body-frame rate)", True, tol)


__all__ = ["check_orientation", "check_base"]
