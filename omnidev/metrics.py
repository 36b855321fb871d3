"""Image quality against a reference: PSNR and SSIM over a mask (pure numpy/OpenCV).

Both compare 8-bit images (grey or BGR) of the same shape; the mask selects the
pixels that count (e.g. where a view has truth). SSIM is Wang et al. (2004) on the
grey image with the usual 11 x 11 Gaussian window (sigma 1.5), K1 = 0.01,
K2 = 0.03, averaged over the masked pixels.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray


def _check(a: NDArray[np.uint8], b: NDArray[np.uint8], mask: NDArray[np.bool_]) -> None:
    if a.shape != b.shape or a.shape[:2] != mask.shape:
        raise ValueError(f"shapes differ: {a.shape}, {b.shape}, mask {mask.shape}")
    if not mask.any():
        raise ValueError("the mask selects no pixel")


def psnr(a: NDArray[np.uint8], b: NDArray[np.uint8], mask: NDArray[np.bool_]) -> float:
    """Peak signal-to-noise ratio (dB) of ``a`` against ``b`` over ``mask`` (all channels)."""
    _check(a, b, mask)
    d = (a.astype(np.float64) - b.astype(np.float64))[mask]
    mse = float(np.mean(d * d))
    return math.inf if mse == 0 else 10.0 * math.log10(255.0**2 / mse)


def ssim(a: NDArray[np.uint8], b: NDArray[np.uint8], mask: NDArray[np.bool_]) -> float:
    """Mean structural similarity of the grey images of ``a`` and ``b`` over ``mask``."""
    _check(a, b, mask)

    def grey(x: NDArray[np.uint8]) -> NDArray[np.float64]:
        g = cv2.cvtColor(x, cv2.COLOR_BGR2GRAY) if x.ndim == 3 else x
        return np.asarray(g, np.float64)

    x, y = grey(a), grey(b)
    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2

    def blur(z: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(cv2.GaussianBlur(z, (11, 11), 1.5), np.float64)

    mx, my = blur(x), blur(y)
    vx, vy, cxy = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    s = ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))
    return float(np.mean(s[mask]))
