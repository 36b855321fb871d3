"""Tracking stage (sec. 6.2.4-6.2.5) on drawn landmarks with known sub-pixel centers."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from omnidev.mouse.track import LandmarkTracker, template_kernel, track_circle

S = 8  # supersampling of the drawings


def draw(size, centers, r=9.0, square=2.2, noise=2.0, seed=0):
    """Black discs of radius r on white squares (side 2*square*r) over a mid-gray picture."""
    w, h = size
    big = np.full((h * S, w * S), 110, np.uint8)
    for cx, cy in centers:
        X, Y = (cx + 0.5) * S - 0.5, (cy + 0.5) * S - 0.5
        half = square * r * S
        cv2.rectangle(big, (int(X - half), int(Y - half)), (int(X + half), int(Y + half)), 235, -1)
        cv2.circle(big, (round(X * 16), round(Y * 16)), round(r * S * 16), 20, -1, cv2.LINE_AA, 4)
    img = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA).astype(np.float64)
    img += np.random.default_rng(seed).normal(0, noise, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def test_kernel_has_eight_bars_of_n_pixels():
    k = template_kernel(9, 6)
    assert k.sum() == 0  # as many inner as outer samples
    # 8 bars x 3 outer and 3 inner samples (on the diagonals two samples can share a pixel)
    assert k[k > 0].sum() == 8 * 3 and k[k < 0].sum() == -8 * 3
    assert list(k[12, 18:25]) == [-1, -1, -1, 0, 1, 1, 1]  # the 0-degree bar across the rim


@pytest.mark.parametrize("dx,dy", [(0.0, 0.0), (3.3, -2.7), (-11.6, 8.2), (17.25, 14.4)])
def test_track_one_circle_subpixel(dx, dy):
    truth = (200.37 + dx, 150.81 + dy)
    img = draw((400, 300), [truth])
    c = track_circle(img, 200.37, 150.81, 9.0)
    assert c is not None
    err = np.hypot(c.x - truth[0], c.y - truth[1])
    assert err < 0.35, (c, truth)
    assert c.contrast > 100


def test_no_landmark_in_window_gives_none():
    img = draw((400, 300), [(60.0, 60.0)])
    assert track_circle(img, 300.0, 200.0, 9.0) is None


def corners(shift=(0.0, 0.0)):
    base = np.array([[100.2, 80.7], [520.4, 90.1], [510.9, 400.3], [110.6, 390.8]])
    return base + np.array(shift)


def test_tracker_follows_four_and_predicts_missing():
    t = LandmarkTracker()
    t.lock(corners(), 9.0)
    # all four move by (6.3, -4.1)
    truth = corners((6.3, -4.1))
    got = t.update(draw((640, 480), truth))
    assert got is not None and np.abs(got - truth).max() < 0.4 and all(t.found)
    # the right two leave the picture (not drawn): predicted by the others' displacement
    truth2 = corners((12.6, -8.2))
    got2 = t.update(draw((640, 480), truth2[[0, 3]], seed=1))
    assert got2 is not None and t.found == [True, False, False, True]
    assert np.abs(got2 - truth2).max() < 0.6
    # three missing: a failure, the caller holds the cursor
    assert t.update(draw((640, 480), truth2[[0]], seed=2)) is None


def test_tracker_ignores_plain_dark_blobs():
    """Dark squares (screen content of the landmarks' colour) do not fit the circular template."""
    img = np.full((300, 400), 235, np.uint8)
    cv2.rectangle(img, (190, 140), (210, 160), 20, -1)
    c = track_circle(img, 200.0, 150.0, 9.0)
    assert c is None or c.contrast < 0.6 * 215
