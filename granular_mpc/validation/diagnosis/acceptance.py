"""Honest acceptance: a refined candidate is added only if its own replays improve the
channels it is credited with and its coefficients are physical; after the additions, the
structure that flagged the missing effect must be explained (``docs/validation.md`` §3.3,
§3.4).

* **Credited channels**: the channels whose replayed prediction the term moves most (RMS
  change over all samples in units of the channel's stance-to-stance scatter σ_c, at least
  :data:`CREDIT_SHARE` of the largest). Their replay RMSE (measured − replayed, all
  samples) must fall in each of them, the model before the addition against the model
  with it (:func:`judge`). A term the linear screening liked but whose replays make its
  own channels worse is reported, not added. Each channel's change also carries the
  paired t-statistic of its stance-by-stance squared-error rise (:func:`rise_t`), shown
  in the report so that a reader can tell a rise within noise from a real one; it does
  not decide (a rule "none significantly worse, one significantly better" was measured in
  session 23 and not kept: docs/validation.md §3.3).
* **Coefficients** (:func:`coefficient_checks`): the dominant parameter must not sit at a
  bound of its range (within :data:`AT_BOUND_SHARE` of the range), nor outside the
  physical interval of its :class:`~granular_mpc.effects.Param` (``wrong sign`` when it is
  on the other side of the neutral value). Such a fit is reported with its flag and not
  added. Other parameters' flags are notes.
* **Joint torques** (:mod:`.torque_evidence`): a joint term on data that measure the joint
  torques and the trunk motion must not be contradicted by the joint-torque equation error — the
  stance-grouped 95 % interval of the share of its torque the error holds reaches
  :data:`.torque_evidence.MIN_REACH`.
* **Explained structure** (:func:`remaining_cells`): the major cells of the calibrated
  model's localisation that are still major (|t| ≥ T_CELL, |bias| ≥ MAJOR_BIAS σ and ≥
  the practical floor √(σ² + σ_meas²), :func:`.localise.practical_floor`) after the
  additions; any left → verdict ``partially_explained``. The final model's cells are
  judged against the scatter of its own residual (:func:`.localise.localize_final`), and
  a candidate that still passes the screening on that residual but could not be added
  is structure left too (:attr:`.verdict.VerdictInputs.leftover_evidence`;
  ``docs/validation.md`` §3.7).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ...effects import EffectInfo
from ..prepare import channel_unit
from .acceptance_records import Acceptance, ChannelChange, CoefficientCheck, TorqueEvidence
from .localization_records import Cell, Localization

#: channels moved by at least this share of the most-moved one are credited to the term
CREDIT_SHARE = 0.5
#: at most this many credited channels
MAX_CREDITED = 4
#: a value within this share of its range from a bound is "at the bound"
AT_BOUND_SHARE = 0.005


def check_coefficient(info: EffectInfo, param: str, value: float) -> CoefficientCheck:
    """One parameter's value against its bounds and its physical interval."""
    spec = info.params[param]
    neutral = info.neutral.get(param, spec.default)
    lo, hi = spec.physical_range
    span = max(spec.upper - spec.lower, 1e-300)
    unit = f" {spec.unit}" if spec.unit and spec.unit != "-" else ""
    val = f"{param} = {value:.4g}{unit}"
    if not lo - 1e-12 * span <= value <= hi + 1e-12 * span:
        other_side = (value - neutral) * ((lo + hi) / 2.0 - neutral) < 0.0
        if other_side:
            return CoefficientCheck(param, value, "wrong_sign",
                                    f"{val} is on the wrong side of its neutral value "
                                    f"{neutral:g} for its physics (allowed [{lo:g}, {hi:g}])")
        return CoefficientCheck(param, value, "outside_physical_range",
                                f"{val} is outside its physical range [{lo:g}, {hi:g}]{unit}")
    for bound in (spec.lower, spec.upper):
        if abs(value - bound) <= AT_BOUND_SHARE * span and abs(bound - neutral) > 1e-12:
            return CoefficientCheck(param, value, "at_bound",
                                    f"{val} sits at the bound {bound:g} of its range: the "
                                    "fit wants more than the effect allows")
    return CoefficientCheck(param, value, "ok", val)


def coefficient_checks(info: EffectInfo, fitted: Mapping[str, float]) -> tuple[CoefficientCheck, ...]:
    """Checks of every parameter that moved from its neutral value (dominant first: the
    one furthest from neutral relative to its range)."""
    moved = [p for p in info.neutral if p in fitted and abs(fitted[p] - info.neutral[p]) > 1e-12]

    def dist(p):
        spec = info.params[p]
        return abs(fitted[p] - info.neutral[p]) / max(spec.upper - spec.lower, 1e-300)

    return tuple(check_coefficient(info, p, float(fitted[p]))
                 for p in sorted(moved, key=dist, reverse=True))


def _channel_rmse(windows, preds, channel: str) -> float:
    e = np.concatenate([np.asarray(w.meas[channel], float) - np.asarray(p[channel], float)
                        for w, p in zip(windows, preds)])
    return float(np.sqrt(np.nanmean(e ** 2)))


def rise_t(windows, before: Sequence[dict], after: Sequence[dict], channel: str) -> float:
    """Paired t-statistic of the rise of ``channel``'s squared error, stance by stance:
    d_w = Σ (meas − after)² − Σ (meas − before)² over window w's samples, t = mean(d) /
    (sd(d)/√n). Positive: the model with the term fits worse. 0 with fewer than two
    stances or no spread; ±inf when every stance moves the same way by the same amount."""
    d = []
    for w, b, a in zip(windows, before, after):
        m = np.asarray(w.meas[channel], float)
        d.append(float(np.nansum((m - np.asarray(a[channel], float)) ** 2)
                       - np.nansum((m - np.asarray(b[channel], float)) ** 2)))
    d = np.asarray(d)
    if d.size < 2:
        return 0.0
    sd = float(np.std(d, ddof=1))
    mean = float(np.mean(d))
    if sd == 0.0:
        return 0.0 if mean == 0.0 else float(np.sign(mean) * np.inf)
    return mean / (sd / np.sqrt(d.size))


def credited_channels(windows, channels: Sequence[str], sigma: Mapping[str, float],
                      before: Sequence[dict], after: Sequence[dict]) -> list[str]:
    """The channels the term moves most (RMS change of the replayed prediction / σ_c)."""
    move = {}
    for c in channels:
        d = np.concatenate([np.asarray(a[c], float) - np.asarray(b[c], float)
                            for a, b in zip(after, before)])
        move[c] = float(np.sqrt(np.nanmean(d ** 2))) / max(sigma.get(c, 1.0), 1e-300)
    top = max(move.values(), default=0.0)
    if not top > 0.0:
        return []
    ranked = sorted((c for c in channels if move[c] >= CREDIT_SHARE * top),
                    key=lambda c: -move[c])
    return ranked[:MAX_CREDITED]


def judge(windows, channels: Sequence[str], sigma: Mapping[str, float], info: EffectInfo,
          fitted: Mapping[str, float], before: Sequence[dict],
          after: Sequence[dict], torque: TorqueEvidence | None = None) -> Acceptance:
    """Decide whether a refined candidate is added (see the module docstring).

    Args:
        windows: the stance windows; channels: scored channels; sigma: channel → σ_c.
        info: the candidate; fitted: its refined parameters.
        before, after: per-window replay outputs without and with it.
        torque: for a joint term, the share of its torque the measured joint torques
            hold (:func:`.torque_evidence.torque_evidence`; None: not tested); refused when
            it is significantly below :data:`.torque_evidence.MIN_REACH`.
    """
    credited = credited_channels(windows, channels, sigma, before, after)
    changes = {}
    reasons = []
    for c in credited:
        r0, r1 = _channel_rmse(windows, before, c), _channel_rmse(windows, after, c)
        changes[c] = ChannelChange(r0, r1, 1.0 - r1 / r0 if r0 > 0 else 0.0, channel_unit(c),
                                   rise_t(windows, before, after, c))
    worse = [c for c, ch in changes.items() if not ch.after < ch.before]
    if not credited:
        reasons.append("its replays change no scored channel")
    elif worse:
        reasons.append("its replays make the channels it is credited with worse: "
                       + ", ".join(f"{c} {100 * -changes[c].reduction:+.1f} % "
                                   f"(rise t = {changes[c].rise_t:.1f})" for c in worse))
    checks = coefficient_checks(info, fitted)
    notes = []
    for k, chk in enumerate(checks):
        if chk.status == "ok":
            continue
        (reasons if k == 0 else notes).append(chk.text)
    if torque is not None and not torque.holds:
        reasons.append(torque.text())
    return Acceptance(info.name, not reasons, changes, checks, tuple(reasons), tuple(notes),
                      torque=torque)


def _same_cell(a: Cell, b: Cell) -> bool:
    return (a.channel, a.side, a.phase_lo) == (b.channel, b.side, b.phase_lo)


def remaining_cells(before: Localization, after: Localization) -> tuple[Cell, ...]:
    """The calibrated model's major cells that are still major after the additions (the
    ``after`` version of each, strongest first)."""
    flagged = [c for c in before.cells if c.major]
    left = [a for a in after.cells if a.major and any(_same_cell(a, b) for b in flagged)]
    return tuple(sorted(left, key=lambda c: -abs(c.t)))


def cell_words(c: Cell) -> str:
    """A cell in words: channel, side, phase, bias."""
    side = "" if c.side == "all" else f" ({c.side} stance)"
    return (f"{c.channel}{side} at {c.phase_lo:g}–{c.phase_hi:g} % of stance: bias "
            f"{c.bias:+.3g} {c.unit} (t = {c.t:.1f})")


__all__ = ["Acceptance", "CoefficientCheck", "judge", "check_coefficient",
           "coefficient_checks", "credited_channels", "rise_t", "remaining_cells", "cell_words",
           "CREDIT_SHARE", "MAX_CREDITED", "AT_BOUND_SHARE"]
