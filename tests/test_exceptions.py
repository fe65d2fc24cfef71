"""granular_mpc.exceptions: one hierarchy, errors that carry and name their data."""

import numpy as np
import pytest

from granular_mpc import exceptions as exc
from granular_mpc.robot import load_biped


def test_every_error_derives_from_the_package_root():
    classes = [v for v in vars(exc).values()
               if isinstance(v, type) and issubclass(v, Exception) and v.__module__ == exc.__name__]
    assert len(classes) >= 8
    assert all(issubclass(c, exc.GranularMpcError) for c in classes)


def test_divergence_error_labels_every_coordinate():
    biped = load_biped(with_visuals=False)
    q = np.zeros(biped.model.nq)
    v = np.full(biped.model.nv, np.nan)
    err = exc.PlantDivergedError(0.25, q, v, "non-finite", q_names=biped.q_names,
                                 v_names=biped.v_names)
    text = str(err)
    assert "t = 0.2500 s" in text and "non-finite" in text
    for name in ("base_qw=0", "q_left_knee=0", "dq_right_hip_pitch=nan", "base_wz_B=nan"):
        assert name in text
    assert err.q_names == biped.q_names


def test_divergence_error_without_names_prints_the_plain_vectors():
    err = exc.PlantDivergedError(1.0, [1.0, 2.0], [3.0], "velocity-bound", q_names=("a",))
    assert "q = [1. 2.]" in str(err)          # a partial name list is not used


def test_biped_coordinate_names_follow_pinocchio_indices():
    biped = load_biped(with_visuals=False)
    assert len(biped.q_names) == biped.model.nq and len(biped.v_names) == biped.model.nv
    for j, iq, iv in zip(biped.joint_names, biped.idx_q, biped.idx_v):
        assert biped.q_names[iq] == f"q_{j}"
        assert biped.v_names[iv] == f"dq_{j}"
        # independent: Pinocchio's own joint name for that index
        jid = biped.model.getJointId(j)
        assert biped.model.joints[jid].idx_q == iq


def test_config_error_keeps_key_and_value():
    e = exc.ConfigError("bad", key="terrain.zeta", value=-1.0)
    assert e.key == "terrain.zeta" and e.value == -1.0
    with pytest.raises(ValueError):          # also a ValueError for callers that catch that
        raise e
