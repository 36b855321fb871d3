"""Accuracy of image -> screen calibrations against known truth (Figs. 5.13-5.14).

Pure functions: the caller supplies the truth (image points and their exact screen
pixels, e.g. from :func:`omnidev.sim.screen.screen_to_image`). Errors are screen
pixels; a point a calibration maps to NaN (outside its screen) counts as missed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from omnidev.errors import CalibrationError
from omnidev.screencal.calibration import (
    METHODS,
    ScreenCalibration,
    ScreenFeatures,
    fit_calibration,
)

FloatArray = NDArray[np.float64]


def heldout_grid(screen_size: tuple[int, int], step: int = 20) -> FloatArray:
    """A dense grid of screen pixels (M, 2) every ``step`` px, from pixel 0 to the last
    pixel on each axis (the border pixels included); never on a dot centre (dots sit
    at half-pixel positions)."""
    sw, sh = screen_size
    xs = np.unique(np.r_[np.arange(0, sw, step), sw - 1]).astype(np.float64)
    ys = np.unique(np.r_[np.arange(0, sh, step), sh - 1]).astype(np.float64)
    gx, gy = np.meshgrid(xs, ys)
    return np.stack([gx.ravel(), gy.ravel()], axis=1)


@dataclass(frozen=True)
class MethodErrors:
    """One method's errors on a point set: ``truth`` and ``estimate`` (M, 2) screen px."""

    method: str
    truth: FloatArray
    estimate: FloatArray

    @property
    def error(self) -> FloatArray:
        """(M,) error length in screen px (NaN where missed)."""
        return np.asarray(np.hypot(*(self.estimate - self.truth).T), np.float64)

    @property
    def missed(self) -> int:
        """Points mapped to NaN."""
        return int(np.count_nonzero(~np.isfinite(self.error)))

    @property
    def rms(self) -> float:
        """RMS error (screen px) over the points not missed."""
        e = self.error
        return float(np.sqrt(np.mean(e[np.isfinite(e)] ** 2)))

    @property
    def max(self) -> float:
        """Largest error (screen px) over the points not missed."""
        e = self.error
        return float(np.max(e[np.isfinite(e)]))


def compare_methods(
    features: ScreenFeatures,
    uv: FloatArray,
    xy_true: FloatArray,
    methods: tuple[str, ...] = METHODS,
) -> list[MethodErrors]:
    """Fit every method to the same features and measure it on image points ``uv``
    whose true screen pixels are ``xy_true``; a method that cannot be fitted to them
    (the cell methods need a border polygon closed around the dots) misses every point."""
    return [MethodErrors(m, xy_true, estimate(features, m, uv)) for m in methods]


def estimate(features: ScreenFeatures, method: str, uv: FloatArray) -> FloatArray:
    """Screen px of image points ``uv`` by ``method`` fitted to ``features``; NaN where
    the method cannot be fitted to them."""
    try:
        return fit_calibration(features, method).image_to_screen(uv)
    except CalibrationError:
        return np.full((len(uv), 2), np.nan)


def errors_of(calib: ScreenCalibration, uv: FloatArray, xy_true: FloatArray) -> MethodErrors:
    """One calibration's errors on image points ``uv`` with true screen ``xy_true``."""
    return MethodErrors(calib.method, xy_true, calib.image_to_screen(uv))


def table(rows: list[MethodErrors]) -> str:
    """A plain-text table: method, RMS, max, missed points."""
    lines = [f"{'method':<12}{'RMS px':>9}{'max px':>9}{'missed':>8}"]
    for r in rows:
        lines.append(f"{r.method:<12}{r.rms:9.3f}{r.max:9.3f}{r.missed:8d}")
    return "\n".join(lines)
