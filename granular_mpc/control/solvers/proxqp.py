"""Our QP problem / solution types and a persistent, warm-started ProxSuite dense solver.

    minimise ½ xᵀ H x + gᵀ x   s.t.   A x = b,   l ≤ C x ≤ u,   lb ≤ x ≤ ub

No ProxSuite type leaves this module: callers build a :class:`QPProblem`, get a
:class:`QPSolution` whose :attr:`~QPSolution.status` is a :class:`QPStatus`. The solver
object keeps one ProxSuite ``dense.QP`` alive for a fixed problem size, ``update``-s it each
tick and warm-starts from the previous result (maintainers' advice, proxsuite issues 226 and
333). Warm start is switched on only after a first successful solve: with proxsuite 0.8,
``WARM_START_WITH_PREVIOUS_RESULT`` set between ``init`` and the first ``solve`` then
``update`` + ``solve`` crashes the process.
"""

from __future__ import annotations

import enum
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ...exceptions import SolverError

#: ProxSuite builds: ``generic`` = the SSE2 build (bit-reproducible: the default),
#: ``native`` = ProxSuite's own choice (AVX2 / AVX-512 where the CPU has them; MPC solves
#: ≈ 40 % faster, real-time factor ≈ 15 % higher, runs not bit-reproducible). Chosen with
#: the environment variable GRANULAR_MPC_PROXSUITE.
PROXSUITE_BUILDS = ("native", "generic")
DEFAULT_BUILD = "generic"

#: ProxSuite dense backends by our name (:class:`ProxQPSolver`'s ``backend``).
DENSE_BACKENDS = {"automatic": "Automatic", "primal_dual_ldlt": "PrimalDualLDLT",
                  "primal_ldlt": "PrimalLDLT"}


def load_proxsuite():
    """The ProxSuite binding module, loaded once per process.

    ProxSuite's vectorised (AVX2) build gives results that depend on the heap alignment of
    its workspace: the same QP solved twice by fresh solver objects can differ by ~1e-10,
    and the closed loop amplifies that until two runs of one scenario part after ~0.5 s
    (statistically the same, not bit for bit). The generic build is deterministic, and the
    default: two runs of one scenario and seed give identical logs;
    ``GRANULAR_MPC_PROXSUITE=native`` opts into the faster vectorised build. The builds
    cannot be mixed in one process (nanobind aborts), so the choice is made at the first
    import; if ``proxsuite`` was already imported, that build is used.
    """
    import importlib
    import importlib.util
    import os
    import sys

    build = os.environ.get("GRANULAR_MPC_PROXSUITE", DEFAULT_BUILD)
    if build not in PROXSUITE_BUILDS:
        raise SolverError(f"environment variable GRANULAR_MPC_PROXSUITE = {build!r} is not a "
                          f"ProxSuite build; allowed: {', '.join(PROXSUITE_BUILDS)}")
    pkg = sys.modules.get("proxsuite")
    if pkg is None and build == "generic":
        spec = importlib.util.find_spec("proxsuite")
        if spec is not None and spec.submodule_search_locations:
            pkg = importlib.util.module_from_spec(spec)
            sys.modules["proxsuite"] = pkg
            try:
                sub = importlib.import_module("proxsuite.proxsuite_pywrap")
            except ImportError:
                del sys.modules["proxsuite"]
                pkg = None
            else:
                pkg._submodule = sub
                pkg.__getattr__ = lambda name: getattr(sub, name)
                pkg.__dir__ = lambda: dir(sub)
    if pkg is None:
        pkg = importlib.import_module("proxsuite")
    return pkg


def proxsuite_build() -> str:
    """Name of the loaded ProxSuite binding (e.g. ``proxsuite_pywrap_avx2``)."""
    return load_proxsuite()._submodule.__name__.rsplit(".", 1)[-1]


class QPStatus(enum.Enum):
    """Outcome of one solve."""

    SOLVED = "solved"
    MAX_ITER = "max_iter"           # stopped before reaching the tolerance
    PRIMAL_INFEASIBLE = "primal_infeasible"
    DUAL_INFEASIBLE = "dual_infeasible"
    NON_FINITE = "non_finite"       # the data or the result contained NaN/inf
    FAILED = "failed"

    @property
    def ok(self) -> bool:
        return self is QPStatus.SOLVED


@dataclass
class QPProblem:
    """A dense convex QP (all arrays float64; empty blocks may be None)."""

    H: np.ndarray
    g: np.ndarray
    A: np.ndarray | None = None
    b: np.ndarray | None = None
    C: np.ndarray | None = None
    l: np.ndarray | None = None
    u: np.ndarray | None = None
    lb: np.ndarray | None = None
    ub: np.ndarray | None = None
    #: the one allocation every array above is a view of, if there is one (the MPC's QP):
    #: the finiteness check then tries one reduction over it before the per-array ones
    buffer: np.ndarray | None = None

    @property
    def n(self) -> int:
        return self.H.shape[0]

    @property
    def n_eq(self) -> int:
        return 0 if self.A is None else self.A.shape[0]

    @property
    def n_in(self) -> int:
        return 0 if self.C is None else self.C.shape[0]

    def check_size(self, n: int, n_eq: int, n_in: int) -> None:
        """Raise :class:`SolverError` unless the problem has ``n`` variables, ``n_eq``
        equality and ``n_in`` inequality rows (a solver's fixed sizes)."""
        if (self.H.shape[0], 0 if self.A is None else self.A.shape[0],
                0 if self.C is None else self.C.shape[0]) != (n, n_eq, n_in):
            raise SolverError(f"QP size {(self.n, self.n_eq, self.n_in)} differs from the "
                              f"solver's {(n, n_eq, n_in)}")

    def check(self) -> None:
        n = self.n
        if self.H.shape != (n, n) or self.g.shape != (n,):
            raise SolverError(f"QP shapes: H {self.H.shape}, g {self.g.shape}")
        for name in ("H", "g", "A", "b", "C"):
            arr = getattr(self, name)
            if arr is not None and not np.isfinite(arr).all():
                raise SolverError(f"QP data {name} is not finite")

    def objective(self, x: np.ndarray) -> float:
        return float(0.5 * x @ self.H @ x + self.g @ x)

    def violation(self, x: np.ndarray) -> float:
        """Largest constraint violation of ``x``."""
        worst = 0.0
        if self.A is not None and self.A.size:
            worst = max(worst, float(np.abs(self.A @ x - self.b).max()))
        if self.C is not None and self.C.size:
            cx = self.C @ x
            worst = max(worst, float(np.max(self.l - cx, initial=0.0)),
                        float(np.max(cx - self.u, initial=0.0)))
        if self.lb is not None:
            worst = max(worst, float(np.max(self.lb - x, initial=0.0)),
                        float(np.max(x - self.ub, initial=0.0)))
        return worst


def _finite(p: QPProblem) -> bool:
    """Whether the QP data can be handed to ProxSuite: H, g, A, b, C finite, l and u free of
    NaN (±inf allowed: a free side). A sum is non-finite iff some term is non-finite (or
    it overflows, which these magnitudes never do): one reduction per array, not two, and
    the sums added (a sum of sums is non-finite iff one of them is: inf − inf is NaN).
    The reductions are ``np.add.reduce`` / ``np.minimum.reduce`` called directly (what
    ``ndarray.sum`` / ``min`` run, without their Python wrappers). With ``p.buffer`` a
    finite sum of it settles it in one reduction (every array finite, so l, u too);
    otherwise — a free side at ±inf, or bad data — the arrays are checked one by one."""
    if p.buffer is not None:
        with np.errstate(invalid="ignore"):     # −inf + inf (two free sides) is NaN: fine
            if math.isfinite(float(_add_reduce(p.buffer, None))):
                return True
    total = 0.0
    for arr in (p.H, p.g, p.A, p.b, p.C):
        if arr is not None:
            total += float(_add_reduce(arr, None))
    if not math.isfinite(total):
        return False
    for arr in (p.l, p.u):
        # min propagates NaN (and only NaN: ±inf are ordered)
        if arr is not None and arr.size and math.isnan(float(_min_reduce(arr, None))):
            return False
    return True


#: the ufunc reductions :func:`_finite` and the solution check call directly
_add_reduce, _min_reduce = np.add.reduce, np.minimum.reduce


@dataclass
class QPSolution:
    x: np.ndarray
    status: QPStatus
    iterations: int = 0
    solve_ms: float = 0.0
    objective: float = float("nan")
    y: np.ndarray | None = None     # equality multipliers
    z: np.ndarray | None = None     # inequality multipliers
    retried: bool = False           # the warm-started attempt failed, a cold one was made
    #: ProxSuite's own timings of the last attempt (solver built with ``timings=True``;
    #: else nan): ``setup_ms`` its model update and preconditioning, ``kernel_ms`` its
    #: iterations [ms]; ``mu_updates``: how often it changed its penalties μ there
    setup_ms: float = float("nan")
    kernel_ms: float = float("nan")
    mu_updates: int = 0


@dataclass
class ProxQPSolver:
    """Persistent dense ProxSuite solver for problems of one size.

    Args:
        n, n_eq, n_in: fixed dimensions; ``box``: whether box bounds lb ≤ x ≤ ub are used.
        eps_abs: absolute tolerance; ``max_iter``: iteration cap per solve.
        backend: ProxSuite's dense linear-algebra backend, one of :data:`DENSE_BACKENDS`:
            ``automatic`` (ProxSuite's choice from the sizes), ``primal_dual_ldlt`` or
            ``primal_ldlt``. Same problem and tolerance either way; the iteration count
            differs (the MPC's QP: 2.9 warm-started iterations with ``primal_dual_ldlt``
            against 6.0 with the ``primal_ldlt`` that ``automatic`` picks for it).
        mu_in_reset: if set, the inequality penalty ``mu_in`` each warm-started ``update``
            starts from (ProxSuite's default is 0.1). None: ProxSuite keeps the previous
            solve's ``mu_in``, which shrinks from solve to solve (0.1 → 1e-8 over ≈ 40
            MPC ticks) until the warm-started subproblems are badly conditioned.
        eps_primal_inf: ProxSuite's primal infeasibility tolerance (None: its default,
            1e-4). For a QP that is feasible by construction a smaller one keeps ProxSuite
            from declaring it infeasible on its way (measured on the MPC's QP with the
            ``primal_dual_ldlt`` backend: a cold solve of a tick where x = 0 is feasible
            ended "primal infeasible" after 50 iterations at 1e-4, solved in 53 at 1e-5 …
            1e-8).
        multipliers: whether a solution carries the multipliers (:attr:`QPSolution.y`,
            :attr:`QPSolution.z`, copied out of ProxSuite); False leaves them None and saves
            the two copies (the MPC, which reads only ``x``). ``x`` is the same either way.
        settings: further ProxSuite settings by name (``rho``-, ``mu``- and refinement
            parameters of ``proxsuite.proxqp.Settings``, e.g. ``{"default_rho": 1e-7}``),
            applied to every fresh ProxSuite object; an unknown name is a
            :class:`SolverError`. For studies of the solver (``bench/proxsuite_settings.py``).
        timings: whether each solution carries ProxSuite's own split of its time
            (:attr:`QPSolution.setup_ms`, :attr:`QPSolution.kernel_ms`); the numbers of the
            solve are the same either way.
    """

    n: int
    n_eq: int
    n_in: int
    box: bool = False
    eps_abs: float = 1e-6
    max_iter: int = 200
    backend: str = "automatic"
    mu_in_reset: float | None = None
    eps_primal_inf: float | None = None
    multipliers: bool = True
    settings: dict | None = None
    timings: bool = False
    _qp: object = field(default=None, repr=False)
    _initialised: bool = field(default=False, repr=False)
    _warm: bool = field(default=False, repr=False)
    _status_table: dict = field(default_factory=dict, repr=False)
    _warm_guess: object = field(default=None, repr=False)
    _cold_guess: object = field(default=None, repr=False)
    _backend: object = field(default=None, repr=False)

    def __post_init__(self) -> None:
        px = self._px = load_proxsuite()
        out = px.proxqp.QPSolverOutput
        # ProxSuite outcome → ours, looked up once (nanobind attribute access is slow)
        self._status_table = {out.PROXQP_SOLVED: QPStatus.SOLVED,
                              out.PROXQP_MAX_ITER_REACHED: QPStatus.MAX_ITER,
                              out.PROXQP_PRIMAL_INFEASIBLE: QPStatus.PRIMAL_INFEASIBLE,
                              out.PROXQP_DUAL_INFEASIBLE: QPStatus.DUAL_INFEASIBLE}
        self._warm_guess = px.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
        self._cold_guess = px.proxqp.InitialGuess.NO_INITIAL_GUESS
        if self.backend not in DENSE_BACKENDS:
            raise SolverError(f"ProxSuite dense backend {self.backend!r} unknown; allowed: "
                              f"{', '.join(DENSE_BACKENDS)}")
        self._backend = getattr(px.proxqp.dense.DenseBackend, DENSE_BACKENDS[self.backend])
        known = ({a for a in dir(px.proxqp.Settings()) if a[0] != "_"}
                 if self.settings else set())
        unknown = sorted(set(self.settings or {}) - known)
        if unknown:
            raise SolverError(f"ProxSuite settings {', '.join(unknown)} unknown; allowed: "
                              f"{', '.join(sorted(known))}")
        self._reset()

    def solve(self, p: QPProblem) -> QPSolution:
        """Solve ``p`` (same dimensions every call); never raises for a numerical failure.

        The arrays of ``p`` are copied into ProxSuite's model, so a caller may refill the
        same buffers for its next problem. Its sizes and data are checked first: a
        non-finite problem gives :attr:`QPStatus.NON_FINITE` without calling ProxSuite.
        """
        p.check_size(self.n, self.n_eq, self.n_in)
        if not _finite(p):
            return QPSolution(np.zeros(self.n), QPStatus.NON_FINITE)
        args = [p.H, p.g, p.A, p.b, p.C, p.l, p.u]
        if self.box:
            args += [p.lb, p.ub]
        t0 = time.perf_counter()
        warm = self._warm
        sol = self._attempt(args)
        retried = False
        if not sol.status.ok and warm:
            # a warm start from a very different previous problem can make ProxSuite stop
            # early (or declare infeasibility): retry once from scratch
            self._reset()
            sol = self._attempt(args)
            retried = True
        sol.solve_ms = (time.perf_counter() - t0) * 1e3
        sol.retried = retried
        if not sol.status.ok:
            self._reset()
        elif not self._warm:
            # safe only now (see module docstring)
            self._qp.settings.initial_guess = self._warm_guess
            self._warm = True
        return sol

    def _attempt(self, args) -> QPSolution:
        try:
            if not self._initialised:
                self._qp.init(*args)
                self._initialised = True
            elif self.mu_in_reset is None:
                self._qp.update(*args)
            else:
                self._qp.update(*args, mu_in=self.mu_in_reset)
            self._qp.solve()
        except (ValueError, RuntimeError):  # ProxSuite's own errors on bad data
            self._reset()
            return QPSolution(np.zeros(self.n), QPStatus.FAILED)
        r = self._qp.results
        info = r.info
        status = self._status_table.get(info.status, QPStatus.FAILED)
        x = np.array(r.x)
        if not math.isfinite(float(_add_reduce(x, None))):
            status = QPStatus.NON_FINITE
        if not self.multipliers:
            sol = QPSolution(x, status, int(info.iter), 0.0, float(info.objValue))
        else:
            sol = QPSolution(x, status, int(info.iter), 0.0, float(info.objValue),
                             np.array(r.y), np.array(r.z))
        if self.timings:        # ProxSuite reports microseconds
            sol.setup_ms, sol.kernel_ms = info.setup_time * 1e-3, info.solve_time * 1e-3
            sol.mu_updates = int(info.mu_updates)
        return sol

    def _reset(self) -> None:
        """A fresh ProxSuite object, cold-started (after a failure a bad previous result is
        no warm start)."""
        px = self._px
        self._qp = px.proxqp.dense.QP(self.n, self.n_eq, self.n_in, self.box,
                                      px.proxqp.dense.HessianType.Dense, self._backend)
        s = self._qp.settings
        s.eps_abs = self.eps_abs
        s.eps_rel = 0.0
        s.max_iter = self.max_iter
        s.verbose = False
        s.initial_guess = self._cold_guess
        if self.eps_primal_inf is not None:
            s.eps_primal_inf = self.eps_primal_inf
        for name, value in (self.settings or {}).items():
            setattr(s, name, value)
        s.compute_timings = self.timings
        self._initialised = False
        self._warm = False


__all__ = ["QPStatus", "QPProblem", "QPSolution", "ProxQPSolver", "DENSE_BACKENDS"]
