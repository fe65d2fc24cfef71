"""A terrain-force effect evaluated on the sinking samples of the foot-force equation
error (``docs/validation.md`` §3.6, §3.7).

The added or candidate effects are evaluated on each sinking sample as the contact law
evaluates them on one of the foot's patches, from the foot-level measured state: the
patch's share of the law's force (``f_terrain``, also taken as the yield force
``f_yield_z``: the medium yields while the sole sinks), the sole arc's submerged
horizontal area at the measured depth (pitch ignored), the velocity from the measured
forward, lateral and vertical components, the vertical acceleration only, the deepest
depth so far from the measured rise, and the touchdown point under the sole
(``intrusion`` = (0, 0, depth)); the foot's force is the patch force times the number of
patches. Used by the force-leftover test (:mod:`.force_leftover`) and by the force start
of a user's or proposed term (:mod:`.force_start`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from ...effects import EffectInfo
from ...effects.state import PatchState
from ...effects.tracing import trace_terrain_force
from .features import ForceSamples, force_samples, sample_columns


def submerged_area(depth: np.ndarray, radius: float, chord: float, width: float) -> np.ndarray:
    """Horizontal area [m²] of a level sole arc of ``radius`` and ``chord``, ``width``
    wide, submerged to ``depth`` [m]: the arc's chord at that depth times the width."""
    d = np.clip(np.asarray(depth, float), 0.0, None)
    half = np.sqrt(np.clip(2.0 * radius * d - d * d, 0.0, None))
    return np.minimum(2.0 * half, chord) * width


@dataclass(frozen=True, eq=False)
class SinkingStates:
    """The patch state of every sinking sample, as the rows of a CasADi input.

    Attributes:
        names: the state quantities, one row of ``X`` each.
        X: (len(names), N) their values.
        n_slices: patches per foot (the foot's force is the patch force times it).
        width: one patch's width [m]; density [kg/m³]; dt: the sample interval [s].
    """

    names: tuple[str, ...]
    X: np.ndarray
    n_slices: int
    width: float
    density: float
    dt: float

    @property
    def n(self) -> int:
        return int(self.X.shape[1])

    def symbolic(self):
        """(x, state): a CasADi symbol of the rows and the :class:`PatchState` over it."""
        import casadi as ca

        x = ca.SX.sym("x", len(self.names))
        sx = dict(zip(self.names, (x[i] for i in range(len(self.names)))))
        zero = 0.0
        state = PatchState(
            depth=sx["depth"], in_contact=1.0, p_c=(zero, zero, -sx["depth"]),
            v_c=(sx["v_x"], sx["v_y"], sx["v_z"]), a_c=(zero, zero, sx["a_z"]),
            intrusion=(zero, zero, sx["depth"]), heading=(sx["hx"], sx["hy"], zero),
            lateral=(-sx["hy"], sx["hx"], zero), f_terrain=(sx["f_x"], sx["f_y"], sx["f_z"]),
            f_yield_z=sx["f_z"], area_h=sx["area"], width=self.width, density=self.density,
            dt=self.dt, depth_max=sx["depth_max"], t_stance=sx["t_stance"], foot=sx["foot"],
            depth_rate=sx["depth_rate"])
        return x, state

    def foot_force(self, F: np.ndarray) -> dict[str, np.ndarray]:
        """A patch force (3, N) in W as the foot's forward (``h``) and vertical (``z``)
        force [N]."""
        hx, hy = self.X[self.names.index("hx")], self.X[self.names.index("hy")]
        F = np.asarray(F, float) * self.n_slices
        return {"h": F[0] * hx + F[1] * hy, "z": F[2]}


def sinking_states(cols: Mapping[str, np.ndarray], law_h: np.ndarray, law_z: np.ndarray, *,
                   n_slices: int, radius: float, chord: float, width: float, density: float,
                   dt: float) -> SinkingStates:
    """The patch state of each sample (the module docstring).

    Args:
        cols: :func:`.features.sample_columns` of the samples.
        law_h, law_z: the law's forward and vertical force on the foot at each sample [N].
        n_slices: patches per foot; radius, chord, width: the sole [m]; density [kg/m³];
            dt: the sample interval [s].
    """
    hx, hy = np.asarray(cols["heading_x"], float), np.asarray(cols["heading_y"], float)
    v_h, v_l, v_z = (np.asarray(cols[k], float) for k in ("v_h", "v_l", "v_z"))
    depth = np.asarray(cols["depth"], float)
    share = 1.0 / n_slices
    rows = {
        "depth": depth, "v_x": v_h * hx - v_l * hy, "v_y": v_h * hy + v_l * hx, "v_z": v_z,
        "a_z": np.asarray(cols["a_z"], float), "hx": hx, "hy": hy,
        "f_x": law_h * hx * share, "f_y": law_h * hy * share, "f_z": law_z * share,
        "area": submerged_area(depth, radius, chord, width * share),
        "depth_max": depth + np.clip(np.asarray(cols["rise"], float), 0.0, None),
        "t_stance": np.asarray(cols["t_stance"], float),
        "foot": np.asarray(cols["foot"], float),
        "depth_rate": np.asarray(cols["depth_rate"], float),
    }
    X = np.vstack([np.asarray(v, float).reshape(-1) for v in rows.values()])
    return SinkingStates(tuple(rows), X, int(n_slices), width * share, float(density), float(dt))


def equation_states(problem, theta: Mapping[str, float]) -> tuple[ForceSamples, SinkingStates]:
    """The foot-force equation error of a diagnosis problem at the calibrated ``theta``
    (:func:`.features.force_samples`) and the patch states of its sinking samples, the
    law's force on the foot being the measured force minus that error.

    Args:
        problem: the diagnosis problem (:class:`~.problem.Problem`).
        theta: the calibrated parameters (ζ).
    """
    biped = problem.biped
    n_slices = int(biped.config.foot.slices)
    terrain = problem.replay_model.terrain
    fs = force_samples(problem.windows, terrain, theta, n_slices=n_slices)
    cols = sample_columns(problem.windows)
    foot = biped.config.foot
    states = sinking_states(cols, cols["f_h"] - fs.target["h"], cols["f_z"] - fs.target["z"],
                            n_slices=n_slices, radius=foot.radius, chord=foot.chord,
                            width=foot.width, density=float(terrain.config.density),
                            dt=1.0 / float(problem.sample_rate_hz))
    return fs, states


def force_function(states: SinkingStates, info: EffectInfo, values: Mapping[str, float],
                   free: str | None = None) -> Callable[[float | None], dict[str, np.ndarray]]:
    """The effect's foot force on the samples, as a function of one parameter.

    Args:
        states: the samples' patch states.
        info: a terrain-force effect; values: its parameters.
        free: the parameter the returned function takes (None: all at ``values``; the
            function then ignores its argument).

    Returns:
        value → {``h``: forward, ``z``: vertical} foot force [N] at each sample.
    """
    import casadi as ca

    from ...terrain.closed_form import casadi_ops

    x, state = states.symbolic()
    p_sym = ca.SX.sym("p")
    p = {k: (p_sym if k == free else float(values[k])) for k in info.params}
    f = trace_terrain_force(info, casadi_ops(), state, p)
    fn = ca.Function("effect", [x, p_sym], [ca.vertcat(*[ca.SX(fi) for fi in f])])
    n = states.n
    mapped = fn.map(n) if n else None

    def at(value: float | None) -> dict[str, np.ndarray]:
        if mapped is None:
            return {"h": np.zeros(0), "z": np.zeros(0)}
        v = float(values.get(free, 0.0)) if value is None else float(value)
        return states.foot_force(np.asarray(mapped(states.X, np.full((1, n), v))))

    return at


__all__ = ["SinkingStates", "sinking_states", "equation_states", "force_function",
           "submerged_area"]
