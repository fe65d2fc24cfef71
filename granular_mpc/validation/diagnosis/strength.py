"""A terrain-strength mismatch in disguise: is a candidate only a φ_s that differs from the
terrain file? (``docs/validation.md`` §3.3)

The calibration keeps φ_s at the terrain file's value by default (left free in the
equation error it trades off against depth-dependent effects, §3.1). A plant whose sand
is weaker or stronger than the file says then leaves a residual that a depth-dependent
candidate imitates: a φ_s of 33° instead of 38° was answered with ``depth_hardening``
n = 1.18, accepted as the answer (held-out −26 %, replays better), because the
capacity–depth curve of a lower φ_s *is* a softer depth law. Such a fit is a calibration
matter, not a missing effect.

The test (:func:`strength_twin`): the φ_s column (the calibrated model's replays with
φ_s one step higher, :func:`add_strength_sensitivity`) joins the model, and the candidate
must still pass the statistical tests of §3.3 against that model — held-out error
reduction ≥ ``MIN_HELDOUT_REDUCTION`` and ΔAICc ≤ ``MAX_DELTA_AICC``. A candidate that does
not is a *strength twin*: it is not significant, and the verdict says that a φ_s mismatch
explains what it explained, with the φ_s the linear fit asks for. A real effect keeps its
evidence (``depth_hardening`` n = 1.5: held-out −79 % alone, −59 % given φ_s) and is fitted
exactly as before: the φ_s column is never part of its fit.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Mapping, Sequence

from ..replay.pool import ReplayPool
from .acceptance_records import StrengthTwin
from .calibration import STRENGTH, CalibrationStage
from .cubes import group_keys, pred_cube
from .problem import Problem
from .regression import Regression
from .residuals import Residuals, guard_jumps
from .thresholds import MAX_DELTA_AICC, MIN_HELDOUT_REDUCTION


def add_strength_sensitivity(problem: Problem, cal: CalibrationStage, res: Residuals,
                             pool: ReplayPool) -> Residuals:
    """``res`` with the sensitivity of every terrain-strength column of ``cal`` (one more
    replay of the calibrated model per column, jump-guarded like the others)."""
    if not cal.strength:
        return res
    windows, channels, edges = problem.windows, problem.channels, problem.edges
    variants = {c.key: res.base.with_theta(**{c.param: c.neutral + c.step})
                for c in cal.strength}
    preds = pool.run(variants)
    Pb = pred_cube(windows, res.base_preds, channels, edges)
    gkeys = group_keys(windows)
    sens = dict(res.sens)
    for c in cal.strength:
        S = (pred_cube(windows, preds[c.key], channels, edges) - Pb) / c.step
        sens[c.key], _ = guard_jumps(S, gkeys)
    return replace(res, sens=sens)


def strength_keys(reg: Regression) -> list[str]:
    """The terrain-strength column keys the regression has (``strength.<param>``)."""
    return sorted(k for k in reg.cols if k.startswith(f"{STRENGTH}."))


def _readable(key: str, value: float) -> tuple[str, float]:
    param = key.split(".", 1)[1]
    return (f"{param}_deg", math.degrees(value)) if param == "phi_s" else (param, value)


def strength_twin(reg: Regression, base_keys: Sequence[str], effect: str,
                  keys: Sequence[str], heldout_error_reduction: float,
                  neutral: Mapping[str, float]) -> StrengthTwin | None:
    """Whether ``effect`` (columns ``keys``) is a terrain-strength mismatch in disguise:
    it fails the held-out or the AICc test of §3.3 once the strength columns join the
    model ``base_keys``. None when it passes, or when the regression has no strength
    column.

    Args:
        neutral: strength column key → its value in the terrain file (the column's
            neutral; {}: the values are not reported, only the decision).
    """
    sk = [k for k in strength_keys(reg) if k not in base_keys]
    if not sk:
        return None
    base = list(base_keys)
    cv0 = reg.cv(base).sse
    cv_s = reg.cv(base + sk).sse
    cv_sc = reg.cv(base + sk + list(keys)).sse
    red_given = 1.0 - cv_sc / cv_s if cv_s > 0 else 0.0
    daicc = reg.aicc(base + sk + list(keys)) - reg.aicc(base + sk)
    if red_given >= MIN_HELDOUT_REDUCTION and daicc <= MAX_DELTA_AICC:
        return None
    beta, _ = reg.fit(base + sk)
    fitted = dict(_readable(k, neutral[k] + float(b))
                  for k, b in zip(sk, beta[len(base):]) if k in neutral)
    filed = dict(_readable(k, neutral[k]) for k in sk if k in neutral)
    return StrengthTwin(effect, float(heldout_error_reduction), float(red_given), float(daicc),
                        float(1.0 - cv_s / cv0) if cv0 > 0 else 0.0, fitted, filed)


__all__ = ["StrengthTwin", "add_strength_sensitivity", "strength_keys", "strength_twin"]
