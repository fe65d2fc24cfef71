"""The paper's model comparison (its Figs. 4 and 5) on a synthesized data set.

The data set (``OUT/dataset``) holds stances of the 3-D plant walking on sand; each stance
is replayed from its measured touchdown state, driven by the measured joint torques, by
the 3-D granular model, by the rigid-ground model and by the paper's own decoupled model
(sagittal 7-DoF + frontal 5-DoF, ``planar``)
(:func:`granular_mpc.validation.replay.validate`), and scored against the data. The
planar row is the paper's contribution in the loop: how well the decoupled model follows
the 3-D plant over whole stances under the same torques.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..columns import GRF_COLUMNS
from ..validation.prepare import windows_frame
from ..validation.replay import validate

#: the paper's "hip and knee joint angles, q_{2,3,5,6}" (Fig. 5a)
HIP_KNEE = ("q_left_hip_pitch", "q_left_knee", "q_right_hip_pitch", "q_right_knee")
MODELS = ("granular", "rigid", "planar")
#: channels of the planar-model agreement row (joint angles, GRF, intrusion)
AGREEMENT = HIP_KNEE + ("grf_x", "grf_z", "intrusion_z")


@dataclass(frozen=True)
class ModelCheck:
    """Both models against the data set.

    Attributes:
        dataset: the data set folder.
        report_dirs: model → folder of its ``report.json``.
        n_stances: stances replayed.
        rmse: model → channel → whole-data RMSE [rad, N, m].
        grf_magnitude_ratio: model → GRF channel → mean |predicted| / mean |measured| [-].
    """

    dataset: Path
    report_dirs: dict
    n_stances: int
    rmse: dict
    grf_magnitude_ratio: dict

    def planar_to_granular(self, channel: str) -> float:
        """RMSE of the decoupled planar model over that of the 3-D granular model [-]."""
        return self.rmse["planar"][channel] / self.rmse["granular"][channel]

    def hip_knee_better(self) -> int:
        """How many of the four hip/knee angles the granular model predicts better."""
        return sum(self.rmse["granular"][c] < self.rmse["rigid"][c] for c in HIP_KNEE)


def model_check(dataset: str | Path, out_dir: str | Path, *, workers: int | None = None,
                n_boot: int = 200) -> ModelCheck:
    """Replay the data set with both models; reports in ``out_dir/validate_<model>/``."""
    dataset, out_dir = Path(dataset), Path(out_dir)
    rmse, ratio, dirs, n = {}, {}, {}, 0
    for model in MODELS:
        d = out_dir / f"validate_{model}"
        rep = validate(dataset, d, model=model, terrain="dry_sand", workers=workers,
                       figures=False, n_boot=n_boot)
        dirs[model] = d
        n = int(rep.report["n_stances"])
        rmse[model] = {k: float(v) for k, v in rep.report["overall_rmse"][model].items()}
        ratio[model] = grf_magnitude_ratio(rep, model)
    return ModelCheck(dataset, dirs, n, rmse, ratio)


def grf_magnitude_ratio(report, model: str) -> dict:
    """Mean |predicted GRF| over mean |measured GRF| per axis, all replayed samples."""
    channels = list(report.report["channels"])
    meas = windows_frame(report.windows, None, channels)
    pred = windows_frame(report.windows, list(report.predictions[model]), channels)
    out = {}
    for c in GRF_COLUMNS:
        m, p = meas[c].to_numpy(dtype=float), pred[c].to_numpy(dtype=float)
        ok = np.isfinite(m) & np.isfinite(p)
        out[c] = float(np.abs(p[ok]).mean() / np.abs(m[ok]).mean()) if ok.any() else float("nan")
    return out


__all__ = ["ModelCheck", "model_check", "grf_magnitude_ratio", "HIP_KNEE", "MODELS",
           "AGREEMENT"]
