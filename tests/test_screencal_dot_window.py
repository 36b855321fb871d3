"""The dot centroid's window follows the dot's shape (issue 12).

Under a steep view a large dot is an ellipse longer than the template's circle; a
round window of 1.25 x the template's radius cut its ends, and the centroid no longer
was the full ellipse's, which the perspective correction assumes. Seed 62072 (held-out
range 62000-62199, looked at after it was reported): 1600x900, yaw and pitch 30
degrees, 5 x 8 dots of radius 58.6 screen px; the left column's dots were 1.0-1.8 image
px off and the calibration 1.08 px RMS / 2.97 max.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from omnidev.errors import CalibrationError
from omnidev.screencal import dots
from omnidev.screencal.calibration import detect_screen
from omnidev.screencal.dots import _elongation
from tests.screen_scene import assert_within_bound, detect, heldout_errors, scene


def test_elongation_and_axis_of_a_drawn_ellipse() -> None:
    img = np.zeros((200, 300), np.uint8)
    cv2.ellipse(img, (150, 100), (40, 16), 30.0, 0, 360, (255,), -1)
    cv2.circle(img, (40, 40), 12, (255,), -1)
    count, labels, stats, cents = cv2.connectedComponentsWithStats(img, connectivity=8)
    area = stats[1:, cv2.CC_STAT_AREA].astype(np.float64)
    elong, axis = _elongation(labels, count, np.asarray(cents[1:], np.float64), area)
    k_circle = int(np.argmin(np.hypot(*(cents[1:] - [40, 40]).T)))
    k_ellipse = 1 - k_circle
    assert abs(float(elong[k_circle]) - 1.0) < 0.03
    assert abs(float(elong[k_ellipse]) - 2.5) < 0.1
    # the major axis at 30 degrees (v down, like OpenCV's angle)
    ang = np.degrees(np.arctan2(axis[k_ellipse, 1], axis[k_ellipse, 0])) % 180
    assert abs(ang - 30.0) < 1.0


def test_a_steep_views_large_dots_are_found_whole(monkeypatch: pytest.MonkeyPatch) -> None:
    sc, grid, feat = detect(62072)
    true = sc.screen_to_image(grid.centers)
    err = np.hypot(*(feat.dots.centers - true).T)
    assert float(np.nanmax(err)) < 0.6  # measured 0.42
    assert_within_bound(heldout_errors(sc, feat))
    # with the round window of before (every blob taken as round)
    monkeypatch.setattr(
        dots,
        "_elongation",
        lambda labels, count, c, a: (np.ones(count - 1), np.tile([1.0, 0.0], (count - 1, 1))),
    )
    caps = scene(62072)[2]
    old = detect_screen(caps[0], caps[1], caps[2], layout=grid)
    assert float(np.nanmax(np.hypot(*(old.dots.centers - true).T))) > 1.5  # measured 1.77


def test_dots_too_small_to_measure_are_refused_not_calibrated() -> None:
    # seed 61011 (out of spec: 352x288, dots of 1.4 image px radius 13 x 7 px apart):
    # the dots' median miss of the layout is 0.09 spacings (just under the layout
    # check's 0.1); calibrated, the map was 7.2 px RMS / 21.8 px max off
    _, grid, caps = scene(61011)
    with pytest.raises(CalibrationError, match=r"measured too roughly.*1\.5 image px radius"):
        detect_screen(caps[0], caps[1], caps[2], layout=grid)
