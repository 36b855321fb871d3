"""``laser-pointer`` tracker: the laser spot on a calibrated screen, in screen coordinates.

A fixed camera watches a display or projection screen (dissertation ch. 5). Each
frame, :class:`omnidev.laser.spot.SpotDetector` finds at most one laser spot
(image pixels, sub-pixel) inside the calibrated screen region; the screen
calibration maps it to screen pixels, and the sample is that position
normalized by the screen size ((0, 0) the top-left pixel, (1, 1) the
bottom-right one). No spot (or a spot outside the screen): None, and the daemon
holds the pointer (and releases held buttons when it is lost).

Calibration file: a screen calibration saved by ``omnidev calibrate screen``
(:func:`omnidev.screencal.calibration.load_screen_calibration`); the camera
frames must have its image size. Spots are looked for inside its screen region
grown by 3 px (a spot at the very edge of the screen keeps its core).

Options (all optional): ``colour`` ("red", default, "green" or "any"),
``method`` ("white-core", default: :class:`~omnidev.laser.spot.SpotDetector`, which
needs the spot's brightest pixel white; "colour":
:class:`~omnidev.laser.colour_spot.ColourSpotDetector`, no white core needed, better
on the randomized scenes of ``omnidev eval laser`` but not yet on the committed
fixtures, see docs/laser-pointer.md), and the chosen
detector's limits (:data:`METHOD_OPTIONS` lists them; see the detectors' docs).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from omnidev import Frame, PointerSample
from omnidev.errors import OmnidevError, TrackerError, naming
from omnidev.laser.colour_spot import ColourSpotDetector
from omnidev.laser.spot import COLOURS, SpotDetector
from omnidev.screencal.calibration import ScreenCalibration, load_screen_calibration

METHODS = ("colour", "white-core")
# each method's options: name -> type
METHOD_OPTIONS: dict[str, dict[str, type]] = {
    "colour": {
        "step": int, "saturated": int, "soft": int, "rise": int, "min_area": int,
        "max_area": int, "busy_frames": int, "bands": int, "halo": float,
        "colour_ratio": float, "min_new": float, "max_elongation": float, "min_fill": float,
        "change_fraction": float, "track_px": float, "busy_gain": float, "fringe": float,
        "max_darker": float, "min_cross": float, "busy_events": int, "position": str,
        "new_margin": int, "confirm": int, "busy_confirm": int, "min_rise": float,
        "fringe_ratio": float, "hold_spot": bool, "peak_margin": int, "beam_channels": int,
        "bright_rise": int, "search_first": bool,
    },
    "white-core": {
        "step": int, "rise": int, "core": int, "saturated": int, "min_area": int,
        "max_area": int, "bands": int, "colour_ratio": float, "halo": float,
        "max_elongation": float, "min_fill": float, "change_fraction": float,
    },
}  # fmt: skip
MASK_GROW_PX = 3  # candidates also this far outside the calibrated screen border


class LaserPointer:
    """Spot detection in the calibrated screen region, then image -> screen."""

    def __init__(
        self, calibration: ScreenCalibration, detector: SpotDetector | ColourSpotDetector
    ) -> None:
        self.calibration = calibration
        self.detector = detector
        self.image_size = (int(calibration.image_size[0]), int(calibration.image_size[1]))
        self.screen_size = (int(calibration.screen_size[0]), int(calibration.screen_size[1]))

    def track(self, frame: Frame) -> PointerSample | None:
        img = frame.image
        h, w = img.shape[:2]
        if img.ndim != 3 or img.shape[2] != 3:
            raise TrackerError(
                f"laser-pointer: frame {frame.index} is grey; the spot's colour needs BGR frames"
            )
        if (w, h) != self.image_size:
            raise TrackerError(
                f"laser-pointer: frame {frame.index} is {w}x{h}, the screen calibration is for "
                f"{self.image_size[0]}x{self.image_size[1]} camera images"
            )
        spot = self.detector.detect(img)
        if spot is None:
            return None
        xy = self.calibration.image_to_screen(np.array([[spot.u, spot.v]], dtype=np.float64))[0]
        if not np.all(np.isfinite(xy)):
            return None
        sw, sh = self.screen_size
        return PointerSample(
            float(xy[0]) / (sw - 1), float(xy[1]) / (sh - 1), frame.timestamp_ns, confidence=1.0
        )

    def reset(self) -> None:
        self.detector.reset()


def _number(options: Mapping[str, Any], key: str, kind: type) -> Any:
    try:
        return kind(options[key])
    except (TypeError, ValueError):
        what = "a whole number" if kind is int else "a number"
        raise TrackerError(f"laser-pointer: {key} must be {what}, got {options[key]!r}") from None


_FLAGS = {"true": True, "yes": True, "1": True, "false": False, "no": False, "0": False}


def _flag(options: Mapping[str, Any], key: str) -> bool:
    value = options[key]
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.strip().lower() in _FLAGS:
        return _FLAGS[value.strip().lower()]
    raise TrackerError(f"laser-pointer: {key} must be true or false, got {value!r}")


def open_tracker(options: Mapping[str, Any], calibration: Path | None) -> LaserPointer:
    """Entry point: the calibration is a screen calibration file; options as documented."""
    method = str(options.get("method", "white-core"))
    if method not in METHODS:
        raise TrackerError(
            f"laser-pointer: method must be one of {', '.join(METHODS)}, got {method!r}"
        )
    kinds = METHOD_OPTIONS[method]
    known = ("colour", "method", *kinds)
    unknown = sorted(set(options) - set(known))
    if unknown:
        other = [m for m in METHODS if m != method and unknown[0] in METHOD_OPTIONS[m]]
        hint = f"; it is an option of method {other[0]!r}" if other else ""
        raise TrackerError(
            f"laser-pointer: unknown option {unknown[0]!r} for method {method!r}{hint} "
            f"(options: {', '.join(known)})"
        )
    colour = str(options.get("colour", "red"))
    if colour not in COLOURS:
        raise TrackerError(
            f"laser-pointer: colour must be one of {', '.join(COLOURS)}, got {colour!r}"
        )
    kwargs: dict[str, Any] = {}
    for key, kind in kinds.items():
        if key in options and kind is bool:
            kwargs[key] = _flag(options, key)
        elif key in options:
            if isinstance(options[key], bool) or (
                kind is int and isinstance(options[key], float) and not options[key].is_integer()
            ):
                what = "a whole number" if kind is int else "a number"
                raise TrackerError(f"laser-pointer: {key} must be {what}, got {options[key]!r}")
            kwargs[key] = _number(options, key, kind)
    if calibration is None:
        raise TrackerError(
            "laser-pointer: needs a screen calibration as its calibration file "
            '([tracker] calibration = "screen.yml", made by omnidev calibrate screen)'
        )
    if not calibration.is_file():
        raise TrackerError(f"laser-pointer: screen calibration {calibration} does not exist")
    try:
        cal = load_screen_calibration(calibration)
    except OmnidevError as exc:
        raise TrackerError(f"laser-pointer: {naming(calibration, exc)}") from None
    # the screen region grown by MASK_GROW_PX: a spot at the very edge keeps its core
    mask = cv2.dilate(
        np.asarray(cal.screen_mask(), np.uint8), np.ones((2 * MASK_GROW_PX + 1,) * 2, np.uint8)
    ).astype(bool)
    try:
        detector: SpotDetector | ColourSpotDetector
        if method == "colour":
            detector = ColourSpotDetector(colour, mask, **kwargs)
        else:
            detector = SpotDetector(colour, mask, **kwargs)
    except ValueError as exc:
        raise TrackerError(f"laser-pointer: {exc}") from None
    return LaserPointer(cal, detector)
