"""The torque acting at a row's time stamp when the logged torque is a held command
(``docs/validation.md`` §3.6, "held torques").

A controller that sets a torque at each tick and logs it there holds it until the next
tick (a zero-order hold of period T): the logged τ(t_k) acts on [t_k, t_k + T], so
against kinematics smoothed over many ticks it acts, on average, T/2 after its stamp.
The joint torque equation error

    e_j(t) = RNEA(q, q̇, q̈; measured foot force)_j(t) − τ_meas,j(t)        [N·m]

then holds τ̇_j·T/2 — on the model's own gait (500 Hz ticks, plant = model, no noise)
0.14 N·m RMS on the swing hip pitch and 0.07 N·m on the swing knee, a const + q pattern
that passed the joint proposal's evidence rule on null data. With τ(t − T/2) in its place
the swing rows' error is 0.008 and 0.011 N·m RMS (T/2 = 1.0 ms is also where that
error is smallest: measured over shifts of −3…+3 ms). ``meta.yaml`` declares T as
``torque_hold_s`` (``synth`` writes it); the delay is not estimated from the data: a
spring, a friction or a torque-sensor gain in the joints moves such an estimate by as
much as the delay itself (measured: 0.8–2.0 ms, and −1.2 ms with joint friction).
"""

from __future__ import annotations

import numpy as np


def hold_delay(hold_s: float | None) -> float:
    """The mean delay [s] of a torque held ``hold_s`` after its stamp (0 when not held)."""
    return 0.5 * float(hold_s) if hold_s else 0.0


def delayed(tau: np.ndarray, rate_hz: float, delay: float) -> np.ndarray:
    """τ(t − ``delay``) on the rows of ``tau`` ((rows, J), rows at ``rate_hz``), by linear
    interpolation between rows (the first and last rows held beyond the ends)."""
    tau = np.asarray(tau, dtype=float)
    if delay == 0.0:
        return tau.copy()
    t = np.arange(tau.shape[0]) / rate_hz
    return np.column_stack([np.interp(t - delay, t, tau[:, j]) for j in range(tau.shape[1])])


__all__ = ["hold_delay", "delayed"]
