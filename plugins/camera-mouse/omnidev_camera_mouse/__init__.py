"""``camera-mouse`` tracker: the screen point under the image center of a hand-held webcam.

Dissertation ch. 6: the detection stage (sec. 6.2.1) finds the four corner
landmarks, the tracking stage (sec. 6.2.4) follows them with the eight-bar
circular template and predicts one or two missing ones (sec. 6.2.5); with three
or more missing the tracker reports nothing (the daemon holds the cursor) and
detects again on the next frame. The cursor is the image center in screen
coordinates, by the dissertation's affine correction (eqs. 6.1-6.4) or by the
homography of the four screen corners (``method``).

Calibration file: the landmark layout (JSON or TOML with the keys of
:meth:`omnidev.mouse.landmarks.LandmarkLayout.to_dict`: screen size, landmark
offsets from the screen corners, circle and square sizes, all in mm).

Options: ``method`` ("homography", default, or "affine").
"""

from __future__ import annotations

import json
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from omnidev import Frame, PointerSample
from omnidev.errors import ConfigError, TrackerError
from omnidev.mouse.detect import detect_landmarks, to_gray
from omnidev.mouse.geometry import cursor_from_corners, image_center, screen_corners_from_landmarks
from omnidev.mouse.landmarks import LandmarkLayout
from omnidev.mouse.track import LandmarkTracker


class CameraMouse:
    """Detection, tracking with prediction, and the cursor (see the module docstring)."""

    def __init__(self, layout: LandmarkLayout, method: str = "homography") -> None:
        if method not in ("homography", "affine"):
            raise TrackerError(f"camera-mouse: method must be homography or affine, got {method!r}")
        self.layout = layout
        self.method = method
        self.tracker = LandmarkTracker()
        self.locked = False
        self.size: tuple[int, int] | None = None

    def _radius_px(self, centers: NDArray[np.float64]) -> float:
        """Landmark radius in pixels: its mm radius times the pixels per mm along the sides."""
        mm = self.layout.landmark_centers_mm()
        px_side = np.linalg.norm(np.roll(centers, -1, axis=0) - centers, axis=1)
        mm_side = np.linalg.norm(np.roll(mm, -1, axis=0) - mm, axis=1)
        return float(self.layout.circle_diameter_mm / 2 * np.mean(px_side / mm_side))

    def track(self, frame: Frame) -> PointerSample | None:
        h, w = frame.image.shape[:2]
        if self.size is None:
            self.size = (w, h)
        elif self.size != (w, h):
            raise TrackerError(
                f"camera-mouse: frame {frame.index} is {w}x{h}, the stream was "
                f"{self.size[0]}x{self.size[1]}"
            )
        gray = to_gray(frame.image)
        centers: NDArray[np.float64] | None = None
        if self.locked:
            centers = self.tracker.update(gray)
            if centers is None:
                self.locked = False  # three or more missing: detect again next frame
                return None
        else:
            det = detect_landmarks(frame.image, self.layout)  # colour edges help step 6
            if det is None:
                return None
            centers = det.centers
            self.tracker.lock(centers, self._radius_px(centers))
            self.locked = True
        corners = screen_corners_from_landmarks(centers, self.layout)
        uv = cursor_from_corners(corners, image_center(w, h), method=self.method)  # type: ignore[arg-type]
        if not np.all(np.isfinite(uv)):
            return None
        return PointerSample(
            float(uv[0]),
            float(uv[1]),
            frame.timestamp_ns,
            confidence=sum(self.tracker.found) / 4.0,
        )

    def reset(self) -> None:
        self.locked = False
        self.size = None


def load_layout(path: Path) -> LandmarkLayout:
    """The landmark layout of a JSON or TOML file; errors name the file and key."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise TrackerError(f"camera-mouse: cannot read {path}: {exc.strerror}") from None
    try:
        data = tomllib.loads(text) if path.suffix == ".toml" else json.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise TrackerError(f"camera-mouse: {path}: not valid {path.suffix[1:]}: {exc}") from None
    try:
        return LandmarkLayout.from_dict(data)
    except ConfigError as exc:
        raise TrackerError(f"camera-mouse: {path}: {exc}") from None


def open_tracker(options: Mapping[str, Any], calibration: Path | None) -> CameraMouse:
    """Entry point: the calibration is the landmark layout file; option ``method``."""
    unknown = set(options) - {"method"}
    if unknown:
        raise TrackerError(f"camera-mouse: unknown option {sorted(unknown)[0]!r} (options: method)")
    if calibration is None:
        raise TrackerError(
            "camera-mouse: needs the landmark layout as its calibration file "
            '([tracker] calibration = "landmarks.json": screen size and landmark offsets in mm)'
        )
    return CameraMouse(load_layout(calibration), str(options.get("method", "homography")))
