"""The library-pair study's parsing and figures (bench/recovery_pairs.py), on hand-made
rows: no synthesis, no diagnosis."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))
from recovery_pairs import DEFAULT_PAIRS, pair_figures, pair_table, split_pair  # noqa: E402


def test_split_pair_keeps_exponents_and_rejects_single_effects():
    assert split_pair("cohesion:suction=3e+3+terrain_slope:slope_y=0.03") == [
        "cohesion:suction=3e+3", "terrain_slope:slope_y=0.03"]
    assert split_pair(DEFAULT_PAIRS[0]) == ["cohesion:suction=3000",
                                            "joint_friction:coulomb=0.1,viscous=0.02"]
    for bad in ("cohesion:suction=3000", "a+b+c", "+cohesion", "cohesion+"):
        with pytest.raises(SystemExit, match="two effects joined by"):
            split_pair(bad)


def _member(effect, rank, added, coef_err):
    return {"effect": effect, "rank": rank, "added_self": added, "coef_err": coef_err,
            "param": "p", "coef": 1.0 + coef_err, "true": 1.0}


def test_pair_figures_count_both_added_ranks_coefficients_and_wrong_terms():
    rows = [
        {"pair": "a+b", "seed": 1, "status": "missing_effect", "added": ["a", "b"],
         "members": [_member("a", 1, True, 0.05), _member("b", 2, True, -0.20)],
         "both_added": True, "wrong_added": []},
        {"pair": "a+b", "seed": 2, "status": "partially_explained", "added": ["a", "c"],
         "members": [_member("a", 1, True, 0.10), _member("b", 5, False, 0.02)],
         "both_added": False, "wrong_added": ["c"]},
    ]
    f = pair_figures(rows)
    assert f["pairs"] == 2
    assert f["pair_both_added_rate"] == pytest.approx(0.5)
    assert f["pair_member_rank_le2_rate"] == pytest.approx(0.75)           # 3 of 4 members
    assert f["pair_member_coef_within_15pct_rate"] == pytest.approx(0.75)  # −20 % is out
    assert f["pair_wrong_added"] == 1
    table = pair_table(rows).splitlines()
    assert len(table) == 4 and "b: 5, no" in table[3] and "a, c" in table[3]
