"""Joint playback: a recorded run's joint references tracked by joint PD (``mode: playback``).

The fallback of the paper's protocol (issue 10, docs/paper.md "The fallback protocol"):
record the joint angles, velocities and torques of a walk on rigid ground, then drive the
plant — rigid or granular — with

    τ = clip(k_p (q_ref(t) − q) + k_d (q̇_ref(t) − q̇) [+ τ_ref(t)], −τ_max, τ_max)

at every controller tick, with no balance feedback of any kind, as a hardware biped whose
position-controlled servos replay a gait. ``q_ref``, ``q̇_ref``, ``τ_ref`` are linear
interpolations of the recorded log rows (actuator order, rad, rad/s, N·m); after the last
recorded row the last angles are held with zero velocity and torque.

With ``k_p = k_d = 0`` and the feed-forward on, at the recorded run's own tick times, the
plant receives exactly the recorded torques: on the recorded run's own terrain it then
repeats that run (``tests/test_playback.py`` checks this).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..columns import SUMMARY_FILE, TIME, joint_columns
from ..exceptions import ConfigError, OutputError
from ..runlog import read_log

PLAYBACK_KEY = "playback.reference"
"""The config key that names the recorded run."""


@dataclass(frozen=True)
class JointReference:
    """Joint references recorded in a run log (actuator order).

    Attributes:
        source: the run folder.
        time: sample times [s], strictly increasing, shape (n,).
        q: joint angles [rad], shape (n, n_joints).
        dq: joint velocities [rad/s], shape (n, n_joints).
        tau: joint torques [N·m] (commanded, held between ticks), shape (n, n_joints).
        window_s: the recorded run's averaging window [s] (its ``summary.json``), used as
            the playback's, or ``None`` when the run has no summary.
    """

    source: Path
    time: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    window_s: tuple[float, float] | None = None

    @classmethod
    def from_run(cls, run_dir: str | Path, joint_names) -> "JointReference":
        """Read the references of a run folder (its ``log/``; ``summary.json`` if present).

        Args:
            run_dir: a folder written by ``granular-mpc run``.
            joint_names: the actuated joints, in actuator order.

        Raises:
            ConfigError: the folder, its log, a joint column or finite increasing times are
                missing (the error names the folder, the column and the key
                ``playback.reference``).
        """
        folder = Path(run_dir)
        if not folder.is_dir():
            raise ConfigError(f"the recorded run {folder} is not a folder", key=PLAYBACK_KEY,
                              value=str(folder), allowed="a run folder written by granular-mpc run")
        try:
            log = read_log(folder)
        except OutputError as exc:
            raise ConfigError(f"the recorded run has no readable log: {exc}", key=PLAYBACK_KEY,
                              value=str(folder)) from None
        arrays = {}
        for kind in ("q", "dq", "tau"):
            cols = joint_columns(joint_names, kind)
            missing = [c for c in cols if c not in log.columns]
            if missing:
                raise ConfigError(f"the log of {folder} has no column {missing[0]} "
                                  f"({len(missing)} joint columns missing)", key=PLAYBACK_KEY,
                                  value=str(folder))
            arrays[kind] = log[cols].to_numpy(dtype=float)
        t = log[TIME].to_numpy(dtype=float)
        bad = ~np.isfinite(t) | np.any(~np.isfinite(np.hstack(list(arrays.values()))), axis=1)
        if bad.any():
            raise ConfigError(f"the log of {folder} has non-finite values in row "
                              f"{int(np.argmax(bad))}", key=PLAYBACK_KEY, value=str(folder))
        if t.size < 2 or np.any(np.diff(t) <= 0):
            raise ConfigError(f"the log of {folder} needs at least 2 rows at increasing times",
                              key=PLAYBACK_KEY, value=str(folder))
        window = None
        summary = folder / SUMMARY_FILE
        if summary.is_file():
            w = json.loads(summary.read_text()).get("window_s")
            if w is not None and len(w) == 2:
                window = (float(w[0]), float(w[1]))
        return cls(folder, t, arrays["q"], arrays["dq"], arrays["tau"], window)

    @property
    def duration(self) -> float:
        """Time of the last recorded row [s]."""
        return float(self.time[-1])

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q_ref, q̇_ref, τ_ref)`` at ``t`` [s]: linear between rows; before the first row
        the first; after the last the last angles, zero velocity and zero torque."""
        time = self.time
        if t >= time[-1]:
            zero = np.zeros(self.q.shape[1])
            return self.q[-1].copy(), zero, zero.copy()
        i = int(np.searchsorted(time, t, side="right")) - 1
        if i < 0:
            return self.q[0].copy(), self.dq[0].copy(), self.tau[0].copy()
        w = (t - time[i]) / (time[i + 1] - time[i])
        return tuple((1.0 - w) * a[i] + w * a[i + 1] for a in (self.q, self.dq, self.tau))


@dataclass(frozen=True)
class JointPlayback:
    """The playback's joint PD law (see the module docstring).

    Attributes:
        reference: the recorded references.
        kp: stiffness [N·m/rad].
        kd: damping [N·m·s/rad].
        feedforward: add the recorded torque.
        tau_max: torque limits per joint [N·m].
    """

    reference: JointReference
    kp: float
    kd: float
    feedforward: bool
    tau_max: np.ndarray

    def torque(self, t: float, q_a: np.ndarray, dq_a: np.ndarray) -> np.ndarray:
        """Joint torques [N·m] at time ``t`` [s] for joint angles ``q_a`` [rad] and velocities
        ``dq_a`` [rad/s] (actuator order)."""
        q_ref, dq_ref, tau_ref = self.reference.at(t)
        tau = self.kp * (q_ref - q_a) + self.kd * (dq_ref - dq_a)
        if self.feedforward:
            tau = tau + tau_ref
        return np.clip(tau, -self.tau_max, self.tau_max)


__all__ = ["JointReference", "JointPlayback", "PLAYBACK_KEY"]
