"""Binned cubes (validation/diagnosis/cubes.py): the grouped phase-bin means against the
per-channel, per-bin loop they replace."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from granular_mpc.validation.diagnosis.cubes import bin_means, cube


def _reference(phase, values, channels, edges):
    """The former loop: one masked mean per channel and bin."""
    b = np.clip(np.searchsorted(edges, phase, side="right") - 1, 0, len(edges) - 2)
    out = np.full((len(channels), len(edges) - 1), np.nan)
    for c, ch in enumerate(channels):
        v = np.asarray(values[ch], dtype=float)
        for k in range(len(edges) - 1):
            m = (b == k) & np.isfinite(v)
            if m.any():
                out[c, k] = v[m].mean()
    return out


@pytest.mark.parametrize("seed", range(40))
def test_bin_means_is_bit_identical_to_the_masked_loop(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    phase = np.sort(rng.uniform(-5.0, 105.0, n))
    if seed % 4 == 1:                             # unsorted phases
        phase = rng.permutation(phase)
    if seed % 4 == 2:                             # a gap: empty bins
        phase = np.where(phase > 50.0, phase + 30.0, phase)
    channels = [f"c{i}" for i in range(int(rng.integers(1, 14)))]
    values = {}
    for ch in channels:
        v = rng.normal(rng.uniform(-1e3, 1e3), rng.uniform(1e-3, 1e3), n)
        if rng.random() < 0.4:                    # some channels with missing samples
            v[rng.random(n) < rng.uniform(0.05, 1.0)] = np.nan
        if rng.random() < 0.1:
            v[rng.random(n) < 0.1] = np.inf
        values[ch] = v if rng.random() < 0.8 else list(v)
    edges = np.linspace(0.0, 100.0, int(rng.integers(2, 21)) + 1)
    got = bin_means(SimpleNamespace(phase=phase), values, channels, edges)
    ref = _reference(phase, values, channels, edges)
    assert got.shape == ref.shape
    assert np.array_equal(got, ref, equal_nan=True)


def test_bin_means_without_channels_is_empty():
    out = bin_means(SimpleNamespace(phase=np.linspace(0, 100, 30)), {}, [],
                    np.linspace(0, 100, 11))
    assert out.shape == (0, 10)


@pytest.mark.parametrize("seed", range(12))
def test_cube_is_bit_identical_to_bin_means_per_window(seed):
    rng = np.random.default_rng(100 + seed)
    edges = np.linspace(0.0, 100.0, int(rng.integers(2, 21)) + 1)
    channels = [f"c{i}" for i in range(int(rng.integers(1, 9)))]
    windows, values = [], []
    for i in range(int(rng.integers(1, 30))):
        n = int(rng.integers(1, 300))
        phase = np.sort(rng.uniform(-5.0, 105.0, n))
        if i % 3 == 1:
            phase = rng.permutation(phase)
        vals = {ch: rng.normal(rng.uniform(-1e3, 1e3), rng.uniform(1e-3, 1e3), n)
                for ch in channels}
        if i % 5 == 2:                           # a window with a missing sample
            vals[channels[0]][int(rng.integers(0, n))] = np.nan
        windows.append(SimpleNamespace(phase=phase))
        values.append(vals)
    got = cube(windows, values, channels, edges)
    ref = np.array([bin_means(w, v, channels, edges) for w, v in zip(windows, values)])
    assert got.shape == ref.shape
    assert np.array_equal(got, ref, equal_nan=True)
