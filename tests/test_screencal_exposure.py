"""Auto-exposure between the white, black and dot captures (issue 12).

With the screen black, an auto-exposure camera opens up: the room, and a projector's
grey black level, come out brighter in the black capture than in the white one. Where
the screen's light falls off (a projector's corner) the black image can then read
brighter than the white one, and a bezel can clip in it. Seeds: 54076 and 57092 (ranges
looked at while tuning; both were refused with a corner 30-180 image px off), 57062
(refused after the first version of the fix: a bezel clipped in the black image joined
the screen). 61005 and 61132 (held-out range 61000-61199, looked at after it was
reported): a projector's grey black under auto-exposure leaves 43 grey levels of white
minus black, less near one side, and the dot capture's noise there crosses the
threshold map in hundreds of specks. 63069 and 63097 (held-out range 63000-63199,
looked at after it was reported): the dot capture at a third exposure.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from omnidev.errors import CalibrationError
from omnidev.screencal import features
from omnidev.screencal.calibration import _border_tdm, _unexplained, detect_screen
from omnidev.screencal.dots import _components
from omnidev.screencal.features import (
    at_exposure,
    binarize,
    border_from_edges,
    border_from_region,
    exposure_gain,
    screen_region,
    to_gray,
)
from tests.screen_scene import assert_within_bound, detect, heldout_errors, scene


def _true_corners(seed: int) -> np.ndarray:
    sc = scene(seed)[0]
    sw, sh = sc.screen_px
    return np.asarray(
        sc.screen_to_image(
            np.array([[-0.5, -0.5], [sw - 0.5, -0.5], [sw - 0.5, sh - 0.5], [-0.5, sh - 0.5]])
        )
    )


def test_exposure_gain_reads_the_room_at_two_exposures() -> None:
    rng = np.random.default_rng(3)
    room = rng.uniform(0.02, 0.6, (120, 160))  # linear light at the white capture's exposure
    white = np.round(255 * room ** (1 / 2.2)).astype(np.uint8)
    black = np.round(255 * np.clip(room / 0.4, 0, 1) ** (1 / 2.2)).astype(np.uint8)
    screen = np.zeros(room.shape, bool)
    screen[40:80, 50:110] = True
    white[screen] = 250
    black[screen] = 60
    assert exposure_gain(white, black, screen) == pytest.approx(0.4, rel=0.03)
    # at_exposure takes the black capture back to the white one's exposure
    back = at_exposure(black, 0.4)
    room_px = ~screen & (black < 250)
    assert float(np.median(np.abs(back[room_px] - white[room_px]))) < 1.0
    assert np.array_equal(at_exposure(black, 1.0), black.astype(np.float32))


def test_exposure_gain_is_one_without_enough_room_to_read() -> None:
    white = np.full((60, 80), 240, np.uint8)
    black = np.full((60, 80), 20, np.uint8)
    assert exposure_gain(white, black, np.ones((60, 80), bool)) == 1.0


@pytest.mark.parametrize("seed", [54076, 57092])
def test_a_corner_darker_than_the_room_change_is_found_at_the_black_captures_exposure(
    seed: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    caps = scene(seed)[2]
    true = _true_corners(seed)
    region = screen_region(caps[0], caps[1])
    assert region.black_gain < 0.7  # measured 0.45 (54076), 0.59 (57092)
    border = border_from_edges(caps[0], caps[1], border_from_region(region), region.black_gain)
    assert float(np.hypot(*(border.vertices[0::2] - true).T).max()) < 1.5
    # at equal exposures (the code before) a corner was 29-181 image px off
    monkeypatch.setattr(features, "exposure_gain", lambda *a: 1.0)
    before = screen_region(caps[0], caps[1])
    old = border_from_edges(caps[0], caps[1], border_from_region(before))
    assert float(np.hypot(*(old.vertices[0::2] - true).T).max()) > 20.0


@pytest.mark.parametrize("seed", [54076, 57092, 57062])
def test_scenes_refused_for_auto_exposure_calibrate_within_the_bound(seed: int) -> None:
    # 54076: one dot in the corner where the black capture was the brighter was 3 image
    # px off (its pixels weighed nothing); with the black capture at the dot
    # capture's exposure, the calibration is within 0.5 px RMS / 1.5 px max
    sc, _, feat = detect(seed)
    e = heldout_errors(sc, feat)
    assert_within_bound(e)


@pytest.mark.parametrize("seed", [61005, 61132])
def test_specks_of_a_low_contrast_side_do_not_set_the_dots_size(seed: int) -> None:
    sc, grid, caps = scene(seed)
    poly, tdm, _ = _border_tdm(to_gray(caps[0]), to_gray(caps[1]), None, "region")
    binary = binarize(caps[2], tdm)
    # the typical area from the layout's 81 largest blobs: every dot kept
    blobs = _components(binary, poly, grid.rows * grid.cols)
    assert len(blobs.area) >= grid.rows * grid.cols
    # the median over all blobs (before): the specks outnumber the dots, and a dot is
    # over 4 x their median area
    every = _components(binary, poly)
    assert len(every.area) > 2 * grid.rows * grid.cols
    assert float(np.median(every.area)) * 4 < float(np.median(blobs.area))
    # refused before ("found 9 / 0 of the 9 x 9 = 81 dots"), within the bound now
    feat = detect(seed)[2]
    assert int(feat.dots.found.sum()) == grid.rows * grid.cols
    assert_within_bound(heldout_errors(sc, feat))


def test_the_dot_capture_at_another_exposure_is_explained_by_the_black_one() -> None:
    rng = np.random.default_rng(5)
    room = rng.uniform(0.02, 0.5, (90, 120))  # linear light, a textured room
    black = np.round(255 * room ** (1 / 2.2)).astype(np.int16)
    # the dot capture 1.3 stops darker, with sensor noise: a level map of the black one
    dots = np.round(255 * (0.4 * room) ** (1 / 2.2) + rng.normal(0, 2, room.shape))
    dots = dots.astype(np.int16)
    assert float(np.median(np.abs(dots - black))) > 2 * features.MIN_CONTRAST
    assert _unexplained(black.ravel(), dots.ravel()) < 0.2
    # a dot capture of another room (or of this one from elsewhere) is not
    other = np.round(255 * rng.permutation(room.ravel()) ** (1 / 2.2)).astype(np.int16)
    assert _unexplained(black.ravel(), other) > 0.8


@pytest.mark.parametrize("seed", [63069, 63097])
def test_an_auto_exposed_dot_capture_calibrates_within_the_bound(seed: int) -> None:
    # held-out range 63000-63199, looked at after it was reported: the dot capture's
    # exposure lies between the white and black ones'. 63069 (a projector's grey black):
    # the dots' background read as bright as the threshold map, and 3 of 28 dots were
    # found; 63097 (a monitor): the room outside the screen read 50 grey levels apart
    # from the black capture and the scene was refused as "camera moved?"
    sc, grid, caps = scene(seed)
    feat = detect(seed)[2]
    assert int(feat.dots.found.sum()) >= grid.rows * grid.cols - 2
    assert_within_bound(heldout_errors(sc, feat))
    if seed == 63069:
        with pytest.raises(CalibrationError, match=r"found \d+ of the 4 x 7 = 28 dots"):
            detect_screen(caps[0], caps[1], caps[2], layout=grid, exposure="as-is")


@pytest.mark.parametrize("seed", [62079, 62126])
def test_dots_weighed_at_the_dot_captures_exposure_are_measured_closer(seed: int) -> None:
    # range 62000-62199 (looked at while tuning): the dot capture 0.77 / 0.82 times the
    # black capture's exposure; weighed against the images as captured, each dot's
    # soft edge rose less over the black image than it should, and the calibration was
    # 0.33 / 0.30 px RMS, 1.15 / 0.70 max; at the dot capture's exposure 0.11 / 0.10,
    # 0.28 / 0.34
    sc, grid, caps = scene(seed)
    now = heldout_errors(sc, detect(seed)[2])
    before = heldout_errors(
        sc, detect_screen(caps[0], caps[1], caps[2], layout=grid, exposure="as-is")
    )
    rms_now, rms_before = (float(np.sqrt(np.nanmean(e**2))) for e in (now, before))
    assert rms_now < 0.15 < 0.25 < rms_before
    assert float(np.nanmax(now)) < 0.5


def test_a_dot_capture_of_another_scene_is_refused() -> None:
    white, black = scene(63097)[2][:2]
    other = cv2.resize(scene(63069)[2][2], (white.shape[1], white.shape[0]))
    with pytest.raises(CalibrationError, match="not explained by a change of exposure"):
        detect_screen(white, black, other, layout=scene(63097)[1])
