"""The camera turn beside the monitor plane's homography in ``predict="flow"`` (issue 13):
the rotation-and-focal fit and the extrapolation test that picks between them."""

from __future__ import annotations

import math

import numpy as np

from omnidev.mouse.flow import apply_h
from omnidev.mouse.track import (
    rotate_points,
    rotation_and_focal,
    rotation_between,
    turn_extrapolates_better,
)

C = (319.5, 239.5)  # principal point of a 640 x 480 camera


def _rot(yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    y, p, r = (math.radians(a) for a in (yaw_deg, pitch_deg, roll_deg))
    ry = np.array([[math.cos(y), 0, math.sin(y)], [0, 1, 0], [-math.sin(y), 0, math.cos(y)]])
    rx = np.array([[1, 0, 0], [0, math.cos(p), -math.sin(p)], [0, math.sin(p), math.cos(p)]])
    rz = np.array([[math.cos(r), -math.sin(r), 0], [math.sin(r), math.cos(r), 0], [0, 0, 1]])
    return rz @ rx @ ry


def _focal(fov_deg: float) -> float:
    return (C[0] + 0.5) / math.tan(math.radians(fov_deg) / 2)


def test_rotation_and_focal_recover_a_turn_and_the_field_of_view() -> None:
    """Points spread over the image, turned by a known rotation with a 77.5 degree lens
    (on the search grid): the fit finds that focal length and reprojects to 1e-6 px, and
    equals :func:`rotation_between` at that focal length (the per-focal reference)."""
    rng = np.random.default_rng(1)
    src = rng.uniform((20, 20), (620, 460), (60, 2))
    f = _focal(77.5)
    R = _rot(6.0, -4.0, 3.0)
    dst = rotate_points(src, R, f, C)
    R_fit, f_fit = rotation_and_focal(src, dst, C)
    assert abs(f_fit - f) < 1e-6 * f
    assert float(np.abs(rotate_points(src, R_fit, f_fit, C) - dst).max()) < 1e-6
    assert np.allclose(R_fit, rotation_between(src, dst, f_fit, C), atol=1e-12)
    # a focal length off the grid: the nearest grid value, still within a pixel or so
    dst2 = rotate_points(src, R, _focal(71.0), C)
    R2, f2 = rotation_and_focal(src, dst2, C)
    assert abs(math.degrees(2 * math.atan((C[0] + 0.5) / f2)) - 71.0) <= 1.25 + 1e-9
    assert float(np.abs(rotate_points(src, R2, f2, C) - dst2).max()) < 2.0


def test_a_turn_is_chosen_where_the_homography_would_extrapolate_from_one_side() -> None:
    """Features bunched in the right third of the picture, noisy by 0.3 px, the camera
    turning: the missing top-left landmark is far outside them. The extrapolation test
    picks the turn, and the turn puts the landmark within 2 px where the homography
    fitted to the same points is more than twice as far off."""
    rng = np.random.default_rng(2)
    f = _focal(65.0)
    R = _rot(-8.0, 3.0, 2.0)
    ref = rng.uniform((430, 60), (620, 420), (40, 2))
    cur = rotate_points(ref, R, f, C) + rng.normal(0, 0.3, ref.shape)
    found_ref = np.array([[600.0, 40.0], [600.0, 440.0]])
    found_cur = rotate_points(found_ref, R, f, C)
    missing_ref = np.array([[30.0, 40.0]])
    truth = rotate_points(missing_ref, R, f, C)
    turn = turn_extrapolates_better(ref, cur, found_ref, found_cur, missing_ref, C, 8)
    assert turn is not None
    err_turn = float(np.linalg.norm(rotate_points(missing_ref, *turn, C) - truth))
    src = np.concatenate([ref] + [found_ref] * 8)
    dst = np.concatenate([cur] + [found_cur] * 8)
    import cv2

    H, _ = cv2.findHomography(src, dst, 0)
    err_h = float(np.linalg.norm(apply_h(H, missing_ref) - truth))
    print(f"\nmissing landmark: turn {err_turn:.2f} px, homography {err_h:.2f} px")
    assert err_turn < 2.0
    assert err_h > 2 * err_turn


def test_the_homography_is_kept_when_the_hand_moves_towards_the_screen() -> None:
    """The camera moves 15 % closer to the monitor (a zoom of the plane's image, which no
    turn of one camera makes): the test keeps the homography."""
    rng = np.random.default_rng(3)
    ref = rng.uniform((100, 60), (620, 420), (60, 2))
    H = np.array([[1.15, 0.0, -0.15 * 330], [0.0, 1.15, -0.15 * 240], [0.0, 0.0, 1.0]])
    cur = apply_h(H, ref) + rng.normal(0, 0.2, ref.shape)
    found_ref = np.array([[620.0, 40.0], [620.0, 440.0]])
    missing_ref = np.array([[30.0, 40.0]])
    assert (
        turn_extrapolates_better(ref, cur, found_ref, apply_h(H, found_ref), missing_ref, C, 8)
        is None
    )
