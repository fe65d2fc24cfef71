"""The validation workbench's small synthetic data sets and their diagnoses: one definition
shared by the session fixtures (tests/conftest.py) and by the held-out threshold study
(``python bench/recovery.py --workbench``, docs/testing.md §"Re-deriving thresholds").

Every data set is one closed-loop plant run (``synth``, noise-free, 3 speeds × 7 stances,
ProxSuite's generic build) plus noisy copies with the realistic sensor model at level 1.
The tests use the plant seeds of :data:`WB_CASES` and the noise seeds :data:`TEST_NOISE_SEEDS`;
the thresholds were set on :data:`HELDOUT_SEED_OFFSET`-shifted plant and noise seeds that no
assertion uses.
"""
from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import Callable

import numpy as np

from granular_mpc.output import exclusive_lock

#: three speeds × ≈ 7 stances: enough trials for trial-grouped cross-validation
WB_SPEEDS = (0.15, 0.25, 0.35)
WB_STEPS = 7
#: a hidden effect outside the library (registered for the synth only, never a candidate)
WB_HIDDEN = "_test_hidden_skew"
#: a looser bed below a 12 mm crust, hidden in the plant; the user's term is the same law
#: (the calibration absorbs it into ζ: the force start, docs/validation.md §3.3)
WB_HIDDEN_LOOSE = "_test_hidden_loose_bed"
USER_LOOSE = "_test_user_loose_bed"
#: the cases whose plant has a hidden effect of its own
HIDDEN_CASES = ("unknown", "loose_bed")
#: name → plant effects, plant seed, scenario overrides
WB_CASES = {
    "null": dict(effects=[], seed=21, overrides=[]),
    "cohesion": dict(effects=["cohesion:suction=3000"], seed=22, overrides=[]),
    "zeta_off": dict(effects=[], seed=23, overrides=["terrain.zeta=1.768"]),
    "unknown": dict(effects=[f"{WB_HIDDEN}:k=18"], seed=24, overrides=[]),
    # seed 1: the data of bench/out_of_library.py's loose_bed_m1_s1 (the same law, plant
    # and noise seeds), where the force start was developed (docs/validation.md §5.3.16)
    "loose_bed": dict(effects=[f"{WB_HIDDEN_LOOSE}:k=1000"], seed=1, overrides=[]),
}
#: noise seeds of the multi-seed recovery test (the first is the fixture's default: the
#: case's plant seed)
TEST_NOISE_SEEDS = {name: (c["seed"], c["seed"] + 10, c["seed"] + 20) for name, c in WB_CASES.items()}
#: held-out data sets: plant seed and noise seed shifted by this (never asserted on)
HELDOUT_SEED_OFFSET = 100

#: the built-in effects library (tests pass it explicitly: other tests register effects
#: of their own in the same session)
LIBRARY = ("inertial_drag", "cohesion", "depth_hardening", "elastic_unloading",
           "joint_friction", "force_sensor_bias", "terrain_slope")
#: user terms of every kind, candidates next to the library on the cohesion data set
USER_SENSOR_TAU = "_test_dg_tau_gain"
USER_JOINT = "_test_dg_damping"
USER_MOCAP = "_test_dg_mocap_offset"
#: the user's guess for the "unknown" data set: lateral force −c·v_x on the sole
USER_OBLIQUE = "_test_user_oblique"


def loose_bed(o, s, p):
    """Looser sand under a 12 mm crust, as lost support: F_z = −min(k·(depth − 12 mm)⁺,
    the law's push) per patch (it never pulls)."""
    loss = o.fmin(p["k"] * o.fmax(s.depth - 0.012, 0.0), o.fmax(s.f_terrain[2], 0.0))
    return (0.0, 0.0, -loss * s.in_contact)


def _register_loose_bed(name: str) -> None:
    from granular_mpc.effects import Param, register_effect, registered_effects

    if name not in registered_effects():
        register_effect(name, params={"k": Param(200.0, 0.0, 1.0e5, "N/m",
                                                 "stiffness lost below 12 mm")})(loose_bed)


def register_hidden() -> None:
    """Register the hidden plant effects of the "unknown" and "loose_bed" cases
    (idempotent)."""
    from granular_mpc.effects import Param, register_effect, registered_effects

    _register_loose_bed(WB_HIDDEN_LOOSE)
    if WB_HIDDEN in registered_effects():
        return

    @register_effect(WB_HIDDEN, params={"k": Param(12.0, 0.0, 200.0, "N·s/m", "")})
    def _skew(o, s, p):
        """Sideways push proportional to the forward velocity of the sole."""
        return (0.0, -p["k"] * s.v_c[0] * s.in_contact, 0.0)


def register_user_terms() -> None:
    """Register the user-written candidates (idempotent)."""
    from granular_mpc.effects import (Param, register_effect, register_joint_effect,
                                      register_sensor_effect, registered_names)

    _register_loose_bed(USER_LOOSE)

    if USER_OBLIQUE not in registered_names():
        @register_effect(USER_OBLIQUE, params={"c": Param(10.0, -200.0, 200.0, "N·s/m", "")})
        def _oblique(o, s, p):
            """The user's guess: lateral force −c·v_x on the sole."""
            return (0.0, -p["c"] * s.v_c[0] * s.in_contact, 0.0)

    if USER_SENSOR_TAU not in registered_names():
        @register_sensor_effect(USER_SENSOR_TAU,
                                params={"gain": Param(1.1, 0.5, 2.0, "-", "torque gain")},
                                neutral={"gain": 1.0})
        def _tau_gain(cols, p, ctx):
            """τ_meas = g τ."""
            return {f"tau_{j}": p["gain"] * np.asarray(cols[f"tau_{j}"]) for j in ctx.joint_names}

    if USER_JOINT not in registered_names():
        @register_joint_effect(USER_JOINT,
                               params={"b": Param(0.05, 0.0, 2.0, "N·m·s/rad", "damping")})
        def _damping(q_a, dq_a, p):
            """Viscous joint damping."""
            return -p["b"] * dq_a

    if USER_MOCAP not in registered_names():
        @register_sensor_effect(USER_MOCAP,
                                params={"dx": Param(0.01, -1.0, 1.0, "m", "mocap offset")})
        def _mocap(cols, p, ctx):
            """A motion-capture x offset: no scored channel sees it."""
            return {"base_x": np.asarray(cols["base_x"]) + p["dx"]}


def case_candidates(name: str) -> list[str]:
    """Candidates of a case's diagnosis: the library, plus on "cohesion" the user terms of
    every kind (sensor on the torques, joint, a sensor effect no scored channel sees), on
    "unknown" the user's oblique term and on "loose_bed" the user's loose bed (the truth)."""
    extra = {"cohesion": [USER_SENSOR_TAU, USER_JOINT, USER_MOCAP],
             "unknown": [USER_OBLIQUE], "loose_bed": [USER_LOOSE]}.get(name, [])
    if extra:
        register_user_terms()
    return list(LIBRARY) + extra


def make_clean(name: str, out: Path, plant_seed: int | None = None) -> Path:
    """Synthesize the case's noise-free data set into ``out``."""
    from granular_mpc.validation.synth import synthesize

    case = WB_CASES[name]
    if name in HIDDEN_CASES:
        register_hidden()
    synthesize("sand_walk", out, speeds=WB_SPEEDS, steps=WB_STEPS,
               seed=case["seed"] if plant_seed is None else plant_seed,
               effects=case["effects"], noise=0.0, format="parquet",
               overrides=case["overrides"], overwrite=True)
    return out


def diagnose_case(name: str, data: Path, out: Path | None, *, user_terms: bool = True,
                  figures: bool = True):
    """``(Diagnosis, caught warnings)`` of one case's data set (seed 0, 100 resamples)."""
    from granular_mpc.validation.diagnose import diagnose

    cands = case_candidates(name) if user_terms else list(LIBRARY)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        d = diagnose(data, out, seed=0, n_boot=100, candidates=cands, figures=figures)
    return d, [str(w.message) for w in caught if issubclass(w.category, UserWarning)]


def build_once(out: Path, build: Callable[[Path], object]) -> Path:
    """``out`` built by ``build(out)`` once among the processes that share its folder.

    The test session's workers (``pytest -n``, docs/testing.md) share one folder per run:
    the first worker that needs a data set builds it while holding ``<out>.lock``, the
    others wait and then read it. ``<out>.done`` is written only after a complete build,
    so a build interrupted half-way is redone, never read.
    """
    done = out.with_name(out.name + ".done")
    if done.is_file():
        return out
    with exclusive_lock(out.with_name(out.name + ".lock")):
        if not done.is_file():              # another worker may have built it meanwhile
            build(out)
            done.write_text(str(os.getpid()))
    return out
