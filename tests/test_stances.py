"""Stances from touchdown to lift-off: contact state, force, plan; debounce; log ends."""
from __future__ import annotations

import numpy as np
import pytest

from granular_mpc.analysis import (Stance, debounce, find_stances, planned_column,
                                   resolve_source, stance_table, true_runs)
from synthetic_log import CONTACT_FZ, make_contact_log, make_log


def _windows(stances):
    return [(s.side, s.row_start, s.row_stop) for s in stances]


def test_true_runs_and_debounce_by_hand():
    m = np.array([0, 1, 1, 0, 1, 1, 1, 0, 0, 1, 0, 1, 1, 0], dtype=bool)
    assert true_runs(m) == [(1, 3), (4, 7), (9, 10), (11, 13)]
    # one-sample gaps (row 3, row 10) filled, then one-sample runs removed: none left
    assert true_runs(debounce(m, 1)) == [(1, 7), (9, 13)]
    # an isolated one-sample run is removed; a gap at the edge of the record is not filled
    m2 = np.array([0, 0, 1, 0, 0, 1, 1, 1, 0], dtype=bool)
    assert true_runs(debounce(m2, 1)) == [(5, 8)]
    m3 = np.array([0, 1, 1, 1, 0, 1, 1], dtype=bool)
    assert true_runs(debounce(m3, 1)) == [(1, 7)]
    # two-sample chatter needs debounce 2
    m4 = np.array([1, 1, 1, 0, 0, 1, 1, 1], dtype=bool)
    assert true_runs(debounce(m4, 1)) == [(0, 3), (5, 8)]
    assert true_runs(debounce(m4, 2)) == [(0, 8)]
    assert np.array_equal(debounce(m, 0), m)
    with pytest.raises(ValueError):
        debounce(m, -1)


def test_contact_stances_are_touchdown_to_liftoff():
    L = make_contact_log(4)
    st = find_stances(L.df)                       # auto → contact columns
    assert all(isinstance(s, Stance) and s.source == "contact" for s in st)
    assert _windows(st) == L.contact
    t = L.df.time.to_numpy()
    for s, (_, a, b) in zip(st, L.contact):
        assert s.t_touchdown == t[a] and s.t_liftoff == t[b - 1]
        assert s.complete and s.n_samples == b - a
        assert s.duration_s == pytest.approx((b - a - 1) * L.dt)
    # the plan starts `early` = 4 rows after touchdown and ends `late` = 2 rows before
    planned = find_stances(L.df, "planned")
    assert _windows(planned) == L.planned
    assert all(s.source == "planned" for s in planned)
    assert [p.row_start - c.row_start for p, c in zip(planned, st)] == [4] * 4


def test_force_stances_match_contact_and_threshold():
    L = make_contact_log(4)
    df = L.df.drop(columns=["left_contact", "right_contact"])
    assert resolve_source(df) == "force"
    st = find_stances(df)
    assert _windows(st) == L.contact and all(s.source == "force" for s in st)
    # a threshold above the force floor CONTACT_FZ trims each stance at both ends
    # (fz = CONTACT_FZ (1 + sin πu) > 1.5 CONTACT_FZ only for u in (1/6, 5/6))
    trimmed = find_stances(df, force_threshold_N=1.5 * CONTACT_FZ)
    for s, (_, a, b) in zip(trimmed, L.contact):
        u = np.linspace(0.0, 1.0, b - a)
        inside = np.flatnonzero(np.sin(np.pi * u) > 0.5)
        assert (s.row_start, s.row_stop) == (a + inside[0], a + inside[-1] + 1)


def test_force_from_v1_stance_foot_columns():
    # measured data format v1: only the labelled stance foot's grf_z
    L = make_log(4, gap_rows=5)
    df = L.df.drop(columns=[c for c in L.df.columns if c.startswith(("left_", "right_"))])
    assert resolve_source(df) == "force"
    st = find_stances(df, force_threshold_N=1.0)
    assert _windows(st) == L.segments
    labels_only = df.drop(columns=["grf_z"])
    assert resolve_source(labels_only) == "planned"
    assert _windows(find_stances(labels_only)) == L.segments


def test_one_sample_chatter_is_debounced():
    L = make_contact_log(4)
    (s0, a0, b0), (s1, a1, b1) = L.contact[0], L.contact[1]
    chatter = [(s0, a0 + 20),          # a one-sample lift-off mid-stance
               (s1, a1 - 3),           # a one-sample touchdown during swing
               (s1, a1 + 1)]           # a flicker right after touchdown
    C = make_contact_log(4, chatter=chatter)
    st = find_stances(C.df)
    # the brief contact 3 samples (6 ms) before the touchdown is a landing bounce: the
    # 20 ms debounce merges it, and the touchdown is that first contact
    expected = [(s, a, b) if (s, a, b) != (s1, a1, b1) else (s1, a1 - 3, b1)
                for s, a, b in L.contact]
    assert _windows(st) == expected
    one = _windows(find_stances(C.df, debounce_samples=1))   # one-sample chatter only
    assert one == L.contact
    raw = _windows(find_stances(C.df, debounce_samples=0))
    assert len(raw) > len(L.contact)                     # undebounced: a stance split
    assert (s0, a0, a0 + 20) in raw and (s0, a0 + 21, b0) in raw
    assert (s1, a1 + 2, b1) in raw                       # touchdown 2 samples late
    # the force source gets the same debounce
    f = find_stances(C.df.drop(columns=["left_contact", "right_contact"]))
    assert _windows(f) == expected


def test_stances_at_the_start_and_end_of_the_log():
    L = make_contact_log(3, lead_rows=2, early=4, late=3)   # contact clipped at both ends
    st = find_stances(L.df)
    assert _windows(st) == L.contact
    assert st[0].row_start == 0 and not st[0].touchdown_seen and st[0].liftoff_seen
    assert st[-1].row_stop == len(L.df) and not st[-1].liftoff_seen and st[-1].touchdown_seen
    assert not st[0].complete and st[1].complete and not st[-1].complete
    tab = stance_table(st)
    assert list(tab.row_start) == [st[1].row_start]
    full = stance_table(st, include_incomplete=True)
    assert list(full.complete) == [False, True, False]
    assert list(full.stance_source) == ["contact"] * 3
    assert full.attrs["stance_source"] == "contact"


def test_standing_start_is_not_a_touchdown():
    # a run log: no contact at row 0, both feet on the ground from row 1 (the robot settles)
    L = make_contact_log(3, lead_rows=5, early=4)          # first contact at row 1
    assert L.contact[0][1] == 1
    st = find_stances(L.df)
    assert not st[0].touchdown_seen and not st[0].complete
    assert all(s.complete for s in st[1:])
    later = make_contact_log(3, lead_rows=7, early=4)      # first contact at row 3: a touchdown
    assert find_stances(later.df)[0].complete


def test_planned_column_preference_and_errors():
    L = make_contact_log(2)
    df = L.df.copy()
    assert planned_column(df) == "stance"
    df["planned_stance"] = df["stance"]
    df["stance"] = "none"                         # a log whose stance is no longer the plan
    assert planned_column(df) == "planned_stance"
    assert _windows(find_stances(df, "planned")) == L.planned
    with pytest.raises(ValueError, match="source"):
        find_stances(df, "bogus")
    with pytest.raises(ValueError, match="left_contact"):
        find_stances(df.drop(columns=["left_contact"]), "contact")
    bad = L.df.copy()
    bad.loc[30, "time"] = bad.loc[29, "time"]
    with pytest.raises(ValueError, match="row 30"):
        find_stances(bad)
