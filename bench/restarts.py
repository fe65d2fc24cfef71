"""Replays restarted mid-stance: how far they drift, and the joint rates they start from.

    python bench/restarts.py [--seed 1] [--out DIR] [--json PATH]

One plant run without a hidden effect (``synth``: ``sand_walk``, the out-of-library
design, 3 trials at 0.15 / 0.25 / 0.35 m/s × 7 stances), copied without noise and with
the noise of level 1 (``noisy_copy``, same seed). Every stance is replayed on the model
file (a) in one piece from its first sample and (b) restarted once from the measured
state mid-stance (``stance_windows(segments=2)``, :mod:`granular_mpc.validation.restarts`).
Figures, over the windows that got a restart, per copy (``clean`` / ``noisy``):

* ``rmse.<channel>.<whole|restart>.<first|second>.<copy>``: replay RMSE over the samples
  before (``first``) and from (``second``) the restart, of the one-piece replay and of the
  restarted one (the first parts are the same replay);
* ``rate_rms.<estimator>.<copy>``: the joint rates at the restart rows against the
  noise-free ``dq_*`` samples [rad/s]: Savitzky–Golay derivatives of the measured angles
  (``sg<degree>_<samples>``; ``sg2_15`` is what a window start uses), the measured ``dq_*``
  sample (``raw``);
* ``restarts``, ``windows``: how many windows got one.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _report import emit_study  # noqa: E402
from ool_forms import SPEEDS  # noqa: E402

CHANNELS = ("q_left_knee", "q_right_knee", "q_left_hip_pitch", "q_right_hip_pitch", "grf_z",
            "grf_x", "intrusion_z")
#: joint-rate estimators at a restart row: name → (degree, samples)
RATE_ESTIMATORS = {"sg2_15": (2, 15), "sg4_15": (4, 15), "sg4_21": (4, 21), "sg4_25": (4, 25),
                   "sg4_31": (4, 31)}


def replay_errors(ds, biped, rm, whole, cut, copy: str) -> dict:
    """``rmse.*`` figures of one copy (module docstring)."""
    from granular_mpc.validation.replay import Variant, replay_granular

    sq: dict = {}
    for w0, w in zip(whole, cut):
        if not w.restarts:
            continue
        s = w.restarts[0].start
        for how, win in (("whole", w0), ("restart", w)):
            out = replay_granular(rm, win, Variant())
            for c in CHANNELS:
                e = np.asarray(out[c]) - w.meas[c]
                for part, sl in (("first", slice(0, s)), ("second", slice(s, None))):
                    sq.setdefault(f"rmse.{c}.{how}.{part}.{copy}", []).append(e[sl])
    return {k: float(np.sqrt(np.nanmean(np.concatenate(v) ** 2))) for k, v in sq.items()}


def rate_errors(truth, ds, cut, copy: str) -> dict:
    """``rate_rms.*`` figures of one copy (module docstring)."""
    from scipy.signal import savgol_filter

    from granular_mpc.columns import joint_columns

    J = list(truth.joint_names)
    dt = 1.0 / truth.meta.sample_rate_hz
    cols = {t: (truth.trials[t][joint_columns(J, "dq")].to_numpy(float),
                ds.trials[t][joint_columns(J, "q")].to_numpy(float),
                ds.trials[t][joint_columns(J, "dq")].to_numpy(float)) for t in truth.trials}
    errs: dict = {}
    for w in cut:
        exact_dq, q, raw_dq = cols[w.trial]
        for r in w.restarts:
            k = w.row_start - 1 + r.start            # the row of the restart's state
            for name, (deg, n) in RATE_ESTIMATORS.items():
                est = savgol_filter(q[k - n // 2:k + n // 2 + 1], n, deg, deriv=1, delta=dt,
                                    axis=0)[n // 2]
                errs.setdefault(f"rate_rms.{name}.{copy}", []).append(est - exact_dq[k])
            errs.setdefault(f"rate_rms.raw.{copy}", []).append(raw_dq[k] - exact_dq[k])
    return {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in errs.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=None, help="keep the data sets here")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()

    from granular_mpc.robot.model import load_biped
    from granular_mpc.validation import load_dataset
    from granular_mpc.validation.prepare import stance_windows
    from granular_mpc.validation.replay import build_replay_model, model_terrain
    from granular_mpc.validation.synth import noisy_copy, synthesize

    tmp = tempfile.TemporaryDirectory() if args.out is None else None
    root = Path(tmp.name) if tmp else args.out
    clean, noisy = root / "clean", root / "noisy"
    if not (clean / "meta.yaml").is_file():
        synthesize("sand_walk", clean, speeds=list(SPEEDS), steps=7, seed=args.seed, effects=[],
                   noise=0.0, format="parquet", overwrite=True, workers=1)
    if not (noisy / "meta.yaml").is_file():
        noisy_copy(clean, noisy, 1.0, seed=args.seed, overwrite=True)
    truth = load_dataset(clean)
    biped = load_biped(truth.meta.robot, with_visuals=False)
    rm = build_replay_model(biped, model_terrain("dry_sand"),
                            sample_rate_hz=truth.meta.sample_rate_hz)
    figures: dict = {}
    for copy, path in (("clean", clean), ("noisy", noisy)):
        ds = truth if copy == "clean" else load_dataset(path)
        whole = stance_windows(ds, biped, contact_stiffness=rm.contact_stiffness)
        cut = stance_windows(ds, biped, contact_stiffness=rm.contact_stiffness, segments=2)
        figures[f"windows.{copy}"] = len(cut)
        figures[f"restarts.{copy}"] = sum(len(w.restarts) for w in cut)
        figures.update(replay_errors(ds, biped, rm, whole, cut, copy))
        figures.update(rate_errors(truth, ds, cut, copy))
    emit_study(figures, [], args.json)
    if tmp:
        tmp.cleanup()


if __name__ == "__main__":
    main()
