"""Where the replays start a user's or proposed term that the calibration has absorbed
(``docs/validation.md`` §3.3, "The force start").

The calibration fits ζ to the foot force on the sinking samples before any candidate is
tried. A missing force that grows with depth is then partly absorbed into ζ: on a looser
bed under a 12 mm crust (1000 N/m per patch, ``bench/ool_forms.py``) ζ falls from 1.36 to
0.95, and the screening, linearised at that ζ and at a small magnitude, fits the user's
own right term at k = 41 N/m and ranks it fifth — the two changes that together fit the
data (ζ back up, k = 1000) are each far outside the linearisation.

So a terrain-force candidate that is not one of the package's own effects (a user's
term, or a proposal passed back) is also fitted on the foot-force equation error
(§3.6, :mod:`.features`), its main parameter by a bounded search and ζ free (linear), one
axis at a time. When the fit meets the proposal's evidence rule for a single law
(:func:`.proposal.axis_passes` with :data:`.proposal.MIN_LAW_FORCE`: a trial-grouped
held-out reduction and a least force explained, the thresholds set on data without a
missing force), the replays refine the term from there too — its magnitude and ζ
together (:func:`.refine.refine`). It then competes as a rival: it is added only when
its refined AICc is below every other contender's and it passes the acceptance.

The package's own effects are not started this way: their screening was measured on the
recovery study, and a force start would make a library proxy (depth hardening for a
layer) stronger, not the user's hypothesis.
"""

from __future__ import annotations

from typing import Callable, Mapping, Sequence

import numpy as np

from ..calibrate import CAL_PARAMS
from .candidates import CandidateSet
from .features import AXES
from .problem import Problem
from .proposal import MIN_LAW_FORCE, MIN_SAMPLES, axis_passes
from .ranking_records import ForceStart
from .sample_forces import equation_states, force_function

#: grid of the search: this many values per side of the neutral value, spaced
#: geometrically from 10⁻⁴ of the distance to the bound up to the bound
GRID_POINTS = 33


def is_package_effect(fn: Callable) -> bool:
    """Whether an effect function is one of the package's own (its module is inside
    ``granular_mpc``)."""
    return (getattr(fn, "__module__", "") or "").split(".")[0] == "granular_mpc"


def search_grid(neutral: float, lower: float, upper: float) -> np.ndarray:
    """Values of a parameter to search: :data:`GRID_POINTS` per side of ``neutral``,
    geometric from 10⁻⁴ of the distance to the bound up to the bound."""
    steps = np.logspace(-4.0, 0.0, GRID_POINTS)
    out = [neutral]
    if upper > neutral:
        out += list(neutral + steps * (upper - neutral))
    if lower < neutral:
        out += list(neutral - steps * (neutral - lower))
    return np.unique(np.clip(out, lower, upper))


def _zeta_fit(y: np.ndarray, J: np.ndarray) -> float:
    """Least-squares Δζ of y ≈ J Δζ (0 without a gradient)."""
    jj = float(J @ J)
    return float(J @ y) / jj if jj > 0.0 else 0.0


def best_value(force: Callable[[float], np.ndarray], y: np.ndarray, J: np.ndarray,
               grid: np.ndarray, rows: np.ndarray) -> tuple[float, float, float]:
    """The value of ``grid`` (refined between its neighbours by a bounded scalar search)
    minimising the RSS of y − force(v) − J Δζ over ``rows``, Δζ fitted: (value, Δζ, RSS)."""
    from scipy.optimize import minimize_scalar

    cache: dict[float, np.ndarray] = {}

    def rss(v: float) -> float:
        if v not in cache:
            cache[v] = force(v)
        r = y[rows] - cache[v][rows]
        a = _zeta_fit(r, J[rows])
        return float(np.sum((r - a * J[rows]) ** 2))

    scores = [rss(v) for v in grid]
    k = int(np.argmin(scores))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    best = float(grid[k])
    if hi > lo:
        opt = minimize_scalar(rss, bounds=(lo, hi), method="bounded",
                              options={"xatol": 1e-6 * max(abs(hi - lo), 1e-12)})
        if opt.success and opt.fun < scores[k]:
            best = float(opt.x)
    final = rss(best)                       # (cached from here on)
    return best, _zeta_fit(y[rows] - cache[best][rows], J[rows]), final


def heldout_reduction(force: Callable[[float], np.ndarray], y: np.ndarray, J: np.ndarray,
                      grid: np.ndarray, groups: np.ndarray) -> float:
    """Trial-grouped held-out reduction of the equation error: the value and Δζ fitted on
    the other trials, the squared errors of each held-out trial pooled, against ζ alone
    fitted the same way (0 with fewer than two trials)."""
    trials = np.unique(groups)
    if trials.size < 2:
        return 0.0
    with_term = without = 0.0
    for t in trials:
        train, test = groups != t, groups == t
        v, a, _ = best_value(force, y, J, grid, train)
        a0 = _zeta_fit(y[train], J[train])
        with_term += float(np.sum((y[test] - force(v)[test] - a * J[test]) ** 2))
        without += float(np.sum((y[test] - a0 * J[test]) ** 2))
    return 1.0 - float(np.sqrt(with_term / without)) if without > 0.0 else 0.0


def force_starts(problem: Problem, candidates: CandidateSet,
                 theta: Mapping[str, float]) -> tuple[ForceStart, ...]:
    """The equation-error fit of every terrain-force candidate that is not a package
    effect, has one magnitude parameter and acts on the sinking samples (the module
    docstring): per candidate, the axis with the larger explained force among those that
    pass, else the axis with the larger explained force (``passes`` False); () without
    enough sinking samples or such candidates. A fit outside the parameter's physical
    range does not pass.

    Args:
        problem: the diagnosis problem; theta: the calibrated parameters (ζ).
    """
    names = [n for n, i in candidates.infos.items()
             if i.kind == "terrain_force" and i.main and not is_package_effect(i.fn)
             and len(candidates.columns[n]) == 1]
    if not names or "zeta" not in theta:
        return ()
    fs, states = equation_states(problem, theta)
    if fs.n < MIN_SAMPLES:
        return ()
    out = []
    for name in names:
        start = fit_start(name, candidates, states, fs, float(theta["zeta"]))
        if start is not None:
            out.append(start)
    return tuple(out)


def fit_start(name: str, candidates: CandidateSet, states, fs, zeta: float,
              axes: Sequence[str] = AXES) -> ForceStart | None:
    """One candidate's :class:`ForceStart` on ``axes`` (None: it exerts no force on the
    samples there)."""
    info = candidates.infos[name]
    spec = info.params[info.main]
    values = info.resolve_params({})
    fn = force_function(states, info, values, free=info.main)
    neutral = float(info.neutral.get(info.main, spec.default))
    grid = search_grid(neutral, float(spec.lower), float(spec.upper))
    probe = fn(float(grid[-1] if abs(grid[-1] - neutral) >= abs(grid[0] - neutral)
                     else grid[0]))
    every = np.ones(fs.n, bool)
    fits = []
    for ax in axes:
        if not np.any(np.abs(probe[ax]) > 1e-9):
            continue
        y, J = fs.target[ax], fs.nuisance[ax]
        force = (lambda v, ax=ax: fn(v)[ax])
        v, a, rss = best_value(force, y, J, grid, every)
        r0 = y - _zeta_fit(y, J) * J
        before = float(np.sqrt(np.mean(r0 ** 2)))
        after = float(np.sqrt(rss / fs.n))
        red = heldout_reduction(force, y, J, grid, fs.trial)
        lo_p, hi_p = spec.physical_range
        ok = axis_passes(red, red, before, after, ax, MIN_LAW_FORCE) and lo_p <= v <= hi_p
        # ζ from the vertical axis, where the calibration identifies it (on the forward
        # axis its gradient is small: a fit there has put ζ below 0)
        dz = _zeta_fit(fs.target["z"] - fn(v)["z"], fs.nuisance["z"])
        lo, hi = CAL_PARAMS["zeta"]
        fits.append(ForceStart(name, info.main, v, float(np.clip(zeta + dz, lo, hi)), ax,
                               before, after, red, ok, fs.n))
    if not fits:
        return None
    return max(fits, key=lambda s: (s.passes, s.explained))


__all__ = ["ForceStart", "force_starts", "fit_start", "best_value", "heldout_reduction",
           "search_grid", "is_package_effect", "GRID_POINTS"]
