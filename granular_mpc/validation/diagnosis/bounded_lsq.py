"""Bounded least squares on a QR-reduced system: the fits of the screening
(``docs/validation.md`` §3.3) on one factorisation per set of rows.

A system y ≈ A β on n rows (A: (n, P), all the columns a regression may use) is reduced
once to the triangular factor of [A, y]: A = Q R, z = Qᵀ y and the part of y outside the
span of every column, ρ² = ‖(I − QQᵀ) y‖². For any subset S of the columns,

    ‖y − A_S β‖² = ‖z − R_S β‖² + ρ²,

so every fit on those rows — each candidate, each forward-selection step — is a
(≤ P)-row problem on R_S and z instead of an n-row one. Householder QR is backward stable
column by column, so columns of very different scales (units) lose nothing.

:func:`bvls` is the bounded-variable least-squares algorithm of Stark & Parker (1995) as
``scipy.optimize.lsq_linear(method="bvls")`` implements it (same initialisation, loops,
tolerances and termination tests, so the same solution), without its input checks, and
with the constant ρ² in its relative cost test.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Iterator

import numpy as np
from scipy.linalg.lapack import dgelsd, dgelsd_lwork
from threadpoolctl import ThreadpoolController

#: relative cost tolerance of the BVLS iterations (``lsq_linear``'s default ``tol``)
BVLS_TOL = 1e-10


@lru_cache(maxsize=1)
def _controller() -> ThreadpoolController:
    return ThreadpoolController()


@lru_cache(maxsize=1)
def _blas_libraries() -> tuple:
    return tuple(_controller().select(user_api="blas").lib_controllers)


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Context manager: BLAS on one thread. The factorisations here are small (≈ 10³ × 30):
    a second thread gains nothing on them, and on a loaded machine its spin-waits made a
    QR ≈ 50× slower (median 0.9 ms, mean 107 ms vs 1.8 ms at load 7).

    What ``ThreadpoolController.limit(limits=1, user_api="blas")`` does (set, then
    restore, each BLAS library's thread count), at a quarter of its cost per use (the
    screening enters it ≈ 1500 times)."""
    libs = _blas_libraries()
    before = [lib.get_num_threads() for lib in libs]
    for lib in libs:
        lib.set_num_threads(1)
    try:
        yield
    finally:
        for lib, n in zip(libs, before):
            lib.set_num_threads(n)


def lstsq_solution(A: np.ndarray, b: np.ndarray, rcond: float) -> np.ndarray:
    """``np.linalg.lstsq(A, b, rcond=rcond)[0]`` for a real (m, n) ``A`` and (m,) ``b``:
    the same LAPACK driver (``dgelsd``, minimum-norm, singular values below
    ``rcond`` · σ_max dropped; ``rcond`` < 0: machine precision) with its optimal workspace,
    the same solution bit for bit (``tests/test_bounded_lsq.py``), without numpy's
    per-call input handling (a third of a small solve's cost; the screening makes ≈ 10⁴).

    Raises:
        numpy.linalg.LinAlgError: the SVD did not converge.
    """
    m, n = A.shape
    if m == 0 or n == 0:
        return np.zeros(n)
    if m < n:                          # dgelsd returns x in b's storage: room for n values
        b = np.concatenate([b, np.zeros(n - m)])
    work, iwork, info = dgelsd_lwork(m, n, 1, rcond)
    if info:
        return np.linalg.lstsq(A, b[:m], rcond=rcond)[0]
    x, _, _, info = dgelsd(A, b, work, iwork, rcond)
    if info > 0:
        raise np.linalg.LinAlgError("SVD did not converge in Linear Least Squares")
    if info < 0:
        return np.linalg.lstsq(A, b[:m], rcond=rcond)[0]
    return x[:n]


def _kkt_optimality(g: np.ndarray, on_bound: np.ndarray) -> float:
    """Largest violation of the KKT conditions (gradient ``g``, bound state ±1 / 0)."""
    g_kkt = g * on_bound
    free = on_bound == 0
    g_kkt[free] = np.abs(g[free])
    return float(np.max(g_kkt))


def bvls(A: np.ndarray, b: np.ndarray, lb: np.ndarray, ub: np.ndarray, *,
         rows: int | None = None, cost_offset: float = 0.0,
         tol: float = BVLS_TOL) -> np.ndarray:
    """β minimising ‖b − Aβ‖² within lb ≤ β ≤ ub (bounded-variable least squares).

    Args:
        A: (m, k) matrix; b: (m,) target; lb, ub: (k,) bounds (±inf allowed, lb < ub).
        rows: rows of the system ``A`` stands for (a reduced system: the singular-value
            cutoff of its least-squares steps is the full system's, ε · max(rows, k));
            default m.
        cost_offset: ½ ρ², the cost the reduced system does not see (it enters only the
            relative termination test, as it would on the full system).
        tol: relative cost tolerance.

    Returns:
        (k,) solution.
    """
    m, n = A.shape
    rows = m if rows is None else rows
    # the unbounded solution first (cutoff: machine precision, as lsq_linear's)
    x = lstsq_solution(A, b, -1.0)
    if np.all((x >= lb) & (x <= ub)):
        return x
    rcond = np.finfo(float).eps * max(rows, n)
    on_bound = np.zeros(n)
    mask = x <= lb
    x[mask] = lb[mask]
    on_bound[mask] = -1
    mask = x >= ub
    x[mask] = ub[mask]
    on_bound[mask] = 1
    free_set = on_bound == 0
    active_set = ~free_set
    free_set, = np.nonzero(free_set)
    r = A.dot(x) - b
    cost = 0.5 * np.dot(r, r) + cost_offset
    g = A.T.dot(r)
    iteration = 0
    # initialisation: least squares on the free variables until it is feasible
    while free_set.size > 0:
        iteration += 1
        z = lstsq_solution(A[:, free_set], b - A.dot(x * active_set), rcond)
        lbv = z < lb[free_set]
        ubv = z > ub[free_set]
        v = lbv | ubv
        if np.any(lbv):
            ind = free_set[lbv]
            x[ind] = lb[ind]
            active_set[ind] = True
            on_bound[ind] = -1
        if np.any(ubv):
            ind = free_set[ubv]
            x[ind] = ub[ind]
            active_set[ind] = True
            on_bound[ind] = 1
        ind = free_set[~v]
        x[ind] = z[~v]
        r = A.dot(x) - b
        cost = 0.5 * np.dot(r, r) + cost_offset
        g = A.T.dot(r)
        if np.any(v):
            free_set = free_set[~v]
        else:
            break
    max_iter = n + iteration
    status = None
    optimality = _kkt_optimality(g, on_bound)
    for iteration in range(iteration, max_iter):
        if optimality < tol:
            status = 1
        if status is not None:
            break
        move_to_free = np.argmax(g * on_bound)
        on_bound[move_to_free] = 0
        while True:
            free_set = on_bound == 0
            active_set = ~free_set
            free_set, = np.nonzero(free_set)
            x_free = x[free_set]
            lb_free = lb[free_set]
            ub_free = ub[free_set]
            z = lstsq_solution(A[:, free_set], b - A.dot(x * active_set), rcond)
            lbv, = np.nonzero(z < lb_free)
            ubv, = np.nonzero(z > ub_free)
            v = np.hstack((lbv, ubv))
            if v.size > 0:
                alphas = np.hstack((lb_free[lbv] - x_free[lbv],
                                    ub_free[ubv] - x_free[ubv])) / (z[v] - x_free[v])
                i = np.argmin(alphas)
                i_free = v[i]
                alpha = alphas[i]
                x_free *= 1 - alpha
                x_free += alpha * z
                x[free_set] = x_free
                on_bound[free_set[i_free]] = -1 if i < lbv.size else 1
            else:
                x[free_set] = z
                break
        r = A.dot(x) - b
        cost_new = 0.5 * np.dot(r, r) + cost_offset
        if cost - cost_new < tol * cost:
            status = 2
        cost = cost_new
        g = A.T.dot(r)
        optimality = _kkt_optimality(g, on_bound)
    return x


@dataclass(frozen=True, eq=False)
class ReducedSystem:
    """y ≈ A β on ``n`` rows, reduced to the triangular factor of [A, y].

    Attributes:
        R: (min(n, P), P) triangular factor of A (A = Q R).
        z: Qᵀ y, (min(n, P),).
        rss_outside: ρ² = ‖(I − QQᵀ) y‖², the squared residual no column removes.
        n: rows of the system.
    """

    R: np.ndarray
    z: np.ndarray
    rss_outside: float
    n: int
    #: (columns, bounds) → (β, RSS) of the fits made so far: the bootstrap's forward
    #: selection and refits ask for the same fit again (≈ 40 % of the calls)
    _fits: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @classmethod
    def of(cls, A: np.ndarray, y: np.ndarray) -> "ReducedSystem":
        """Reduce the (n, P) columns ``A`` and the (n,) target ``y`` (Q is never formed)."""
        n, P = A.shape
        with one_blas_thread():
            Ra = np.linalg.qr(np.column_stack([A, y]), mode="r")
        rest = float(Ra[P, P] ** 2) if Ra.shape[0] > P else 0.0
        return cls(Ra[:P, :P], Ra[:P, P], rest, int(n))

    def fit(self, cols: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> tuple[np.ndarray, float]:
        """(β, RSS) of the bounded fit on the columns ``cols`` (indices into A): BVLS on
        unit-norm columns, as :func:`~.regression.fit_bounded` defines it."""
        if not len(cols):
            return np.zeros(0), float(self.z @ self.z) + self.rss_outside
        key = (cols.tobytes(), np.asarray(lb, dtype=float).tobytes(),
               np.asarray(ub, dtype=float).tobytes())
        done = self._fits.get(key)
        if done is None:
            done = self._fits[key] = self._fit(cols, lb, ub)
        return done[0].copy(), done[1]

    def _fit(self, cols: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> tuple[np.ndarray, float]:
        """:meth:`fit`, computed."""
        A = self.R[:, cols]
        scale = np.sqrt((A ** 2).sum(axis=0))
        scale[scale == 0] = 1.0
        beta = bvls(A / scale, self.z, lb * scale, ub * scale, rows=self.n,
                    cost_offset=0.5 * self.rss_outside) / scale
        r = self.z - A @ beta
        return beta, float(r @ r) + self.rss_outside


__all__ = ["ReducedSystem", "bvls", "lstsq_solution", "one_blas_thread", "BVLS_TOL"]
