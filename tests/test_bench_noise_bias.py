"""The noise-bias study's case parsing and table (bench/noise_bias.py), on hand-made rows:
no synthesis, no diagnosis."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))
from noise_bias import ALL_VARIANTS, VARIANTS, parse_case, table  # noqa: E402


def test_parse_case_reads_forms_and_library_effects():
    effects, cand, param, true, seed = parse_case("stiction_m1_s3")
    assert (cand, param, true, seed) == ("user_stiction", "tau_s", 0.5, 3)
    assert effects == ["ool_stiction:tau_s=0.5"]
    effects, cand, param, true, seed = parse_case("joint_friction:coulomb=0.1,viscous=0.02@2")
    # the main parameter: the one furthest from neutral relative to its range
    assert (cand, param, true, seed) == ("joint_friction", "coulomb", 0.1, 2)
    assert effects == ["joint_friction:coulomb=0.1,viscous=0.02"]
    for bad in ("stiction", "nosuchform_m0_s1", "stiction_m7_s1"):
        with pytest.raises(SystemExit, match="neither"):
            parse_case(bad)
    with pytest.raises(SystemExit, match="names no parameter"):
        parse_case("cohesion@1")
    with pytest.raises(SystemExit, match="unknown effect 'nosuch'"):
        parse_case("nosuch:k=1@1")
    with pytest.raises(SystemExit, match="invalid literal"):
        parse_case("cohesion:suction=3000@x")


def test_variants_silence_one_group_each_and_table_prints_every_variant():
    assert VARIANTS["none"] == 0.0 and VARIANTS["all"] == 1.0
    for name, noise in VARIANTS.items():
        if name.startswith("no_"):
            assert noise["level"] == 1.0
            assert all(v == 0.0 for k, v in noise.items() if k != "level")
    row = {"case": "stiction_m0_s2", "param": "tau_s", "true": 0.2,
           "coef_err": {v: 0.1 * i for i, v in enumerate(ALL_VARIANTS)}}
    row["coef_err"]["no_tau"] = float("nan")
    lines = table([row]).splitlines()
    assert len(lines) == 3
    cells = [c.strip() for c in lines[2].strip("|").split("|")]
    assert cells[:4] == ["stiction_m0_s2", "tau_s = 0.2", "+0 %", "+10 %"]
    assert cells[2 + list(ALL_VARIANTS).index("no_tau")] == "-"
    assert len(cells) == 2 + len(ALL_VARIANTS)
