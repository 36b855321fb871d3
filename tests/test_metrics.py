"""PSNR and SSIM against known values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from omnidev.metrics import psnr, ssim


def test_known_values():
    rng = np.random.default_rng(0)
    a = rng.integers(0, 256, (64, 80), dtype=np.uint8)
    m = np.ones(a.shape, bool)
    assert psnr(a, a, m) == math.inf and ssim(a, a, m) == pytest.approx(1.0)
    b = np.clip(a.astype(int) + 10, 0, 255).astype(np.uint8)
    d = (a.astype(float) - b)[m]
    assert psnr(a, b, m) == pytest.approx(10 * math.log10(255**2 / np.mean(d * d)))
    noisy = np.clip(a + rng.normal(0, 40, a.shape), 0, 255).astype(np.uint8)
    assert ssim(a, noisy, m) < ssim(a, b, m) < 1.0


def test_errors():
    a = np.zeros((4, 4), np.uint8)
    with pytest.raises(ValueError, match="shapes differ"):
        psnr(a, np.zeros((4, 5), np.uint8), np.ones((4, 4), bool))
    with pytest.raises(ValueError, match="no pixel"):
        ssim(a, a, np.zeros((4, 4), bool))
