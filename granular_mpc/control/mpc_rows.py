"""The ground polytope's rows the MPC's QP needs: rows implied by the others dropped.

Each (step, foot in contact) block of the MPC's QP carries the polytope's cone rows
(``h = 0``) on each of the foot's ``n_points`` contact points, its capacity rows (``h > 0``)
on the foot's total force, and the box ``0 ≤ f_z ≤ f_max / n_points`` on each point. A row
that every force satisfying the other rows and the box satisfies is redundant: the QP
without it has the same feasible set, hence the same optimum, and ProxSuite does less
work per tick (measured on 140 recorded sand-walk ticks, update + solve + read-out:
0.454 ms against 0.509 ms median CPU time with the two lateral capacity rows of dry sand
dropped, n_in 144 → 120; docs/speed.md, "Session 21: MPC tick").

Redundancy is decided once per model by one linear program per row, in the foot's
heading frame (the QP's rows are these rotated by the yaw, which leaves the box on f_z
and the set's shape alone): ``max r·f`` over the remaining rows (without any copy of the
candidate) and the box; the row is dropped if that maximum is at most its bound plus
:data:`REDUNDANCY_TOL` (relative to the bound's scale). The polytope the controller uses
at a tick is the share-scaled one (``h·s``, ``f_max·s``, s ∈ [0, 1]): a cone scaling of
the set at s = 1, so a row redundant at s = 1 is redundant at every share.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog

from .contact_model import ForcePolytope

#: slack allowed in the redundancy test, relative to max(|h|, f_max): a dropped row may be
#: exceeded by at most this fraction of the polytope's scale (dry sand's lateral capacity
#: rows are implied to ≈ 1e-8 of it, the LP's own round-off)
REDUNDANCY_TOL = 1e-7


@dataclass(frozen=True)
class PolytopeRows:
    """The polytope rows the MPC keeps (foot heading frame).

    Attributes:
        cone: (n_cone, 3) rows with h = 0, applied to each contact point.
        capacity: (n_cap, 3) rows with h > 0, applied to the foot's total force.
        h_capacity: (n_cap,) their bounds [N].
        dropped: indices (into the polytope's ``G``) of the rows found redundant.
    """

    cone: np.ndarray
    capacity: np.ndarray
    h_capacity: np.ndarray
    dropped: tuple[int, ...]


def _pair_rows(poly: ForcePolytope, rows: list[int], n_points: int) -> tuple[np.ndarray,
                                                                             np.ndarray]:
    """``A f ≤ b`` of one block (f: the points' forces stacked, 3 n_points) from the
    polytope rows ``rows``: cone rows on each point, capacity rows on the sum."""
    A, b = [], []
    for i in rows:
        g = poly.G[i]
        if poly.h[i] <= 0.0:
            for p in range(n_points):
                a = np.zeros(3 * n_points)
                a[3 * p:3 * p + 3] = g
                A.append(a)
                b.append(0.0)
        else:
            A.append(np.tile(g, n_points))
            b.append(float(poly.h[i]))
    if not A:
        return np.zeros((0, 3 * n_points)), np.zeros(0)
    return np.array(A), np.array(b)


def row_is_redundant(poly: ForcePolytope, row: int, others: list[int],
                     n_points: int) -> bool:
    """Whether polytope row ``row`` (on point 0 if a cone row, on the sum if a capacity
    row) is implied by the rows ``others`` and the box ``0 ≤ f_z ≤ f_max / n_points``."""
    npair = 3 * n_points
    A, b = _pair_rows(poly, others, n_points)
    c = np.zeros(npair)
    if poly.h[row] <= 0.0:
        c[0:3] = poly.G[row]
        bound = 0.0
    else:
        c[:] = np.tile(poly.G[row], n_points)
        bound = float(poly.h[row])
    zmax = float(poly.f_max) / n_points
    box = [(None, None), (None, None), (0.0, zmax)] * n_points
    res = linprog(-c, A_ub=A if len(b) else None, b_ub=b if len(b) else None, bounds=box,
                  method="highs")
    if res.status != 0:         # unbounded (or a solver failure): keep the row
        return False
    scale = max(float(np.max(np.abs(poly.h), initial=0.0)), float(poly.f_max), 1.0)
    return float(-res.fun) <= bound + REDUNDANCY_TOL * scale


def mpc_polytope_rows(poly: ForcePolytope, n_points: int) -> PolytopeRows:
    """The rows of ``poly`` the MPC's QP keeps: each row in turn is dropped if the rows
    still kept (without it) and the box imply it."""
    kept = list(range(poly.G.shape[0]))
    dropped = []
    if np.isfinite(poly.f_max):
        for i in range(poly.G.shape[0]):
            others = [j for j in kept if j != i]
            if row_is_redundant(poly, i, others, n_points):
                kept = others
                dropped.append(i)
    kept_arr = np.array(kept, dtype=int)
    cone = kept_arr[poly.h[kept_arr] <= 0.0]
    cap = kept_arr[poly.h[kept_arr] > 0.0]
    return PolytopeRows(poly.G[cone].copy(), poly.G[cap].copy(), poly.h[cap].copy(),
                        tuple(dropped))


__all__ = ["PolytopeRows", "REDUNDANCY_TOL", "mpc_polytope_rows", "row_is_redundant"]
