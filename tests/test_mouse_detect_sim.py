"""Detection (sec. 6.2.1) on frames of the 3D fixture renderer omnidev.sim.monitor: lens
distortion, motion blur, noise, screen content in the landmarks' colours, a textured wall.
Truth: the renderer's landmark image positions and the screen point under the image center."""

from __future__ import annotations

import numpy as np
import pytest

from omnidev.mouse.detect import detect_landmarks
from omnidev.mouse.geometry import cursor_homography, image_center
from omnidev.mouse.landmarks import LandmarkLayout
from omnidev.sim import monitor as mon
from omnidev.sim.handcam import HandCamera

LAYOUT = LandmarkLayout(
    mon.SCREEN_W * 1000,
    mon.SCREEN_H * 1000,
    tuple((ox * 1000, oy * 1000) for ox, oy in mon.LANDMARK_OFFSETS),
    mon.LANDMARK_RADIUS * 2000,
    mon.LANDMARK_SQUARE * 1000,
)
CAM = HandCamera.default()


@pytest.mark.parametrize(
    ("trajectory", "index", "max_err_px"),
    [("drift", 15, 0.25), ("roll", 30, 0.25), ("oblique", 30, 0.25), ("sweep", 15, 1.5)],
)
def test_detects_rendered_landmarks(trajectory, index, max_err_px):
    img, truth = mon.render_frame(CAM, mon.MonitorScene(0), trajectory, index, supersample=2)
    assert all(truth.visible)
    det = detect_landmarks(img, LAYOUT)
    assert det is not None
    uv = np.array(truth.landmarks_uv, dtype=np.float64)
    # Lens distortion bends the plane's image slightly; the landmark centers themselves are
    # measured where the renderer put them.
    assert np.linalg.norm(det.centers - uv, axis=1).max() < max_err_px
    cur = cursor_homography(det.screen_corners, image_center(CAM.width, CAM.height))
    assert truth.screen_xy is not None
    assert np.linalg.norm((cur - truth.screen_xy) * [1920, 1080]) < 4 * max_err_px + 1.0


@pytest.mark.parametrize("variant", ["three-landmarks", "no-monitor"])
def test_no_lock_without_four_landmarks(variant):
    for index in (0, 20):
        img, _ = mon.render_frame(CAM, mon.MonitorScene(0, variant=variant), "drift", index)
        assert detect_landmarks(img, LAYOUT) is None
