"""Camera-mouse geometry against a pinhole camera's exact truth (ray-plane intersection)."""

from __future__ import annotations

import numpy as np
import pytest

from omnidev.errors import ConfigError
from omnidev.mouse.geometry import (
    apply_homography,
    corrected_rectangle,
    cursor_affine,
    cursor_from_corners,
    cursor_homography,
    homography_check_opencv,
    homography_image_to_screen,
    image_center,
    screen_corners_from_landmarks,
)
from omnidev.mouse.landmarks import LandmarkLayout, draw_landmark, draw_landmark_sheet
from tests.mouse_scene import LAYOUT, Camera, look_at, oblique_camera

SCREEN_PX = np.array([1920.0, 1080.0])


def _view(yaw, pitch=0.0, roll=0.0):
    cam = oblique_camera(yaw, pitch_deg=pitch, roll_deg=roll)
    corners = cam.project(LAYOUT.screen_corners_mm())
    return cam, corners, image_center(*cam.size)


@pytest.mark.parametrize(("yaw", "pitch", "roll"), [(0, 0, 0), (35, 10, 20), (45, -20, -30)])
def test_homography_cursor_is_exact_under_perspective(yaw, pitch, roll):
    cam, corners, c0 = _view(yaw, pitch, roll)
    truth = cam.true_cursor()
    got = cursor_homography(corners, c0)
    err_px = np.abs((got - truth) * SCREEN_PX).max()
    assert err_px < 1e-6
    # The same map from OpenCV (float32 points) agrees to its precision.
    cv = apply_homography(homography_check_opencv(corners), c0)
    assert np.abs((cv - truth) * SCREEN_PX).max() < 1e-2


def test_affine_is_exact_for_a_frontal_view_with_any_roll():
    # A camera facing the screen squarely (any rotation about its axis) sees a similarity:
    # the dissertation's affine correction is then exact.
    for roll in (0.0, 15.0, -30.0):
        C = np.array([301.0, 117.0, -900.0])
        cam = Camera(look_at(C, C + np.array([0.0, 0.0, 1.0]), roll), C)
        corners = cam.project(LAYOUT.screen_corners_mm())
        c0 = image_center(*cam.size)
        err = np.abs((cursor_affine(corners, c0) - cam.true_cursor()) * SCREEN_PX).max()
        assert err < 1e-9


def test_affine_exact_for_an_affine_view():
    # Corners related to the screen rectangle by an exact affine map: both methods exact.
    A = np.array([[0.31, -0.08, 120.0], [0.05, 0.29, 80.0]])
    rect = LAYOUT.screen_corners_mm()
    corners = rect @ A[:, :2].T + A[:, 2]
    p = np.array([0.37 * 520.0, 0.81 * 292.5])
    c0 = A[:, :2] @ p + A[:, 2]
    truth = p / np.array([520.0, 292.5])
    assert np.abs(cursor_affine(corners, c0) - truth).max() < 1e-12
    assert np.abs(cursor_homography(corners, c0) - truth).max() < 1e-12


def test_affine_error_grows_with_obliqueness(capsys):
    errs = []
    for yaw in (0, 15, 30, 45):
        cam, corners, c0 = _view(yaw)
        truth = cam.true_cursor()
        e_aff = float(np.linalg.norm((cursor_affine(corners, c0) - truth) * SCREEN_PX))
        e_hom = float(np.linalg.norm((cursor_homography(corners, c0) - truth) * SCREEN_PX))
        errs.append(e_aff)
        assert e_hom < 1e-6
        with capsys.disabled():
            print(
                f"\nyaw {yaw:2d} deg: affine cursor error {e_aff:7.2f} px, "
                f"homography {e_hom:.1e} px"
            )
    assert errs == sorted(errs)
    assert errs[-1] > 20.0 * max(errs[0], 0.05)
    assert errs[-1] > 30.0  # at 45 degrees the affine misses by tens of 1920x1080 pixels


def test_corrected_rectangle_eqs_6_3_6_4():
    c = np.array([[0.0, 0.0], [100.0, 0.0], [90.0, 40.0], [10.0, 40.0]])
    rect = corrected_rectangle(c)
    assert rect[2, 0] == pytest.approx((100.0 + 80.0) / 2)
    assert rect[2, 1] == pytest.approx(2 * np.hypot(10.0, 40.0) / 2)


def test_cursor_method_selection():
    _cam, corners, c0 = _view(30)
    assert np.array_equal(
        cursor_from_corners(corners, c0, method="affine"), cursor_affine(corners, c0)
    )
    assert np.array_equal(cursor_from_corners(corners, c0), cursor_homography(corners, c0))
    with pytest.raises(ValueError, match="unknown cursor method"):
        cursor_from_corners(corners, c0, method="bogus")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="collinear"):
        homography_image_to_screen([[0, 0], [1, 0], [2, 0], [0, 1]])


@pytest.mark.parametrize(("yaw", "roll"), [(0, 0), (40, 25)])
def test_screen_corners_from_landmarks_exact(yaw, roll):
    cam = oblique_camera(yaw, roll_deg=roll)
    lm = cam.project(LAYOUT.landmark_centers_mm())
    got = screen_corners_from_landmarks(lm, LAYOUT)
    assert np.abs(got - cam.project(LAYOUT.screen_corners_mm())).max() < 1e-8


def test_layout_round_trip_and_errors_name_the_key():
    layout = LandmarkLayout(
        600.0, 340.0, ((-20.0, -30.0), (22.0, -30.0), (21.0, 28.0), (-19.0, 31.0)), 18.0, 28.0
    )
    assert LandmarkLayout.from_dict(layout.to_dict()) == layout
    d = layout.to_dict()
    del d["offsets_mm"]
    with pytest.raises(ConfigError, match="'offsets_mm'"):
        LandmarkLayout.from_dict(d)
    d = layout.to_dict()
    del d["offsets_mm"]["br"]
    with pytest.raises(ConfigError, match="offsets_mm.br"):
        LandmarkLayout.from_dict(d)
    d = layout.to_dict()
    d["offsets_mm"]["tl"] = [1.0, "x"]
    with pytest.raises(ConfigError, match=r"offsets_mm.tl\[1\]"):
        LandmarkLayout.from_dict(d)
    d = layout.to_dict()
    d["screen_height_mm"] = -3
    with pytest.raises(ConfigError, match="screen_height_mm"):
        LandmarkLayout.from_dict(d)
    d = layout.to_dict()
    d["colour"] = 1
    with pytest.raises(ConfigError, match="'colour'"):
        LandmarkLayout.from_dict(d)
    d = layout.to_dict()
    d["offsets_mm"]["tr"] = [-700.0, 0.0]  # TR landmark left of TL: not a TL, TR, BR, BL quad
    with pytest.raises(ConfigError, match="offsets_mm"):
        LandmarkLayout.from_dict(d)
    d = layout.to_dict()
    d["circle_diameter_mm"] = 40.0
    with pytest.raises(ConfigError, match="circle_diameter_mm"):
        LandmarkLayout.from_dict(d)


def test_landmark_image_true_size():
    dpi = 300.0
    img = draw_landmark(circle_diameter_mm=20.0, square_side_mm=30.0, dpi=dpi)
    assert img.shape == (round(30.0 * dpi / 25.4),) * 2
    # Dark area (coverage-weighted) equals the circle's area at that DPI to < 0.1 %.
    area_px = (255.0 - img.astype(np.float64)).sum() / 255.0
    r_px = 10.0 * dpi / 25.4
    assert area_px == pytest.approx(np.pi * r_px**2, rel=1e-3)
    # Centered: the darkness centroid is the image center.
    w = 255.0 - img.astype(np.float64)
    ys, xs = np.mgrid[0 : img.shape[0], 0 : img.shape[1]]
    c = (img.shape[0] - 1) / 2
    assert (w * xs).sum() / w.sum() == pytest.approx(c, abs=1e-6)
    assert (w * ys).sum() / w.sum() == pytest.approx(c, abs=1e-6)
    sheet = draw_landmark_sheet(LAYOUT, dpi=100.0)
    assert sheet.shape == (round(297 * 100 / 25.4), round(210 * 100 / 25.4))
    with pytest.raises(ConfigError, match="does not fit"):
        draw_landmark_sheet(
            LandmarkLayout.symmetric(500, 300, margin_mm=(60, 60), square_side_mm=100.0),
            dpi=100.0,
        )
