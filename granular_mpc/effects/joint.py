"""Effects of kind ``joint``: torques added to the actuators inside ``Plant.forward``.

Each is ``fn(q_a, dq_a, p) -> tau_a`` [N·m] on NumPy arrays in actuator order (``q_a``
[rad], ``dq_a`` [rad/s]); the plant adds the sum of the active ones to the actuator
torques (:func:`joint_torque_function` builds that sum), while the measured torque stays
the commanded one. Library: ``joint_friction`` (viscous + Coulomb).
"""

from __future__ import annotations

from typing import Callable, Mapping, Sequence

import numpy as np

from .api import register_joint_effect
from .params import Param
from .registry import EffectInfo


@register_joint_effect("joint_friction", params={
    "viscous": Param(0.02, 0.0, 2.0, "N·m·s/rad", "viscous friction coefficient b"),
    "coulomb": Param(0.1, 0.0, 5.0, "N·m", "Coulomb friction torque τ_c"),
    "smoothing": Param(0.2, 0.01, 5.0, "rad/s", "velocity below which Coulomb friction is smoothed"),
}, main="coulomb", neutral={"viscous": 0.0, "coulomb": 0.0},
    depends_on=("joint velocity (sign and magnitude)",))
def joint_friction(q_a, dq_a, p):
    """Viscous + Coulomb friction in every actuated joint (gearbox, bearings).

    τ_f = −b q̇ − τ_c tanh(q̇ / ω_s), same for every joint; added to the motor torques, so
    the joints deliver less than the measured (current-based) torque.
    """
    return -p["viscous"] * dq_a - p["coulomb"] * np.tanh(dq_a / p["smoothing"])


def joint_torque_function(specs: Sequence[tuple[EffectInfo, Mapping[str, float]]]
                          ) -> Callable[[np.ndarray, np.ndarray], np.ndarray] | None:
    """One callable ``(q_a, dq_a) -> tau_a`` [N·m] summing the joint effects of ``specs``
    (other kinds skipped; ``None`` if there are none): what
    :class:`~granular_mpc.dynamics.Plant` takes as a joint-effect hook.

    Args:
        specs: ``(EffectInfo, parameter values)`` per effect.
    """
    items = [(info.fn, dict(p)) for info, p in specs if info.kind == "joint"]
    if not items:
        return None

    def tau(q_a: np.ndarray, dq_a: np.ndarray) -> np.ndarray:
        # on CasADi symbols the terms are summed as they are: the compiled plant traces
        # the same sum (dynamics/step_sx.py)
        numeric = isinstance(dq_a, np.ndarray)
        out = np.zeros_like(dq_a) if numeric else 0.0 * dq_a
        for fn, p in items:
            term = fn(q_a, dq_a, p)
            out = out + (np.asarray(term, dtype=float) if numeric else term)
        return out

    return tau


__all__ = ["joint_friction", "joint_torque_function"]
