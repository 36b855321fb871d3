"""Detection stage (sec. 6.2.1) on drawn images: landmarks warped by a known homography onto
a room with dark distractor blobs, screen content with dark dots (some in a decoy rectangle
of the landmarks' aspect ratio); truth = the landmark centers projected by the camera."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from omnidev.mouse.detect import DetectParams, detect_landmarks, find_dark_regions, order_corners
from omnidev.mouse.geometry import cursor_homography, image_center
from tests.mouse_scene import LAYOUT, oblique_camera, render

# numpy's warnings are errors here: a degenerate corner group once gave inf - inf
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

VIEWS = [(0, 0, 0), (0, 0, 25), (30, 0, 0), (40, 10, -15), (-35, -15, 30)]


@pytest.mark.parametrize(("yaw", "pitch", "roll"), VIEWS)
def test_detects_the_four_landmarks_within_half_a_pixel(yaw, pitch, roll):
    cam = oblique_camera(yaw, pitch_deg=pitch, roll_deg=roll)
    img = render(cam, seed=abs(yaw) + 7 * abs(roll))
    truth = cam.project(LAYOUT.landmark_centers_mm())
    # More dark regions than landmarks pass the area/shape filter: the search is real.
    assert len(find_dark_regions(img)) >= 10
    det = detect_landmarks(img, LAYOUT)
    assert det is not None
    assert det.candidates >= 2
    err = np.linalg.norm(det.centers - truth, axis=1).max()
    assert err < 0.5, err
    # The screen corners they predict, and the cursor from them (1920x1080 pixels).
    sc_truth = cam.project(LAYOUT.screen_corners_mm())
    assert np.linalg.norm(det.screen_corners - sc_truth, axis=1).max() < 1.0
    cur = cursor_homography(det.screen_corners, image_center(*cam.size))
    assert np.linalg.norm((cur - cam.true_cursor()) * [1920, 1080]) < 3.0


def test_bgr_input_and_faithful_mode():
    cam = oblique_camera(25, roll_deg=10)
    img = cv2.cvtColor(render(cam, seed=3), cv2.COLOR_GRAY2BGR)
    truth = cam.project(LAYOUT.landmark_centers_mm())
    # The dissertation's procedure alone (no edge floor, no border-position check, binary
    # centroids) picks the right group by the largest total edge strength.
    faithful = DetectParams(min_edge_fraction=0.0, max_border_offset_px=math.inf, refine=False)
    det = detect_landmarks(img, LAYOUT, faithful)
    assert det is not None
    assert np.linalg.norm(det.centers - truth, axis=1).max() < 1.0


@pytest.mark.parametrize(("yaw", "pitch", "roll"), VIEWS[:4])
@pytest.mark.parametrize("hidden", [0, 1, 2, 3])
def test_three_landmarks_give_no_lock(yaw, pitch, roll, hidden):
    cam = oblique_camera(yaw, pitch_deg=pitch, roll_deg=roll)
    assert detect_landmarks(render(cam, hide=(hidden,), seed=hidden), LAYOUT) is None


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_no_monitor_or_no_landmarks_give_no_lock(seed):
    cam = oblique_camera(20, roll_deg=5)
    assert detect_landmarks(render(cam, monitor=False, seed=seed), LAYOUT) is None
    assert detect_landmarks(render(cam, hide=(0, 1, 2, 3), seed=seed), LAYOUT) is None
    blank = np.full((240, 320), 200, np.uint8)
    assert detect_landmarks(blank, LAYOUT) is None


def test_order_corners_under_rotation():
    sq = np.array([[-2.0, -1.0], [2.0, -1.0], [2.0, 1.0], [-2.0, 1.0]])
    for deg in (-40, -20, 0, 20, 40):
        a = math.radians(deg)
        R = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        pts = sq @ R.T
        shuffled = pts[[2, 0, 3, 1]]
        assert np.array_equal(order_corners(shuffled), pts)


def _random_views(n, seed=42):
    """Random hand-held poses (yaw +-45, pitch +-20, roll +-30 deg, 0.7-1.1 m) with all four
    landmarks inside the 640x480 picture."""
    rng = np.random.default_rng(seed)
    views = []
    while len(views) < n:
        yaw, pitch, roll = rng.uniform(-45, 45), rng.uniform(-20, 20), rng.uniform(-30, 30)
        dist, aim = rng.uniform(700, 1100), rng.uniform([0.3, 0.3], [0.7, 0.7])
        cam = oblique_camera(yaw, pitch_deg=pitch, roll_deg=roll, dist=dist, aim=tuple(aim))
        truth = cam.project(LAYOUT.landmark_centers_mm())
        if (truth >= 8).all() and (truth[:, 0] <= 632).all() and (truth[:, 1] <= 472).all():
            views.append((cam, truth))
    return views


def test_random_hand_held_views():
    errs, false_locks = [], 0
    for k, (cam, truth) in enumerate(_random_views(12)):
        det = detect_landmarks(render(cam, seed=100 + k), LAYOUT)
        assert det is not None, k
        errs.append(np.linalg.norm(det.centers - truth, axis=1).max())
        false_locks += detect_landmarks(render(cam, seed=k, hide=(k % 4,)), LAYOUT) is not None
        false_locks += detect_landmarks(render(cam, seed=k, monitor=False), LAYOUT) is not None
    assert max(errs) < 0.5, errs
    assert false_locks == 0


def test_side_edge_strength_follows_a_bent_border():
    """Edge pixels on a parabola that bows 12 px outwards over a 300 px side: the straight
    Hough window finds few of them on one line, the window bent by 12 px finds them all."""
    from omnidev.mouse.detect import side_edge_strength

    edges = np.zeros((200, 400), np.uint8)
    p, q = np.array([50.0, 100.0]), np.array([350.0, 100.0])  # clockwise: inwards is +y
    for x in range(50, 351):
        u = (x - 50) / 300
        edges[round(100 - 12 * 4 * u * (1 - u)), x] = 255
    band = 6.0
    shift = np.array([0.0, band])  # the window from band px outside the side, 2 band deep
    straight, span, _ = side_edge_strength(edges, p - shift, q - shift, 2 * band)
    bent, span_b, _ = side_edge_strength(edges, p - shift, q - shift, 2 * band, bend_px=12.0)
    assert span == span_b
    assert straight < 0.5 * span  # the border's middle lies outside the straight window
    assert bent >= 0.95 * span
