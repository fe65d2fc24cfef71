"""Check of a trial's time column: strictly increasing, sampled at ``sample_rate_hz``."""

from __future__ import annotations

import math

import numpy as np

from ...columns import META_FILE
from .tolerances import FormatTolerances
from .trial_check import TrialCheck


def check_time(t: TrialCheck, fs: float | None, tol: FormatTolerances) -> bool:
    """Strictly increasing time and sampling consistent with ``sample_rate_hz``.

    The step-by-step checks (gaps, short steps) run only when time is strictly
    increasing and its median step matches ``sample_rate_hz``; otherwise they would only
    echo the problems already reported.

    Returns:
        True if ``time`` is finite, strictly increasing and consistent with
        ``sample_rate_hz`` (the time-derivative checks need all three).
    """
    if "time" not in t.values:
        return False
    time = t.values["time"]
    idx = np.flatnonzero(np.isfinite(time))
    if idx.size < 2:
        return False
    dt = np.diff(time[idx])
    later = np.zeros(len(time), dtype=bool)
    later[idx[1:][dt == 0]] = True
    t.add_rows("time", "time repeats the value of the previous row", later)
    later[:] = False
    later[idx[1:][dt < 0]] = True
    t.add_rows("time", "time goes backwards (smaller than in the previous row)", later)
    increasing = bool((dt > 0).all()) and "time" in t.clean
    positive = dt[dt > 0]
    if fs is None or positive.size == 0:
        return False
    median = float(np.median(positive))
    ratio = (1.0 / median) / fs
    if abs(ratio - 1.0) > tol.sample_rate:
        hint = ""
        for factor, unit in ((1e-3, "milliseconds"), (1e-6, "microseconds"), (1e-9, "nanoseconds")):
            if abs(math.log(ratio / factor)) < math.log(1.5):
                hint = f" — is time in {unit}?"
        t.add(f"median time step {median:.6g} s ({1 / median:.6g} Hz) does not match "
              f"sample_rate_hz = {fs:g} in {META_FILE} (tolerance {tol.sample_rate:.0%}){hint}",
              "time")
        return False
    if not increasing:
        return False
    lo, hi = (1 - tol.step_jitter) / fs, (1 + tol.step_jitter) / fs
    step = np.full(len(time), np.nan)
    step[idx[1:]] = dt
    # a step across rows already reported (unreadable line, blank line, NaN time) is no news
    across = (np.diff(idx) > 1) | (np.diff(t.rows[idx]) > 1)
    step[idx[1:][across]] = np.nan
    long = step > hi
    if long.any():
        t.add_rows("time", f"time step longer than {hi:.4g} s = {1 + tol.step_jitter:g}/"
                   f"sample_rate_hz (samples missing?)", long,
                   f"; largest step {np.nanmax(step):.4g} s")
    short = (step > 0) & (step < lo)
    if short.any():
        t.add_rows("time", f"time step shorter than {lo:.4g} s = {1 - tol.step_jitter:g}/"
                   f"sample_rate_hz (irregular sampling?)", short,
                   f"; smallest step {np.nanmin(step[short]):.4g} s")
    return increasing


__all__ = ["check_time"]
