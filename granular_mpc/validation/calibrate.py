"""Calibration of the terrain's own parameters on equation-error residuals.

While a stance foot sinks, the medium yields and the elastic–plastic law's vertical
force *is* the closed-form RFT force for the current depth, pitch and direction of
motion (``docs/model.md`` §2.4). So every measured sample with the stance foot clearly
sinking gives one equation

    F_z,measured = F_z(depth, ψ_c, u_h, u_z; ζ, φ_s) + noise,

with depth = measured intrusion z (the touchdown point lies on the surface), ψ_c the foot
pitch and u = v_c − F/(n K τ) the law's direction of motion (the material velocity of the
contact point plus the elastic displacement over the direction time constant), all from
the smoothed measurements (:mod:`.prepare`). ζ and φ_s are fitted by bounded nonlinear
least squares (``scipy.optimize.least_squares``) with the **exact CasADi Jacobian** of the
closed form (:meth:`granular_mpc.terrain.TerrainModel.casadi_foot_forces`).

Intervals: the Gauss–Newton covariance s²(JᵀJ)⁻¹ inflated by N / N_eff (lag-1
autocorrelation of the residuals within stances), and a one-step (linearised) bootstrap
over whole trials. Parameters the data cannot see (the lateral λ and α_sh, which need
sideways flow; the 21 g added mass) are reported as not identified and kept.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .prepare import StanceWindow

#: fitted parameters (θ name, bounds [θ units]); φ_s in radians
#: (granular media: ζ from 0.33 (glass beads) to 3.05 (Mojave simulant); φ_s of sands and
#: beads 25–50°)
CAL_PARAMS = {"zeta": (0.1, 6.0), "phi_s": (math.radians(25.0), math.radians(50.0))}


#: relative singular-value floor of the Jacobian below which (ζ, φ_s) are not separable
RANK_TOL = 1e-8


@dataclass(frozen=True)
class Calibration:
    """Result of :func:`calibrate`.

    Attributes:
        values: fitted θ (``zeta``, ``phi_s`` [rad]).
        initial: the model's values before calibration.
        se_gn: Gauss–Newton standard errors (inflated for correlated samples).
        ci_gn, ci_boot: 95 % intervals (Gauss–Newton, trial bootstrap).
        n_samples, n_stances: samples and stances used.
        rmse_before, rmse_after: RMS of F_z,meas − F_z,model [N].
        correlation: correlation of the two estimates.
        identified: per parameter, whether the data determine it.
        note: remarks.
    """

    values: dict
    initial: dict
    se_gn: dict = field(default_factory=dict)
    ci_gn: dict = field(default_factory=dict)
    ci_boot: dict = field(default_factory=dict)
    n_samples: int = 0
    n_stances: int = 0
    rmse_before: float = float("nan")
    rmse_after: float = float("nan")
    correlation: float = float("nan")
    identified: dict = field(default_factory=dict)
    note: str = ""

    def to_json(self) -> dict:
        def deg(k, v):
            return math.degrees(v) if k == "phi_s" else v

        out = {
            "method": "equation error on sinking samples: measured vertical GRF vs the closed-"
                      "form RFT force at the measured depth, pitch and direction of motion; "
                      "bounded least squares with the exact CasADi Jacobian",
            "values": self.values, "initial": self.initial,
            "values_readable": {("phi_s_deg" if k == "phi_s" else k): deg(k, v)
                                for k, v in self.values.items()},
            "se_gn": self.se_gn, "ci_gn": self.ci_gn, "ci_bootstrap": self.ci_boot,
            "n_samples": self.n_samples, "n_stances": self.n_stances,
            "rmse_before_N": self.rmse_before, "rmse_after_N": self.rmse_after,
            "correlation_zeta_phi": self.correlation, "identified": self.identified,
            "note": self.note,
        }
        return out

    @classmethod
    def from_json(cls, data: dict) -> "Calibration":
        """The calibration from its :meth:`to_json` form (``values`` as written there)."""
        return cls(values=dict(data["values"]), initial=dict(data["initial"]),
                   se_gn=dict(data.get("se_gn", {})), ci_gn=dict(data.get("ci_gn", {})),
                   ci_boot=dict(data.get("ci_bootstrap", {})),
                   n_samples=int(data.get("n_samples", 0)),
                   n_stances=int(data.get("n_stances", 0)),
                   rmse_before=_float(data.get("rmse_before_N")),
                   rmse_after=_float(data.get("rmse_after_N")),
                   correlation=_float(data.get("correlation_zeta_phi")),
                   identified=dict(data.get("identified", {})), note=data.get("note", ""))


def _float(x) -> float:
    """A JSON number (None: NaN, which JSON cannot hold)."""
    return float("nan") if x is None else float(x)


def sinking_samples(windows: Sequence[StanceWindow], *, min_rate: float = 0.2,
                    min_depth: float = 2e-3, min_force: float = 10.0) -> dict:
    """Samples with the stance foot clearly sinking (in vertical flow)."""
    cols = {k: [] for k in ("depth", "pitch", "v_h", "v_z", "f_h", "f_z", "window", "trial")}
    for w in windows:
        f = w.features
        m = ((f["sink_velocity"] > min_rate) & (f["depth"] > min_depth)
             & (f["grf_z"] > min_force))
        if not m.any():
            continue
        hx, hy = f["heading_x"][m], f["heading_y"][m]
        f_h = w.meas["grf_x"][m] * hx + w.meas["grf_y"][m] * hy
        cols["depth"].append(f["depth"][m])
        cols["pitch"].append(f["pitch"][m])
        cols["v_h"].append(f["v_h"][m])
        cols["v_z"].append(f["vc_z"][m])
        cols["f_h"].append(f_h)
        cols["f_z"].append(w.meas["grf_z"][m])
        cols["window"].append(np.full(int(m.sum()), w.index))
        cols["trial"].append(np.full(int(m.sum()), w.trial, dtype=object))
    return {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in cols.items()}


def _lag1(r: np.ndarray, groups: np.ndarray) -> float:
    num = den = 0.0
    for g in np.unique(groups):
        x = r[groups == g]
        if x.size > 2:
            x = x - x.mean()
            num += float(x[1:] @ x[:-1])
            den += float(x @ x)
    return max(0.0, min(0.95, num / den)) if den > 0 else 0.0


def calibrate(windows: Sequence[StanceWindow], terrain, *, n_slices: int,
              n_boot: int = 200, seed: int = 0,
              params: Sequence[str] = ("zeta", "phi_s")) -> Calibration:
    """Fit ``params`` (ζ, φ_s) on the sinking samples of ``windows``.

    Args:
        windows: stance windows (:func:`~.prepare.stance_windows`).
        terrain: the model :class:`~granular_mpc.terrain.TerrainModel` (granular).
        n_slices: contact patches per foot (the elastic displacement per patch is F/n).
        n_boot: one-step bootstrap replicates over trials.
        seed: bootstrap seed.
    """
    import casadi as ca
    from scipy.optimize import least_squares

    cfg = terrain.config
    theta0 = terrain.casadi_theta.copy()       # (zeta, phi_s, lambda, alpha_sh)
    names4 = ("zeta", "phi_s", "bulldozing_length", "sole_shear_alpha")
    idx = [names4.index(p) for p in params]
    initial = {p: float(theta0[names4.index(p)]) for p in params}
    not_id = {"bulldozing_length": False, "sole_shear_alpha": False, "added_mass_scale": False}
    s = sinking_samples(windows)
    N = int(s["depth"].size)
    if N < 20:
        return Calibration(dict(initial), initial, n_samples=N,
                           identified={**{p: False for p in params}, **not_id},
                           note="too few sinking samples to calibrate (rigid ground, or labels "
                                "that start after the loading): model values kept")
    K, tau = cfg.contact_stiffness, cfg.direction_time_constant
    u_h = s["v_h"] - s["f_h"] / (n_slices * K * tau)
    u_z = s["v_z"] - s["f_z"] / (n_slices * K * tau)
    X = np.vstack([s["depth"], s["pitch"], u_h, u_z])
    # F_z of one sample and its gradient in θ, as one SX function mapped over the samples
    # (5–6× faster than the same expression built over all samples as an MX graph, and
    # the same numbers bit for bit)
    f = terrain.casadi_foot_forces()
    x1, th1 = ca.SX.sym("x", 4), ca.SX.sym("th", 4)
    fz1 = f(x1, th1)[1]
    fun1 = ca.Function("cal", [x1, th1], [fz1, ca.jacobian(fz1, th1)]).map(N, "serial")

    def fun(Xdm, theta):
        F, Jrow = fun1(Xdm, ca.repmat(ca.DM(theta), 1, N))
        return F, np.asarray(Jrow).reshape(N, 4)        # row i: ∂F_z,i/∂θ

    Xdm = ca.DM(X)
    y = s["f_z"]

    def full(p):
        t = theta0.copy()
        t[idx] = p
        return t

    last: list = [None, None, None]            # (p, F, J) of the last evaluation

    def evaluate(p):
        # one CasADi call gives F and its Jacobian: least_squares asks for both at the
        # same point (the residual, then the Jacobian), so the last call is reused
        if last[0] is None or not np.array_equal(last[0], p):
            F, Jt = fun(Xdm, full(p))
            last[:] = [np.array(p, dtype=float), np.asarray(F).ravel(), np.asarray(Jt)]
        return last[1], last[2]

    def resid(p):
        return evaluate(p)[0] - y

    def jac(p):
        return evaluate(p)[1][:, idx]

    lo = np.array([CAL_PARAMS[p][0] for p in params])
    hi = np.array([CAL_PARAMS[p][1] for p in params])
    p0 = np.clip(theta0[idx], lo, hi)
    r0 = resid(p0)
    # robust start (the first samples of an impact carry added mass); then plain LS
    sol = least_squares(resid, p0, jac=jac, bounds=(lo, hi), loss="soft_l1",
                        f_scale=max(2.0, float(np.median(np.abs(r0)))))
    sol = least_squares(resid, sol.x, jac=jac, bounds=(lo, hi))
    p_hat = sol.x
    r = resid(p_hat)
    Jm = jac(p_hat)
    dof = max(N - len(params), 1)
    s2 = float(r @ r) / dof
    rho = _lag1(r, s["window"])
    infl = (1.0 + rho) / (1.0 - rho)
    # a rank-deficient Jacobian (e.g. every sample at one operating point: F = ζ g(φ_s)
    # cannot separate ζ from φ_s) has no covariance: its standard errors are NaN (never the
    # zeros that round-off's negative variances would clip to), so nothing is identified
    sv = np.linalg.svd(Jm, compute_uv=False) if Jm.size else np.zeros(0)
    if sv.size < len(params) or not np.all(np.isfinite(sv)) or sv[-1] <= RANK_TOL * sv[0]:
        cov = np.full((len(params), len(params)), np.nan)
    else:
        try:
            cov = np.linalg.inv(Jm.T @ Jm) * s2 * infl
        except np.linalg.LinAlgError:
            cov = np.full((len(params), len(params)), np.nan)
    var = np.diag(cov)
    se = np.where(var >= 0.0, np.sqrt(np.abs(var)), np.nan)
    corr = float(cov[0, 1] / (se[0] * se[1])) if len(params) == 2 and se.all() else float("nan")
    # one-step bootstrap over whole trials
    rng = np.random.default_rng(seed)
    trials = np.unique(s["trial"].astype(str))
    boot = []
    if trials.size >= 2 and n_boot > 0:
        tr = s["trial"].astype(str)
        members = {t: np.flatnonzero(tr == t) for t in trials}
        for _ in range(n_boot):
            pick = rng.choice(trials, trials.size, replace=True)
            ii = np.concatenate([members[t] for t in pick])
            Jb, rb = Jm[ii], r[ii]
            try:
                step = np.linalg.lstsq(Jb, -rb, rcond=None)[0]
            except np.linalg.LinAlgError:
                continue
            boot.append(np.clip(p_hat + step, lo, hi))
    boot = np.array(boot) if boot else np.zeros((0, len(params)))
    ci_b = {p: ([float(np.percentile(boot[:, k], 2.5)), float(np.percentile(boot[:, k], 97.5))]
                if len(boot) else [None, None]) for k, p in enumerate(params)}
    ci_g = {p: [float(p_hat[k] - 1.96 * se[k]), float(p_hat[k] + 1.96 * se[k])]
            for k, p in enumerate(params)}
    ident = {p: bool(np.isfinite(se[k]) and se[k] < 0.25 * abs(p_hat[k])
                     and lo[k] < p_hat[k] < hi[k]) for k, p in enumerate(params)}
    return Calibration(
        values={p: float(p_hat[k]) for k, p in enumerate(params)}, initial=initial,
        se_gn={p: float(se[k]) for k, p in enumerate(params)}, ci_gn=ci_g, ci_boot=ci_b,
        n_samples=N, n_stances=int(np.unique(s["window"]).size),
        rmse_before=float(np.sqrt(np.mean(r0 ** 2))), rmse_after=float(np.sqrt(np.mean(r ** 2))),
        correlation=corr, identified={**ident, **not_id},
        note=("bulldozing_length and sole_shear_alpha need sideways flow of the sole and the "
              "added mass (≈ 20 g) is below the force noise: kept at the model values"))


__all__ = ["calibrate", "Calibration", "sinking_samples", "CAL_PARAMS"]
