"""Class breaks against an independent implementation: Fisher-Jenks natural breaks of jenkspy."""

from __future__ import annotations

import jenkspy  # test extra: an independent Fisher-Jenks
import numpy as np
import pytest

from gistools.lidar.shrub import jenks_breaks, quantile_breaks


@pytest.mark.parametrize("seed", range(6))
def test_jenks_breaks_equal_jenkspy(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(50, 800))
    centres = np.sort(rng.uniform(0.05, 0.95, 3))
    v = np.concatenate([rng.normal(c, rng.uniform(0.01, 0.08), n) for c in centres]).clip(0.001, 1.0)
    v = np.round(v, 3)  # ties, as cover fractions of a disk have
    expect = jenkspy.jenks_breaks(v, n_classes=3)[1:3]
    assert jenks_breaks(v, sample=v.size) == pytest.approx(tuple(expect), abs=0)


def test_quantile_breaks_equal_numpys_equal_count_split():
    v = np.random.default_rng(3).uniform(0, 1, 3001)
    b1, b2 = quantile_breaks(v)
    assert np.mean(v <= b1) == pytest.approx(1 / 3, abs=1e-3) and np.mean(v <= b2) == pytest.approx(2 / 3, abs=1e-3)
