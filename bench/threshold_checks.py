"""Held-out values of two thresholds the workbench study (`bench/recovery.py --workbench`)
does not cover (docs/testing.md):

    python bench/threshold_checks.py [OUT_DIR]

* test_replay::test_an_encoder_offset_at_its_true_value_restores_the_replay — e_fix vs
  e_ref on every left window of the null case made with the held-out plant seed 121;
* test_diagnose::test_a_user_written_term_closes_the_gap — intrusion_y and grf_y after /
  before on the "unknown" case made with the held-out plant and noise seed 224.

Run from the project root (it imports tests/workbench.py).
"""
import dataclasses, sys, json
from pathlib import Path
import numpy as np
sys.path.insert(0, "tests")
import workbench as wb
from granular_mpc.effects import Param, register_sensor_effect, effect_info
from granular_mpc.robot import load_biped
from granular_mpc.validation.dataformat import load_dataset
from granular_mpc.validation.prepare import stance_windows
from granular_mpc.validation.replay import (Variant, build_replay_model, effect_variant,
                                            model_terrain, replay_granular, validate)
from granular_mpc.validation.synth import noisy_copy

root = Path(sys.argv[1] if len(sys.argv) > 1 else "runs/threshold_checks")
root.mkdir(parents=True, exist_ok=True)
out = {}
# 1) encoder offset: every left window of the held-out null data (plant seed 121)
clean = wb.make_clean("null", root / "null_clean", plant_seed=121)
ds = load_dataset(clean)
biped = load_biped(ds.meta.robot, with_visuals=False)
rm = build_replay_model(biped, model_terrain("dry_sand"), sample_rate_hz=ds.meta.sample_rate_hz,
                        terrain_effects=["cohesion"])
ws = stance_windows(ds, biped, contact_stiffness=rm.contact_stiffness)
def _knee_offset(cols, p, ctx):
    return {"q_left_knee": np.asarray(cols["q_left_knee"]) + p["offset"]}
register_sensor_effect("_ho_knee_offset", params={"offset": Param(0.01, -0.2, 0.2, "rad", "")})(_knee_offset)
info = effect_info("_ho_knee_offset")
trials = {n: df.assign(q_left_knee=df["q_left_knee"] + 0.05) for n, df in ds.trials.items()}
wbias = stance_windows(dataclasses.replace(ds, trials=trials), biped, contact_stiffness=rm.contact_stiffness)
rows = []
for k, w in enumerate(ws):
    if w.side != "left":
        continue
    ref = replay_granular(rm, w, Variant()); fix = replay_granular(rm, wbias[k], effect_variant([(info, {"offset": 0.05})]))
    e_ref = float(np.sqrt(np.mean((ref["q_left_knee"] - w.meas["q_left_knee"]) ** 2)))
    e_fix = float(np.sqrt(np.mean((fix["q_left_knee"] - wbias[k].meas["q_left_knee"]) ** 2)))
    rows.append((e_ref, e_fix, e_fix - 1.2 * e_ref - 2e-3))
out["encoder"] = rows
print("encoder windows", len(rows), "max e_fix-e_ref", max(r[1]-r[0] for r in rows), "worst margin", max(r[2] for r in rows))
# 2) user oblique term: held-out unknown case (plant/noise seed 224)
c = wb.make_clean("unknown", root / "unk_clean", plant_seed=224)
n = noisy_copy(c, root / "unk_noisy", 1.0, seed=224, overwrite=True)
d, _ = wb.diagnose_case("unknown", n, root / "unk_diag", figures=False)
print("added", d.added)
if wb.USER_OBLIQUE in d.added:
    v = validate(d.data, root / "unk_val", effects=[wb.USER_OBLIQUE], params=d.out_dir, n_boot=100)
    ba = v.report["before_after"]
    out["intrusion_y_ratio"] = ba["intrusion_y"]["after"] / ba["intrusion_y"]["before"]
    out["grf_y_ratio"] = ba["grf_y"]["after"] / ba["grf_y"]["before"]
    print("intrusion_y after/before", out["intrusion_y_ratio"], "grf_y", out["grf_y_ratio"])
(root / "out.json").write_text(json.dumps(out, indent=1))
