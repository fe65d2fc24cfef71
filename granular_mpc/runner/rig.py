"""The vertical guide rig of drop tests (``mode: drop``, ``rig:``): a trunk wrench.

In a drop test the trunk hangs on a vertical rail: springs and dampers on trunk x, y and
orientation, vertical motion free. The rig is installed as the plant's
``PlantData.base_wrench`` callable.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin


class GuideRig:
    """Trunk wrench of a vertical guide rail (drop tests), world frame at the trunk origin.

    f = −k (p − p0)_xy − c v_xy (no vertical force);  m = −k_r R0·log3(R0ᵀ R) − c_r R ω_B.

    Args:
        rig: the scenario's ``rig:`` section (``stiffness`` [N/m], ``damping`` [N·s/m],
            ``rot_stiffness`` [N·m/rad], ``rot_damping`` [N·m·s/rad]).
        q0: initial configuration (Pinocchio order, trunk quaternion ``(x, y, z, w)`` in
            ``q0[3:7]``): the rest pose p0, R0 of the springs.
    """

    def __init__(self, rig, q0: np.ndarray) -> None:
        self.k, self.c = rig.stiffness, rig.damping
        self.kr, self.cr = rig.rot_stiffness, rig.rot_damping
        self.p0 = q0[0:3].copy()
        self.R0 = pin.Quaternion(q0[6], q0[3], q0[4], q0[5]).matrix()
        self._w = np.zeros(6)

    def __call__(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The wrench (f_W [N], m_W [N·m]) at configuration ``q``, velocity ``v``.

        The returned array is reused between calls (the plant reads it at once).
        """
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).normalized().matrix()
        vw = R @ v[0:3]
        w = self._w
        w[0] = -self.k * (q[0] - self.p0[0]) - self.c * vw[0]
        w[1] = -self.k * (q[1] - self.p0[1]) - self.c * vw[1]
        w[2] = 0.0
        err = self.R0 @ pin.log3(self.R0.T @ R)
        w[3:6] = -self.kr * err - self.cr * (R @ v[3:6])
        return w


__all__ = ["GuideRig"]
