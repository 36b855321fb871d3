"""``bright-blob`` tracker: the largest bright spot in the frame is the pointer.

A deliberately simple tracker for testing and demonstrating the pointer
daemon (and a crude laser-spot follower): threshold the gray image, take the
largest connected component of at least ``min_area`` pixels, and report its
centroid normalized to the image (x = u / (W - 1), y = v / (H - 1)). With
``press_area`` set, a spot of at least that many pixels holds the left button.

Options (the daemon's ``[tracker.options]``):
    threshold: gray level 0..255 above which a pixel is bright (default 200).
    min_area: smallest spot in pixels (default 12).
    press_area: spot area in pixels from which the left button is down (default: never).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from omnidev import Frame, PointerSample
from omnidev.errors import TrackerError


class BrightBlobTracker:
    """Largest above-threshold blob -> normalized centroid (see the module docstring)."""

    def __init__(
        self, threshold: int = 200, min_area: int = 12, press_area: int | None = None
    ) -> None:
        if not 0 <= threshold < 255:
            raise TrackerError(f"bright-blob: threshold must be 0..254, got {threshold}")
        if min_area < 1:
            raise TrackerError(f"bright-blob: min_area must be >= 1, got {min_area}")
        if press_area is not None and press_area < min_area:
            raise TrackerError("bright-blob: press_area must be >= min_area")
        self.threshold = threshold
        self.min_area = min_area
        self.press_area = press_area

    def track(self, frame: Frame) -> PointerSample | None:
        image = frame.image
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
        _, mask = cv2.threshold(gray, self.threshold, 255, cv2.THRESH_BINARY)
        # Outer contours are ~20x faster than labelling every pixel at 640x480.
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        if not contours:
            return None
        areas = [cv2.contourArea(c) + 0.5 * cv2.arcLength(c, True) + 1 for c in contours]
        best = int(np.argmax(areas))
        area = areas[best]  # ~ pixel count: polygon area through pixel centres + half the rim
        if area < self.min_area:
            return None
        bx, by, bw, bh = cv2.boundingRect(contours[best])
        H, W = gray.shape[:2]
        # Intensity-weighted centroid over the blob's box grown by 2 px, so the
        # antialiased rim (below threshold) counts too: sub-pixel accuracy.
        x0, y0 = max(bx - 2, 0), max(by - 2, 0)
        x1, y1 = min(bx + bw + 2, W), min(by + bh + 2, H)
        patch = gray[y0:y1, x0:x1].astype(np.float64)
        weight = np.clip(patch - self.threshold / 2.0, 0.0, None)
        total = float(weight.sum())
        ys, xs = np.mgrid[y0:y1, x0:x1]
        u = float((weight * xs).sum() / total)
        v = float((weight * ys).sum() / total)
        pressed = self.press_area is not None and area >= self.press_area
        return PointerSample(
            x=u / (W - 1),
            y=v / (H - 1),
            timestamp_ns=frame.timestamp_ns,
            confidence=min(1.0, area / (4.0 * self.min_area)),
            buttons=frozenset({"left"}) if pressed else frozenset(),
        )

    def reset(self) -> None:
        """Nothing is carried between frames."""


def _int(options: Mapping[str, Any], key: str, default: int | None) -> int | None:
    value = options.get(key, default)
    if value is None:
        return None
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float)
        or not math.isfinite(value)
        or value != int(value)
        or abs(value) > 1e9
    ):
        raise TrackerError(f"bright-blob: option {key} must be an integer, got {value!r}")
    return int(value)


def open_tracker(options: Mapping[str, Any], calibration: Path | None) -> BrightBlobTracker:
    """Entry point: options threshold, min_area, press_area; no calibration."""
    unknown = set(options) - {"threshold", "min_area", "press_area"}
    if unknown:
        raise TrackerError(
            f"bright-blob: unknown option {sorted(unknown)[0]!r} "
            "(options: threshold, min_area, press_area)"
        )
    if calibration is not None:
        raise TrackerError("bright-blob: takes no calibration file (it reports image coordinates)")
    threshold = _int(options, "threshold", 200)
    min_area = _int(options, "min_area", 12)
    assert threshold is not None and min_area is not None
    return BrightBlobTracker(threshold, min_area, _int(options, "press_area", None))
