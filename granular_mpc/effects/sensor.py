"""Effects of kind ``sensor``: changes of the measurement only, after the plant has run.

Each is ``fn(cols, p, ctx) -> {column: values}``: ``cols`` maps format-v1 column names to
NumPy arrays of one trial (or a replayed prediction of it), ``ctx`` is a
:class:`~granular_mpc.effects.state.SensorContext`; it returns the columns it changes as
new arrays. :func:`apply_sensor_effects` applies several in order. Library:
``force_sensor_bias``.

A sensor effect maps the *true* columns to the *measured* ones. It receives every column
of the data format (``q_*``, ``dq_*``, ``tau_*``, ``base_*``, ``grf_*``, ``intrusion_*``,
``time``) and may change any of them, inputs such as ``tau_*`` included.
:func:`check_sensor_effect` tries it once on a data set's columns (a clear error naming the
effect and the column it reads that the data do not have); :func:`invert_sensor_effects`
solves the map for the true values of chosen columns (what a replay driven by measured
torques and started from a measured state needs, ``docs/validation.md`` §2).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..exceptions import ConfigError
from .api import register_sensor_effect
from .params import Param
from .registry import EffectInfo
from .state import SensorContext


@register_sensor_effect("force_sensor_bias", params={
    "bias_x": Param(0.0, -50.0, 50.0, "N", "offset of grf_x"),
    "bias_y": Param(0.0, -50.0, 50.0, "N", "offset of grf_y"),
    "bias_z": Param(6.0, -50.0, 50.0, "N", "offset of grf_z"),
}, main="bias_z", neutral={"bias_x": 0.0, "bias_y": 0.0, "bias_z": 0.0},
    depends_on=("nothing: constant on every stance sample",))
def force_sensor_bias(cols, p, ctx: SensorContext):
    """Constant offset of the foot force sensor (zero drift), world axes.

    grf_i ← grf_i + b_i on every row with a stance foot (rows without one stay 0).
    """
    on = ctx.in_stance
    return {f"grf_{ax}": np.asarray(cols[f"grf_{ax}"], dtype=float) + p[f"bias_{ax}"] * on
            for ax in "xyz"}


def apply_sensor_effects(cols: Mapping[str, np.ndarray],
                         specs: Sequence[tuple[EffectInfo, Mapping[str, float]]],
                         ctx: SensorContext) -> dict[str, np.ndarray]:
    """The columns after the sensor effects of ``specs`` (in order; other kinds skipped);
    columns they do not return are unchanged, ``cols`` itself is not modified.

    Args:
        cols: format-v1 columns of one trial.
        specs: ``(EffectInfo, parameter values)`` per effect.
        ctx: stance labels, time, joint names of the trial.
    """
    out = dict(cols)
    for info, p in specs:
        if info.kind != "sensor":
            continue
        changed = info.fn(out, dict(p), ctx)
        for k, v in changed.items():
            out[k] = np.asarray(v, dtype=float)
    return out


def check_sensor_effect(info: EffectInfo, params: Mapping[str, float],
                        cols: Mapping[str, np.ndarray], ctx: SensorContext) -> tuple[str, ...]:
    """Apply a sensor effect once to ``cols`` and return the columns it changes.

    Args:
        info: the effect (kind ``sensor``).
        params: its parameter values.
        cols: every column of (a part of) a data set, format-v1 names.
        ctx: the rows' stance labels, times and joint names.

    Returns:
        The names of the columns it returns, sorted.

    Raises:
        ConfigError: it reads a column ``cols`` does not have (the error names the effect
            and the column), fails otherwise, or returns a column that is not one of
            ``cols`` or an array of another length.
    """
    key = f"effects.{info.name}"
    try:
        changed = info.fn(dict(cols), dict(params), ctx)
    except KeyError as exc:
        col = exc.args[0] if exc.args else "?"
        raise ConfigError(f"sensor effect '{info.name}' reads column {col!r}, which the data "
                          "set does not have", key=key, value=str(col),
                          allowed=", ".join(sorted(cols))) from None
    except Exception as exc:                       # a user's function: say whose it is
        raise ConfigError(f"sensor effect '{info.name}' failed on the data set's columns: "
                          f"{type(exc).__name__}: {exc}", key=key) from None
    n = len(ctx.time)
    for c, v in dict(changed).items():
        if c not in cols:
            raise ConfigError(f"sensor effect '{info.name}' returns column {c!r}, which is "
                              "not a column of the data format", key=key, value=str(c),
                              allowed=", ".join(sorted(cols)))
        if np.shape(np.asarray(v, dtype=float)) != (n,):
            raise ConfigError(f"sensor effect '{info.name}' returns column {c!r} with shape "
                              f"{np.shape(v)}; expected ({n},)", key=key, value=str(c))
    return tuple(sorted(changed))


#: a numerical inversion has converged when its residual is below this share of the
#: measured column's largest magnitude (at least 1 in the column's unit)
INVERSION_TOL = 1e-9
#: Newton iterations of a numerical inversion (it stops earlier once converged)
INVERSION_ITERATIONS = 30


def invert_sensor_effects(cols: Mapping[str, np.ndarray],
                          specs: Sequence[tuple[EffectInfo, Mapping[str, float]]],
                          ctx: SensorContext, targets: Sequence[str], *,
                          strict: bool = True) -> dict[str, np.ndarray]:
    """True values of the columns ``targets`` whose image under the sensor effects of
    ``specs`` is the measured ``cols``: x with h(x) = m.

    When every effect that changes a target has an ``inverse`` (:class:`EffectInfo`;
    ``register_sensor_effect(…, inverse=…)``), the inverses are applied in the reverse
    order. Otherwise the map is solved element by element by Newton iterations with a
    finite-difference slope (exact in one iteration for an offset, in a few for a gain; a
    map of each sample on its own, cross-column maps approximately): a map that mixes
    samples (a delay of a sample or more) has a zero slope on its own sample and does not
    converge.

    Args:
        cols: measured columns (every column the effects read).
        specs: ``(EffectInfo, parameter values)`` per effect (other kinds skipped).
        ctx: the rows' context.
        targets: the columns to solve for (the others are held at their measured values).
        strict: raise when the numerical solve has not converged (else return its last
            iterate).

    Returns:
        ``cols`` with ``targets`` replaced by their true values (a new dict).

    Raises:
        ConfigError: (``strict``) the numerical solve did not converge; the error names the
            effects without an inverse and the column.
    """
    specs = [(i, p) for i, p in specs if i.kind == "sensor"]
    x = {c: np.asarray(v, dtype=float) for c, v in cols.items()}
    targets = [t for t in targets if t in x]
    if not specs or not targets:
        return x
    acting = [(i, p) for i, p in specs if set(i.fn(dict(x), dict(p), ctx)) & set(targets)]
    if not acting:
        return x
    if all(i.inverse is not None for i, _ in acting):
        for info, p in reversed(acting):
            true = info.inverse(dict(x), dict(p), ctx)
            x.update({c: np.asarray(v, dtype=float) for c, v in true.items() if c in targets})
        return x
    meas = {t: x[t].copy() for t in targets}
    scale = {t: max(float(np.max(np.abs(meas[t]), initial=0.0)), 1.0) for t in targets}
    for k in range(INVERSION_ITERATIONS):
        hx = apply_sensor_effects(x, specs, ctx)
        r = {t: float(np.max(np.abs(hx[t] - meas[t]), initial=0.0)) for t in targets}
        # converged to 1e-12 (in the column's unit), or after 6 steps to INVERSION_TOL of
        # its scale: a map of each sample on its own stops where it always did
        if max(r.values()) <= 1e-12 or (
                k >= 6 and max(r[t] / scale[t] for t in targets) <= INVERSION_TOL):
            return x
        eps = {t: 1e-6 * np.maximum(np.abs(x[t]), 1.0) for t in targets}
        x_eps = dict(x)
        x_eps.update({t: x[t] + eps[t] for t in targets})
        hx_eps = apply_sensor_effects(x_eps, specs, ctx)
        for t in targets:
            slope = (hx_eps[t] - hx[t]) / eps[t]
            slope = np.where(np.abs(slope) > 1e-6, slope, 1.0)
            x[t] = x[t] - (hx[t] - meas[t]) / slope
    hx = apply_sensor_effects(x, specs, ctx)
    worst = {t: float(np.max(np.abs(hx[t] - meas[t]), initial=0.0)) / scale[t] for t in targets}
    if strict and max(worst.values()) > INVERSION_TOL:
        col = max(worst, key=worst.get)
        names = [i.name for i, _ in acting if i.inverse is None]
        raise ConfigError(
            f"sensor effect {', '.join(repr(n) for n in names)} cannot be inverted on "
            f"{col!r} sample by sample (residual {worst[col]:.1e} of the column's scale "
            f"after {INVERSION_ITERATIONS} Newton steps): a map that mixes samples (a time "
            "shift of a sample or more, a filter) needs its inverse — "
            "register_sensor_effect(…, inverse=fn), fn(cols, p, ctx) -> {column: true "
            "values}", key=f"effects.{names[0] if names else '?'}", value=col)
    return x


__all__ = ["force_sensor_bias", "apply_sensor_effects", "check_sensor_effect",
           "invert_sensor_effects", "INVERSION_TOL", "INVERSION_ITERATIONS"]
