"""Measured-state columns of sinking samples for the foot-force equation tests
(tests/test_sample_forces.py, tests/test_force_leftover.py)."""
from __future__ import annotations

import math

import numpy as np


def sinking_columns(n: int = 40, seed: int = 3) -> dict[str, np.ndarray]:
    """Sinking samples of a foot heading 30° left of W x, some of them already rising."""
    rng = np.random.default_rng(seed)
    yaw = math.radians(30.0)
    return {"depth": rng.uniform(0.004, 0.03, n), "v_h": rng.uniform(0.05, 0.6, n),
            "v_l": rng.uniform(-0.05, 0.05, n), "v_z": -rng.uniform(0.3, 1.0, n),
            "a_z": rng.normal(0.0, 5.0, n), "t_stance": rng.uniform(0.0, 0.1, n),
            "foot": (np.arange(n) % 2).astype(float), "heading_x": np.full(n, math.cos(yaw)),
            "heading_y": np.full(n, math.sin(yaw)),
            "rise": np.where(np.arange(n) % 3 == 0, rng.uniform(0.0, 0.004, n), 0.0),
            "depth_rate": rng.uniform(0.3, 1.0, n)}
