"""The out-of-library benchmark's command line (bench/out_of_library.py): a design outside
the allowed range (a speed outside the scenario's ``command.speed`` range) stops before
any case runs, with one message naming the option."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parent.parent / "bench" / "out_of_library.py"


@pytest.mark.parametrize("args, message", [
    (["--speeds", "2"], "--speeds: speed: Input should be less than or equal to 1.5 (got 2.0)"),
    (["--speeds", "0.2", "-3"],
     "--speeds: speed: Input should be greater than or equal to -1 (got -3.0)"),
    (["--steps", "1"], "--steps: 1"),
    (["--replay-segments", "0"], "--replay-segments: 0"),
])
def test_a_design_out_of_range_stops_before_any_case(tmp_path, args, message):
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, str(SCRIPT), *args, "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert message in proc.stderr
    assert not out.exists()                     # nothing synthesised, nothing written


def test_one_out_folder_holds_one_design(tmp_path):
    sys.path.insert(0, str(SCRIPT.parent))
    from out_of_library import check_design

    errors = []
    check_design(tmp_path, [0.15, 0.25, 0.35], 7, errors.append)
    assert errors == [] and (tmp_path / "design.json").is_file()
    check_design(tmp_path, [0.15, 0.25, 0.35], 7, errors.append)      # the same: reused
    assert errors == []
    check_design(tmp_path, [0.15, 0.2, 0.3, 0.35], 11, errors.append)
    assert len(errors) == 1
    assert "speeds [0.15, 0.25, 0.35], steps 7, replay segments 1" in errors[0]
    assert "asked: speeds [0.15, 0.2, 0.3, 0.35], steps 11, replay segments 1" in errors[0]
    # the same speeds and stances, replayed in two segments per stance: another design
    check_design(tmp_path, [0.15, 0.25, 0.35], 7, errors.append, 2)
    assert len(errors) == 2 and "asked: speeds [0.15, 0.25, 0.35], steps 7, replay segments 2" in errors[1]


def test_the_held_out_layer_forms_act_below_their_interface_only():
    """The opt-in held-out layers (``EXTRA_FORMS``, not in the default run): a soft bed
    under a 12 mm crust takes k·(d − 12 mm) off the vertical force below it; the loose bed
    takes the same but never more than the law's own push (it never pulls a sole the law has
    let go of, where the soft bed does); a ratio layer scales the law's force by 1 + g·(d −
    17 mm)/d below 17 mm; none acts above."""
    from dataclasses import replace

    sys.path.insert(0, str(SCRIPT.parent))
    from ool_forms import EXTRA_FORMS, FORMS, loose_bed, ratio_layer, soft_bed

    from granular_mpc.effects.state import PatchState
    from granular_mpc.terrain.closed_form import FLOAT

    assert {f.name for f in EXTRA_FORMS} == {"soft_bed", "loose_bed", "ratio_layer"}
    assert not {f.name for f in EXTRA_FORMS} & {f.name for f in FORMS}
    s = PatchState(depth=0.02, in_contact=1.0, p_c=(0.0, 0.0, -0.02), v_c=(0.1, 0.0, -0.3),
                   a_c=(0.0, 0.0, 0.0), intrusion=(0.0, 0.0, 0.02), heading=(1.0, 0.0),
                   lateral=(0.0, 1.0), f_terrain=(4.0, 0.0, 50.0), f_yield_z=50.0,
                   area_h=0.002, width=0.04, density=1500.0, dt=5e-4)
    assert soft_bed(FLOAT, s, 300.0)[2] == pytest.approx(-300.0 * 0.008)
    assert soft_bed(FLOAT, replace(s, depth=0.01), 300.0)[2] == pytest.approx(0.0)
    assert loose_bed(FLOAT, s, 300.0)[2] == pytest.approx(-300.0 * 0.008)
    assert loose_bed(FLOAT, replace(s, depth=0.01), 300.0)[2] == pytest.approx(0.0)
    weak = replace(s, f_terrain=(4.0, 0.0, 1.5))        # the law lets go: at most its push
    assert loose_bed(FLOAT, weak, 300.0)[2] == pytest.approx(-1.5)
    let_go = replace(s, f_terrain=(4.0, 0.0, 0.0))
    assert loose_bed(FLOAT, let_go, 300.0)[2] == pytest.approx(0.0)
    assert soft_bed(FLOAT, let_go, 300.0)[2] == pytest.approx(-300.0 * 0.008)
    f = ratio_layer(FLOAT, s, 2.0)
    assert f[2] == pytest.approx(2.0 * 0.003 / 0.02 * 50.0)
    assert f[0] == pytest.approx(2.0 * 0.003 / 0.02 * 4.0)
    assert ratio_layer(FLOAT, replace(s, depth=0.015), 2.0) == pytest.approx((0.0, 0.0, 0.0))
