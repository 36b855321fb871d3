"""Image center of a catadioptric omni-image (dissertation sec. 4.3).

An omni-image shows a bright mirror disc on a dark surround, with a dark
cut-off circle in its middle where the camera sees itself. The center is
found from both circles: the outer boundary of the bright disc and the
boundary of the dark hole inside it, each fitted by an algebraic
least-squares circle (Kasa); the cut-off circle's center is the more precise
(its boundary is sharp and complete), the disc's is the fallback.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.errors import CalibrationError


@dataclass(frozen=True)
class OmniCircles:
    """Image center (u0, v0) px, the mirror disc's radius and the cut-off radius, px."""

    center: tuple[float, float]
    disc_radius: float
    cutoff_radius: float


def fit_circle(points: NDArray[np.float64]) -> tuple[float, float, float]:
    """Algebraic least-squares circle through (n, 2) points: (cx, cy, radius)."""
    x, y = points[:, 0], points[:, 1]
    A = np.stack([x, y, np.ones_like(x)], axis=1)
    b = x * x + y * y
    (p, q, s), *_ = np.linalg.lstsq(A, b, rcond=None)
    cx, cy = p / 2, q / 2
    return float(cx), float(cy), float(np.sqrt(s + cx * cx + cy * cy))


def detect_omni_circles(image: NDArray[np.uint8]) -> OmniCircles:
    """Find the mirror disc and the cut-off circle of an omni-image.

    Raises :class:`CalibrationError` when no bright disc with a dark center is found.
    """
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    gray = cv2.GaussianBlur(gray, (5, 5), 0)
    _, mask = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    contours, hierarchy = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if not contours or hierarchy is None:
        raise CalibrationError("no bright mirror disc found in the omni-image")
    outer = [i for i, h in enumerate(hierarchy[0]) if h[3] < 0]
    disc_i = max(outer, key=lambda i: cv2.contourArea(contours[i]))
    disc = contours[disc_i].reshape(-1, 2).astype(np.float64)
    dcx, dcy, dr = fit_circle(disc)
    h, w = gray.shape
    on_border = (
        (disc[:, 0] <= 0) | (disc[:, 1] <= 0) | (disc[:, 0] >= w - 1) | (disc[:, 1] >= h - 1)
    )
    if np.count_nonzero(~on_border) > 20:
        dcx, dcy, dr = fit_circle(disc[~on_border])
    holes = [i for i, hh in enumerate(hierarchy[0]) if hh[3] == disc_i]
    best: tuple[float, float, float] | None = None
    best_d = np.inf
    for i in holes:
        pts = contours[i].reshape(-1, 2).astype(np.float64)
        if len(pts) < 12 or cv2.contourArea(contours[i]) < 50:
            continue
        cx, cy, r = fit_circle(pts)
        d = float(np.hypot(cx - dcx, cy - dcy))
        if d < 0.25 * dr and d < best_d:
            best, best_d = (cx, cy, r), d
    if best is None:
        raise CalibrationError(
            "no dark cut-off circle found inside the mirror disc; give the image center explicitly"
        )
    # Contours run through pixel centers on the inside of the boundary: the
    # hole's contour lies half a pixel outside the hole, the disc's inside the disc.
    return OmniCircles((best[0], best[1]), dr + 0.5, best[2] - 0.5)
