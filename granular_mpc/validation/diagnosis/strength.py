"""A terrain-file mismatch in disguise: is a candidate only a φ_s — or a contact damping or
added mass — that differs from the terrain file? (``docs/validation.md`` §3.3)

The parameters are tested in groups (:data:`TESTED_GROUPS`): the strength φ_s, then the
contact regime (the elastic-regime damping and the added mass of the solidified wedge,
:data:`.calibration.CONTACT_PARAMS`), each refined and tested on its own. Everything below
says φ_s; the contact regime is handled the same way (a plant damping 3× the file's pulls
on a rising sole like ``cohesion``, an added mass 2× pushes like ``inertial_drag``).

The calibration keeps φ_s at the terrain file's value by default (left free in the
equation error it trades off against depth-dependent effects, §3.1). A plant whose sand
is weaker or stronger than the file says then leaves a residual that a depth-dependent
candidate imitates: a φ_s of 33° instead of 38° was answered with ``depth_hardening``
n = 1.18, accepted as the answer (held-out −26 %, replays better), because the
capacity–depth curve of a lower φ_s *is* a softer depth law. The data cannot tell such a
φ_s mismatch from a missing effect that weakens (strengthens) the sand as a lower (higher)
φ_s does: the twin's sentence gives both readings and asks for φ_s measured independently.

The test (:func:`strength_twin`): the φ_s column (the calibrated model's replays with
φ_s one step higher, :func:`add_strength_sensitivity`) joins the model, and the candidate
must still pass the statistical tests of §3.3 against that model — held-out error
reduction ≥ ``MIN_HELDOUT_REDUCTION`` and ΔAICc ≤ ``MAX_DELTA_AICC``. A candidate that does
not is a *strength twin*: it is not significant, and the verdict says that a φ_s mismatch
explains what it explained, with the φ_s the linear fit asks for. A real effect keeps its
evidence (``depth_hardening`` n = 1.5: held-out −79 % alone, −59 % given φ_s) and is fitted
exactly as before: the φ_s column is never part of its fit.

**Torque-side candidates are no twins when the joint equations show a torque
discrepancy** (:func:`not_twins`). φ_s changes the foot force the terrain law gives; it
cannot change the joint-torque equation error at the measured state (RNEA with the
*measured* foot force minus the measured torque, :mod:`.joint_proposal`). When that error
passes the joint-axis proposal's evidence rule on some joint (a discrepancy nulls do not
show), a joint effect or a sensor effect on ``tau_*`` has evidence a φ_s mismatch cannot
imitate, and is not tested as a twin. Measured (``docs/validation.md`` §5.3.6): a
torque-sensor gain of 0.2 was otherwise called "indistinguishable from φ_s = 29.5°".

The derivative at the file's φ_s is a poor column for a plant 5° weaker (the response is
far from linear there), so the test runs against the model replayed at the φ_s the data
ask for (:func:`strength_model`: Gauss–Newton steps on ζ and φ_s by replays, then every
candidate replayed there; ``docs/validation.md`` §3.7).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np

from ..replay.pool import ReplayPool
from .acceptance_records import StrengthTwin
from .calibration import STRENGTH, CalibrationStage, nuisance_columns
from .candidates import CandidateSet, diverged_candidates
from .cubes import group_keys, pred_cube, residual_cube
from .problem import Problem
from .proposal_records import Proposal
from .regression import Regression, RegressionBuilder
from .residuals import Residuals, compute_residuals, guard_jumps
from .thresholds import MAX_DELTA_AICC, MIN_HELDOUT_REDUCTION


#: the tested terrain-file parameters, refined and tested against group by group
#: (:func:`strength_models`, :func:`first_twin`): the strength, then the contact regime.
#: Refined together, the contact regime took over a φ_s mismatch (35° against the file's
#: 38°: φ_s went to 37.2°, the damping to 1.8×, the added mass to 0.5×) and a depth law
#: passed beside them (issue 11, seed 109)
TESTED_GROUPS = (("phi_s",), ("contact_damping", "added_mass_scale"))
#: a twin's parameters must remove at least this share of what the candidate removes alone
#: (held-out error; and at least the screening's 2 %): a user's sole friction removing 62 %
#: alone failed beside an added mass of 4.8× that removed 22 % (issue 11, seed 1) — the
#: parameters did not explain its evidence, the refined model only spoiled its column
TWIN_SHARE = 0.5
#: at most this many Gauss–Newton steps of the strength by replays (:func:`strength_model`)
STRENGTH_ITERATIONS = 4
#: … stopped when a step moves the strength by less than this share of the column's
#: finite-difference step (φ_s: 0.25° of 3°)
STRENGTH_TOLERANCE = 1.0 / 12.0


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


@dataclass(frozen=True, eq=False)
class StrengthModel:
    """The calibrated model replayed at the terrain-file parameters the data ask for.

    Attributes:
        key: the first tested column (``strength.phi_s`` when φ_s is not calibrated).
        path: its values along the Gauss–Newton steps, the terrain file's first [the
            parameter's unit; φ_s: rad].
        regression: every candidate column (recomputed by replays at the refined
            values) and the tested columns (the derivatives there) on the residual of
            the model replayed there; the nuisance columns as in the screening.
        values: every tested column's refined value (key → value; ``key``'s is
            ``path[-1]``). Empty: only ``key`` was refined.
        at_bound: the tested columns whose refinement ended at a bound of their range:
            the data ask for a value the parameter cannot take (:func:`strength_twin`
            then reads no twin).
    """

    key: str
    path: tuple[float, ...]
    regression: Regression
    values: Mapping[str, float] = field(default_factory=dict)
    at_bound: tuple[str, ...] = ()

    @property
    def value(self) -> float:
        """The strength the data ask for (the last step)."""
        return self.path[-1]

    def value_of(self, key: str, default: float) -> float:
        """The refined value of column ``key`` (``default``: not refined)."""
        return self.value if key == self.key else float(self.values.get(key, default))


def _builder(problem: Problem, res: Residuals, seed: int) -> RegressionBuilder:
    return RegressionBuilder(problem.windows, problem.channels, res.sigma,
                             "trial" if problem.n_trials >= 3 else "stance", seed)


def strength_model(problem: Problem, candidates: CandidateSet, cal: CalibrationStage,
                   res: Residuals, pool: ReplayPool, *, seed: int = 0,
                   iterations: int = STRENGTH_ITERATIONS,
                   params: Sequence[str] | None = None) -> StrengthModel | None:
    """Refine the tested terrain-file parameters ``params`` (None: all of ``cal``'s) by
    replays, then replay every candidate there.

    A plant whose φ_s is 5° below the terrain file's is far outside the range where the
    replay responds linearly to φ_s (the bearing capacity grows about exponentially with
    it): the derivative one step above the file's value, fitted beside the nuisance
    columns, asks for 34.3° where the plant has 33°, and a depth-dependent candidate then
    still removes 14 % of the held-out error beside it (issue 11, the φ_s = 33° null at
    seed 101); replayed at 33°, the same candidate removes nothing. So the tested
    parameters (one group of :data:`TESTED_GROUPS`, :func:`.calibration.strength_columns`)
    are refined like an added effect, together with the calibrated ζ that trades off
    against them: Gauss–Newton steps, each fitting the derivatives at the current values
    beside the touchdown-depth column on the residual replayed there, until every step
    is below :data:`STRENGTH_TOLERANCE` of its column's step or after ``iterations``
    steps. A step that leaves a larger residual than the point it left is not taken. The
    candidates are then replayed there (:func:`.residuals.compute_residuals`), so that
    :func:`strength_twin` compares each with the model the data ask for.

    Returns None when ``cal`` has none of ``params`` or the data ask for the file's values
    (the first step is below the tolerance, or does not lower the residual): the
    screening's own regression then serves.
    """
    tested = tuple(c for c in cal.strength if params is None or c.param in params)
    if not tested:
        return None
    primary = next((c for c in tested if c.param == "phi_s"), tested[0])
    own = {c.param for c in tested}
    windows, channels, edges = problem.windows, problem.channels, problem.edges
    gkeys = group_keys(windows)
    base_keys = list(cal.nuisance_keys)
    test_keys = [c.key for c in tested]
    builder = _builder(problem, res, seed)
    # the model's own parameters that move with the tested ones: ζ (and any calibrated
    # one), re-linearised at every step; the touchdown depth stays a linear column
    moving = {c.param for c in cal.nuisance if c.param in cal.calibration.values} | own
    theta = dict(cal.theta)
    theta.update({c.param: c.neutral for c in tested})
    R, sens = res.R, {k: res.sens[k] for k in base_keys + test_keys}
    path = [primary.neutral]

    def columns(th):
        fixed = {k: v for k, v in th.items() if k not in own}
        return nuisance_columns(fixed) + tuple(replace(c, neutral=th[c.param]) for c in tested)

    def mean_square(reg: Regression) -> float:
        return reg.fit(base_keys)[1] / max(reg.matrix(base_keys)[0].shape[0], 1)

    last, taken, cost = None, dict(theta), math.inf
    for _ in range(iterations + 1):
        cols = columns(theta)
        bounds = {c.key: c.bounds for c in cols}
        reg = builder.build(R, sens, res.geometry, bounds, base_keys).regression
        # a step that leaves a larger residual (mean square of the nuisance fit) than
        # the point it left is not taken: the linearisation failed there (an inertial
        # drag of c_d = 4 asked for an added mass 4.9× the file's, whose replays miss
        # the data by far more than the file's)
        here = mean_square(reg)
        if here > cost:
            theta = taken
            path.pop()
            break
        taken, cost = dict(theta), here
        if len(path) > iterations:
            break
        beta, _ = reg.fit(base_keys + test_keys)
        step = dict(zip(base_keys + test_keys, (float(b) for b in beta)))
        scaled = np.array([step[c.key] / c.step for c in tested])
        if float(np.max(np.abs(scaled))) <= STRENGTH_TOLERANCE:
            break
        # a step back across the previous iterate brackets the values the data ask for:
        # take the middle of the bracket and stop (the steps would oscillate)
        reverse = last is not None and float(scaled @ last) < 0.0
        last = scaled
        for c in [c for c in cols if c.param in moving]:
            theta[c.param] = min(max(c.neutral + (0.5 if reverse else 1.0) * step[c.key],
                                     c.lower), c.upper)
        path.append(theta[primary.param])
        if reverse:
            break
        at = res.base.with_theta(**theta)
        cols = columns(theta)
        variants = {"at": at}
        variants.update({c.key: at.with_theta(**{c.param: c.neutral + c.step}) for c in cols
                         if c.param in moving})
        preds = pool.run(variants)
        P = pred_cube(windows, preds["at"], channels, edges)
        R = residual_cube(windows, preds["at"], channels, edges)
        for c in cols:
            if c.key in preds:
                sens[c.key], _ = guard_jumps((pred_cube(windows, preds[c.key], channels, edges)
                                              - P) / c.step, gkeys)
    if len(path) == 1:
        return None
    fixed = {k: v for k, v in theta.items() if k not in own}
    refined = tuple(replace(c, neutral=theta[c.param]) for c in tested)
    at = replace(cal, theta=theta, nuisance=nuisance_columns(fixed), strength=refined)
    res_at = add_strength_sensitivity(problem, at, compute_residuals(problem, candidates, at,
                                                                     pool), pool)
    bounds = {c.key: c.bounds for c in at.nuisance + at.strength}
    # a candidate whose replays diverge there is left out (the regression keeps only the
    # rows where every column is finite); strength_twin then answers None for it
    keep = candidates.without(list(diverged_candidates(candidates, res_at.sens, res_at.R)))
    bounds.update({c.key: c.bounds for cols in keep.columns.values() for c in cols})
    sens = {k: v for k, v in res_at.sens.items() if k in bounds}
    reg = builder.build(res_at.R, sens, res_at.geometry, bounds, base_keys).regression
    at_bound = tuple(c.key for c in refined if c.neutral <= c.lower or c.neutral >= c.upper)
    return StrengthModel(primary.key, tuple(path), reg,
                         {c.key: c.neutral for c in refined if c.key != primary.key}, at_bound)


def strength_models(problem: Problem, candidates: CandidateSet, cal: CalibrationStage,
                    res: Residuals, pool: ReplayPool, *, seed: int = 0
                    ) -> tuple[StrengthModel, ...]:
    """One :func:`strength_model` per group of :data:`TESTED_GROUPS` that ``cal`` tests and
    the data move from the terrain file's values."""
    out = []
    for group in TESTED_GROUPS:
        m = strength_model(problem, candidates, cal, res, pool, seed=seed, params=group)
        if m is not None:
            out.append(m)
    return tuple(out)


def first_twin(reg: Regression, base_keys: Sequence[str], effect: str, keys: Sequence[str],
               heldout_error_reduction: float, neutral: Mapping[str, float],
               models: Sequence[StrengthModel] = (),
               steps: Mapping[str, float] | None = None) -> StrengthTwin | None:
    """:func:`strength_twin` for each group of :data:`TESTED_GROUPS` in turn (the group's
    refined model from ``models`` if there is one, else the linear test on ``reg``): the
    first twin, or None."""
    for group in TESTED_GROUPS:
        tested = [f"{STRENGTH}.{p}" for p in group]
        model = next((m for m in models if m.key in tested), None)
        tw = strength_twin(reg, base_keys, effect, keys, heldout_error_reduction, neutral,
                           model, steps, tested)
        if tw is not None:
            return tw
    return None


def twin_suspects(reg: Regression, base_keys: Sequence[str],
                  cand_keys: Mapping[str, Sequence[str]]) -> list[str]:
    """The candidates a strength twin test can concern: those that pass the held-out and
    AICc tests of §3.3 against ``base_keys`` on ``reg`` (a superset of the candidates that
    pass the first screening). :func:`strength_model` replays only these at the refined
    strength, and is not needed when there are none: on the 55-stance benchmark data set
    this halves the replays it costs (a candidate that is not replayed there is not a
    twin, :func:`strength_twin`)."""
    base = list(base_keys)
    cv0, a0 = reg.cv(base).sse, reg.aicc(base)
    out = []
    for name, keys in cand_keys.items():
        red = 1.0 - reg.cv(base + list(keys)).sse / cv0 if cv0 > 0 else 0.0
        if red >= MIN_HELDOUT_REDUCTION and reg.aicc(base + list(keys)) - a0 <= MAX_DELTA_AICC:
            out.append(name)
    return out


def strength_keys(reg: Regression) -> list[str]:
    """The terrain-strength column keys the regression has (``strength.<param>``)."""
    return sorted(k for k in reg.cols if k.startswith(f"{STRENGTH}."))


def _readable(key: str, value: float) -> tuple[str, float]:
    param = key.split(".", 1)[1]
    return (f"{param}_deg", math.degrees(value)) if param == "phi_s" else (param, value)


def strength_twin(reg: Regression, base_keys: Sequence[str], effect: str,
                  keys: Sequence[str], heldout_error_reduction: float,
                  neutral: Mapping[str, float],
                  model: StrengthModel | None = None,
                  steps: Mapping[str, float] | None = None,
                  tested: Sequence[str] | None = None) -> StrengthTwin | None:
    """Whether ``effect`` (columns ``keys``) is a terrain-file parameter mismatch in
    disguise: it fails the held-out or the AICc test of §3.3 once the tested columns join
    the model ``base_keys``, and those columns themselves remove at least
    :data:`TWIN_SHARE` of what it removes alone (``heldout_error_reduction``) and at least
    the screening's 2 %. None otherwise, when there is no tested column, or when the
    refined model ended at a bound of a parameter's range (:attr:`StrengthModel.at_bound`).

    Args:
        reg: the screening's regression (the model at the terrain file's strength).
        neutral: strength column key → its value in the terrain file (the column's
            neutral; {}: the values are not reported, only the decision).
        model: the model replayed at the strength the data ask for
            (:func:`strength_model`): the test then runs on its regression (the
            candidate replayed there, beside the strength's derivative there), and the
            strength reported is the refined one. None: the linear test on ``reg``.
        steps: column key → its finite-difference step; the parameter the fit moves
            furthest in these steps is the twin's reading (:attr:`StrengthTwin.parameter`;
            None or without steps: φ_s).
        tested: the tested columns' keys (None: every one the regression has).
    """
    test = model.regression if model is not None else reg
    if any(k not in test.cols for k in keys):
        return None                       # its replays diverged at the refined strength
    if model is not None and model.at_bound:
        return None     # the data ask for a value out of the parameters' range: no reading
    sk = [k for k in strength_keys(test) if k not in base_keys
          and (tested is None or k in tested)]
    if not sk:
        return None
    base = list(base_keys)
    cv0 = reg.cv(base).sse
    cv_s = test.cv(base + sk).sse
    cv_sc = test.cv(base + sk + list(keys)).sse
    red_given = 1.0 - cv_sc / cv_s if cv_s > 0 else 0.0
    daicc = test.aicc(base + sk + list(keys)) - test.aicc(base + sk)
    if red_given >= MIN_HELDOUT_REDUCTION and daicc <= MAX_DELTA_AICC:
        return None
    strength_red = float(1.0 - cv_s / cv0) if cv0 > 0 else 0.0
    if strength_red < max(MIN_HELDOUT_REDUCTION, TWIN_SHARE * heldout_error_reduction):
        return None         # the parameters do not explain what the candidate explained
    beta, _ = test.fit(base + sk)
    start = {k: (model.value_of(k, neutral[k]) if model is not None else neutral[k])
             for k in sk if k in neutral}
    moved = {k: float(b) for k, b in zip(sk, beta[len(base):])}
    fitted = dict(_readable(k, start[k] + moved[k]) for k in sk if k in start)
    filed = dict(_readable(k, neutral[k]) for k in sk if k in neutral)
    # the reading: the parameter furthest from the file, in steps of its column
    shifts = {k: abs(start[k] + moved[k] - neutral[k]) / steps[k]
              for k in sk if k in start and (steps or {}).get(k)}
    parameter = _readable(max(shifts, key=shifts.get), 0.0)[0] if shifts else "phi_s_deg"
    return StrengthTwin(effect, float(heldout_error_reduction), float(red_given), float(daicc),
                        strength_red, fitted, filed, parameter)


def torque_side(candidates: CandidateSet) -> frozenset[str]:
    """The candidates acting on the joint side of the equations of motion: joint effects,
    and sensor effects that change a ``tau_*`` column (at their default parameters,
    :attr:`.candidates.CandidateSet.sensor_outputs`)."""
    joints = {n for n, info in candidates.infos.items() if info.kind == "joint"}
    return frozenset(joints | candidates.sensors_changing("tau_"))


def not_twins(candidates: CandidateSet, proposal: Proposal | None) -> frozenset[str]:
    """The candidates no strength-twin test applies to: the torque-side ones
    (:func:`torque_side`) when the joint-torque equation error passed the joint-axis
    proposal's evidence rule on some joint (``proposal.joint_fits``) — a discrepancy a
    terrain-strength mismatch cannot produce (module docstring). Empty otherwise."""
    if proposal is None or not any(f.proposed for f in proposal.joint_fits):
        return frozenset()
    return torque_side(candidates)


__all__ = ["torque_side", "not_twins", "StrengthTwin", "StrengthModel", "add_strength_sensitivity", "strength_model",
           "strength_models", "first_twin", "TESTED_GROUPS", "TWIN_SHARE",
           "strength_keys", "strength_twin", "twin_suspects", "STRENGTH_ITERATIONS", "STRENGTH_TOLERANCE"]
