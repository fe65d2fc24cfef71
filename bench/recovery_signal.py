"""How far a recovery case's hidden effect moves its channel, in units of the channel's noise.

Issue 11 sets its recovery targets on the library effects "at any magnitude that moves its
channel ≥ 2 σ". This module measures that, per case of ``bench/recovery.py``, from the data
sets already on disk (no diagnosis). **Our reading of the issue's words** (the issue does not
define them further):

* σ_c — the noise of channel c: the standard deviation over the stance rows
  (``stance != "none"``) of all trials of (noisy − clean) for that channel, from the case's
  noisy data set and the noise-free plant run it was made from (same units as the channel:
  rad, N, m).
* s_c — the effect's signature on channel c: the noise-free data set is replayed by
  :func:`granular_mpc.validation.replay.validate` with the model file (no calibration) without
  and with the true effect at its true value; with RMSE_before and RMSE_after of those two
  replays, s_c = sqrt(max(before² − after², 0)) — the part of the model file's replay error
  the effect explains (``after`` is not zero on noise-free data: the stance-window replay
  has an error floor of its own, e.g. ≈ 0.4 × ``before`` on the knee angles of a weak
  depth hardening; subtracting it in quadrature keeps the floor out of the signature).
* signal = max_c s_c / σ_c over the scored channels (``q_*``, ``grf_*``, ``intrusion_*``:
  the channels of ``validate``'s ``before_after``), and the channel attaining it. A case
  "moves its channel ≥ 2 σ" ⇔ signal ≥ 2.

A secondary figure, not the issue's: ``signal_from(..., with_floor=True)`` divides s_c by
sqrt(after_c² + σ_c²), the scatter that remains on the noisy data with the true effect at its
true value (the replay's error floor and the noise) — how far the effect stands out of what
the diagnosis sees as residual.

The replays are cached per plant run in ``<tag>_signature.json`` and the noise per noisy
set in ``<tag>_n<level>_sigma.json`` beside the data sets, so a restarted study redoes
nothing.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from granular_mpc.columns import STANCE
from granular_mpc.validation import load_dataset
from granular_mpc.validation.prepare import windows_frame
from granular_mpc.validation.scored_channels import channel_names

#: the issue's threshold: a case belongs to its population when signal ≥ this
SIGNAL_THRESHOLD = 2.0


@dataclass(frozen=True)
class Signal:
    """The signal of one case.

    Attributes:
        value: max over channels of s_c / σ_c (dimensionless); NaN when no channel has
            a positive noise σ.
        channel: the channel attaining it (None with NaN).
        signature: s_c of that channel (channel units: rad, N, m).
        sigma: σ_c of that channel (channel units); with ``with_floor`` the scale used,
            sqrt(after_c² + σ_c²).
    """

    value: float
    channel: str | None
    signature: float
    sigma: float

    @property
    def moves_2_sigma(self) -> bool:
        """True when the effect moves its channel by ≥ 2 σ (:data:`SIGNAL_THRESHOLD`)."""
        return bool(self.value >= SIGNAL_THRESHOLD)


def effect_signature(before: float, after: float) -> float:
    """s = sqrt(max(before² − after², 0)): the replay RMSE the effect explains (channel units)."""
    return math.sqrt(max(before * before - after * after, 0.0))


def largest_ratio(signature: Mapping[str, float], scale: Mapping[str, float]) -> Signal:
    """max_c signature_c / scale_c and its channel; channels missing from ``scale`` or with
    scale_c ≤ 0 are skipped (NaN and None when none is left)."""
    best = Signal(float("nan"), None, float("nan"), float("nan"))
    for c, s in signature.items():
        sd = scale.get(c, 0.0)
        if not sd > 0.0:
            continue
        if best.channel is None or s / sd > best.value:
            best = Signal(s / sd, c, s, sd)
    return best


def signal_from(before_after: Mapping[str, tuple[float, float]],
                sigma: Mapping[str, float], *, with_floor: bool = False) -> Signal:
    """The case's signal from the noise-free replays and the channel noise.

    Args:
        before_after: channel → (RMSE before, RMSE after) of the model file without and with
            the true effect, replayed on the noise-free data (channel units).
        sigma: channel → noise standard deviation σ_c (channel units). Channels missing
            here, or with σ_c ≤ 0, are skipped.
        with_floor: divide s_c by sqrt(after_c² + σ_c²) instead of σ_c — the scatter left
            with the true effect at its true value on the noisy data (the replay's own
            error floor and the noise); a secondary figure, not the issue's σ.

    Returns:
        :class:`Signal` (max_c s_c / σ_c and its channel).
    """
    sig = {c: effect_signature(b, a) for c, (b, a) in before_after.items()}
    if not with_floor:
        return largest_ratio(sig, sigma)
    scale = {c: math.hypot(a, sigma[c]) for c, (_, a) in before_after.items()
             if sigma.get(c, 0.0) > 0.0}
    return largest_ratio(sig, scale)


def noise_sigma(clean: Mapping[str, pd.DataFrame], noisy: Mapping[str, pd.DataFrame],
                channels: Sequence[str]) -> dict[str, float]:
    """σ_c: std over the stance rows (``stance != "none"``) of all trials of (noisy − clean).

    Args:
        clean: trial name → noise-free trial table (format-v1 columns).
        noisy: trial name → the same trial with noise (same rows).
        channels: the channels to measure.

    Returns:
        channel → σ_c (channel units).
    """
    diffs: dict[str, list[np.ndarray]] = {c: [] for c in channels}
    for name, c_df in clean.items():
        n_df = noisy[name]
        rows = (c_df[STANCE] != "none").to_numpy()
        for c in channels:
            diffs[c].append(n_df[c].to_numpy()[rows] - c_df[c].to_numpy()[rows])
    return {c: float(np.std(np.concatenate(d))) for c, d in diffs.items()}


def channel_noise(clean: Path, noisy: Path, cache: Path | None = None) -> dict[str, float]:
    """:func:`noise_sigma` of two data sets on disk, on the scored channels (channel units).

    Args:
        clean: the noise-free data set (format v1).
        noisy: its noisy copy (same trials and rows).
        cache: JSON file read if present, written otherwise.
    """
    if cache is not None and cache.is_file():
        return json.loads(cache.read_text(encoding="utf-8"))
    c_ds, n_ds = load_dataset(clean), load_dataset(noisy)
    sigma = noise_sigma(c_ds.trials, n_ds.trials,
                        channel_names(list(c_ds.joint_names), c_ds.channels))
    if cache is not None:
        cache.write_text(json.dumps(sigma, indent=1), encoding="utf-8")
    return sigma


def clean_replay(clean: Path, effect: str, seed: int,
                 cache: Path | None = None) -> dict[str, tuple[float, float, float]]:
    """channel → (RMSE before, RMSE after, moved): the noise-free data replayed with the model
    file (no calibration) without and with ``effect`` at its true value — as
    ``bench/out_of_library.py``'s ``truth_replay`` — and ``moved``, the RMS over all replayed
    samples of (prediction with the effect − prediction without): how far the effect moves
    the channel's prediction (channel units). One process (``workers=1``), ≈ 3–7 s.

    Args:
        clean: the noise-free data set.
        effect: the true effect string (``"name:k=v,…"``).
        seed: bootstrap seed of the report's intervals (does not change the RMSEs).
        cache: JSON file (effect string → table) read if it holds ``effect``, updated
            otherwise.
    """
    from granular_mpc.validation.replay import validate

    stored = (json.loads(cache.read_text(encoding="utf-8"))
              if cache is not None and cache.is_file() else {})
    if effect not in stored or any(len(v) != 3 for v in stored[effect].values()):
        v = validate(clean, None, effects=[effect], params=None, n_boot=20, workers=1,
                     figures=False, seed=seed)
        ba = v.report["before_after"]
        model = v.report["model"]
        before = windows_frame(v.windows, list(v.predictions[model]), list(ba))
        after = windows_frame(v.windows, list(v.predictions[f"{model}+effects"]), list(ba))
        moved = {c: float(np.sqrt(np.nanmean((after[c].to_numpy() - before[c].to_numpy()) ** 2)))
                 for c in ba}
        stored[effect] = {c: [x["before"], x["after"], moved[c]] for c, x in ba.items()}
        if cache is not None:
            cache.write_text(json.dumps(stored, indent=1), encoding="utf-8")
    return {c: (float(b), float(a), float(m)) for c, (b, a, m) in stored[effect].items()}


@dataclass(frozen=True)
class CaseSignal:
    """The three readings of one case (see the module docstring).

    Attributes:
        signal: s_c / σ_c, s_c = sqrt(before² − after²) — the issue's population: ≥ 2.
        moved: m_c / σ_c, m_c the RMS change of the replay's prediction by the effect.
        floor: s_c / sqrt(after_c² + σ_c²).
    """

    signal: Signal
    moved: Signal
    floor: Signal


def case_signal(root: Path, tag: str, level: float, effect: str, seed: int) -> CaseSignal:
    """The signal of the case ``<tag>_n<level>`` of a recovery study folder ``root``
    (``<tag>_clean`` and ``<tag>_n<level>`` must be there; caches are written beside them)."""
    clean = root / f"{tag}_clean"
    noisy = root / f"{tag}_n{level:g}"
    sigma = channel_noise(clean, noisy, root / f"{tag}_n{level:g}_sigma.json")
    rep = clean_replay(clean, effect, seed, root / f"{tag}_signature.json")
    ba = {c: (b, a) for c, (b, a, _) in rep.items()}
    return CaseSignal(signal_from(ba, sigma),
                      largest_ratio({c: m for c, (_, _, m) in rep.items()}, sigma),
                      signal_from(ba, sigma, with_floor=True))


__all__ = ["SIGNAL_THRESHOLD", "Signal", "CaseSignal", "effect_signature", "largest_ratio",
           "signal_from", "noise_sigma",
           "channel_noise",
           "clean_replay", "case_signal"]
