"""The multi-step functions of the compiled plant (:mod:`.compiled`), built from its one-step
CasADi function with ``mapaccum``: ``plant_chunk`` (``k`` steps, the last state) and
``plant_steps<k>`` (``k`` steps, every step's state and aux, with the per-step checks)."""

from __future__ import annotations

import casadi as ca

from .step_sx import AUX_SLICES

#: a state whose entries are all below this in magnitude has a finite sum (the per-step
#: check of :meth:`~.compiled.CompiledPlant.advance_steps` cannot fire; nx × 1e300 < 1.7e308)
BOUND = 1e300


def chunk_function(step: ca.Function, k: int) -> ca.Function:
    """``plant_chunk(x, u, θ, w) -> (x_k, aux)``: ``k`` steps with the command held.

    ``aux`` is the last step's auxiliary output with its last entry (largest |v|) the
    maximum over the ``k`` steps.
    """
    X, U = ca.MX.sym("x", step.size1_in(0)), ca.MX.sym("u", step.size1_in(1))
    T, W = ca.MX.sym("theta", step.size1_in(2)), ca.MX.sym("wrench", step.size1_in(3))
    acc = step.mapaccum("plant_acc", k)
    xs, aux = acc(X, ca.repmat(U, 1, k), ca.repmat(T, 1, k), ca.repmat(W, 1, k))
    aux_out = ca.vertcat(aux[:-1, -1], ca.mmax(aux[-1, :]))
    return ca.Function("plant_chunk", [X, U, T, W], [xs[:, -1], aux_out],
                       ["x", "u", "theta", "wrench"], ["x_next", "aux"])


def steps_function(step: ca.Function, k: int, max_speed: float) -> ca.Function:
    """``plant_steps<k>(x, u, θ, w) -> (xs, auxs, info)``: ``k`` steps with the command
    held, every step's result (the same compiled step as ``plant_step``, called ``k`` times
    by ``mapaccum``).

    Outputs: ``xs`` (nx × k) the state after each step, ``auxs`` (n_aux × k) each step's
    auxiliary output (column j: step j), and ``info`` (3): the number of failed tests
    ``|x_ij| < BOUND`` and ``speed_j < max_speed`` (a NaN fails them: 0 means no step's
    state has a non-finite sum or exceeds the velocity bound; ``BOUND`` = 1e300, nx ×
    1e300 < 1.7e308), then per foot 1 + the last step that evaluated its contact (0:
    none) — comparisons and selections of whole numbers only, no arithmetic on the state.
    """
    X, U = ca.MX.sym("x", step.size1_in(0)), ca.MX.sym("u", step.size1_in(1))
    T, W = ca.MX.sym("theta", step.size1_in(2)), ca.MX.sym("wrench", step.size1_in(3))
    acc = step.mapaccum(f"plant_acc{k}", k)
    xs, aux = acc(X, ca.repmat(U, 1, k), ca.repmat(T, 1, k), ca.repmat(W, 1, k))
    failed = (ca.sum1(ca.sum2(1 - (ca.fabs(xs) < BOUND)))
              + ca.sum2(1 - (aux[-1, :] < max_speed)))
    last = []
    for foot in (0, 1):
        ev = aux[AUX_SLICES[foot, "evaluated"].start, :]
        j_last = ca.MX(0)
        for j in range(k):
            j_last = ca.if_else(ev[j] > 0.5, j + 1, j_last)
        last.append(j_last)
    return ca.Function(f"plant_steps{k}", [X, U, T, W], [xs, aux, ca.vertcat(failed, *last)],
                       ["x", "u", "theta", "wrench"], ["xs", "auxs", "info"])


__all__ = ["BOUND", "chunk_function", "steps_function"]
