"""Dot indexing on randomized scenes of the kind that defeated the corner homography.

Seeds from the tuning range 50000-50049 (issue 12): all dots were found as blobs,
but the border corners' homography predicted them up to 0.75 dot spacings off
(k1 < -0.15, yaw >= 25 degrees), so only 5-13 of them were indexed and the scene
was refused. Growing the lattice neighbour by neighbour indexes all of them. Two
refusals that must stay refusals: 50106 (tuning range, an occluder hides the bottom
corners) and 55094 (held out on 2026-12-05, then looked at: a corner far off when the
white and black captures are compared at their own exposures; at one exposure it
calibrates). 68076 (held out on 2026-12-07, then looked at): a barrel lens strong enough
that the first step of the growth had to adapt to it.
"""

from __future__ import annotations

import numpy as np
import pytest

from omnidev.errors import CalibrationError
from omnidev.screencal import features
from omnidev.screencal.dots import _grow_lattice
from tests.screen_scene import assert_within_bound, detect, heldout_errors


def test_barrel_and_yaw_scene_indexes_every_dot_at_its_true_position() -> None:
    # seed 50015: 960x540, k1 < -0.15, yaw >= 25 deg, 8 x 11 dots; was "found 6 of 88"
    scene, grid, feat = detect(50015)
    assert grid.shape == (8, 11)
    assert feat.dots.count == grid.count
    true_uv = scene.screen_to_image(grid.centers)
    err = np.hypot(*(feat.dots.centers - true_uv).T)
    spacing = float(np.median(np.hypot(*np.diff(true_uv.reshape(8, 11, 2), axis=1).T)))
    assert spacing > 40  # image px: an off-by-one index would be >= 40 px off
    assert float(err.max()) < 1.0  # every dot at its own true image position


def test_barrel_and_yaw_scene_calibrates_within_bound_against_truth() -> None:
    scene, _, feat = detect(50015)
    e = heldout_errors(scene, feat)
    ok = np.isfinite(e)
    assert ok.mean() > 0.99
    # measured 0.51 px RMS (1920x1080 screen px); was refused before
    assert float(np.sqrt(np.mean(e[ok] ** 2))) < 0.6
    assert float(np.median(e[ok])) < 0.4


def test_glare_on_a_corner_no_longer_moves_the_border_or_refuses() -> None:
    # seed 50036: a reflection on the screen's top-right corner cut it off the lit
    # region; the border fitted to the region's outline put that corner 50 image px
    # off and the calibration was refused; the border refitted to the sub-pixel edge
    # points puts it 3 px off, and the calibration meets the bound
    scene, _, feat = detect(50036)
    sw = scene.screen_px[0]
    true = scene.screen_to_image(np.array([[-0.5, -0.5], [sw - 0.5, -0.5]]))
    assert float(np.hypot(*(feat.border.vertices[[0, 2]] - true).T).max()) < 4.0
    e = heldout_errors(scene, feat)
    assert_within_bound(e)


def test_a_hidden_corner_is_a_clear_refusal_naming_the_corner() -> None:
    # seed 50106: an occluder hides the screen's bottom corners (the border there is
    # 80-100 image px off); calibrated anyway, the radial map was 20 px off at worst
    with pytest.raises(CalibrationError, match="bottom-left corner.* hidden"):
        detect(50106)


def test_a_corner_off_by_a_fraction_of_a_coarse_grid_is_still_refused(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # seed 55094 (held out on 2026-12-05, then looked at): 4 x 4 dots, 301 screen px
    # apart, strong barrel; with the white and black captures compared at their own
    # exposures the border's right-hand corners were 27-30 image px off. The best of
    # the three lens models put a corner 0.2 spacings (60 px) off, within half a
    # spacing; calibrated, the map was 89 px off at its worst. The corners are held to 2 %
    # of the screen's width too.
    monkeypatch.setattr(features, "exposure_gain", lambda *a: 1.0)
    with pytest.raises(CalibrationError, match="corner is .* at most 38 px"):
        detect(55094)
    # at one exposure (auto-exposure gain 0.42) the corners are within 0.7 image px and
    # the scene calibrates within the bound
    monkeypatch.undo()
    sc, _, feat = detect(55094)
    e = heldout_errors(sc, feat)
    assert_within_bound(e)


def test_grow_lattice_follows_a_bending_grid_and_skips_a_missing_dot() -> None:
    # a 6 x 8 lattice, spacing 10, bent by a quadratic term that shifts the far
    # column by 1.1 spacings against the centre one: predicting every dot from the
    # nominal lattice would index it a row off; growth does not (the first step in
    # each direction is the nominal one, so the bend is zero at the start dot)
    j, i = np.meshgrid(np.arange(8), np.arange(6))
    pts = np.stack([10.0 * j, 10.0 * i + 0.7 * (j - 3) ** 2], axis=-1).reshape(-1, 2)
    keep = np.ones(len(pts), bool)
    keep[2 * 8 + 5] = False  # dot (2, 5) missing
    start = 3 * 8 + 3 - 1  # dot (3, 3): its place among the kept dots
    index = _grow_lattice(pts[keep], (10.0, 10.0), start)
    kept = np.flatnonzero(keep)
    assert len(index) == keep.sum()
    for (a, b), k in index.items():
        assert divmod(int(kept[k]), 8) == (3 + a, 3 + b)


def test_strong_barrel_centre_indexes_every_dot_at_its_true_position() -> None:
    # seed 68076 (held out 2026-12-07, then looked at): 640x480, k1 = -0.34 with a
    # 334 px focal length; the middle of the picture is magnified ~1.4 x against the
    # border corners' homography, so no blob lay within the gate of the nominal first
    # step and the scene was refused ("found 5 of 81")
    scene, grid, feat = detect(68076)
    assert grid.count == 81 and feat.dots.count >= 80  # was 5
    true_uv = scene.screen_to_image(grid.centers)
    err = np.hypot(*(feat.dots.centers - true_uv).T)[feat.dots.found]
    assert float(err.max()) < 1.0  # every dot found at its own true image position
    assert_within_bound(heldout_errors(scene, feat))


def test_grow_lattice_first_step_adapts_to_a_magnified_middle_not_to_a_diagonal() -> None:
    # a 5 x 7 lattice with spacing (14, 8): 1.4 x the nominal (10, 5.7) the growth is
    # given, beyond its gate of the nominal step; the first step is the nearest blob
    # along each direction. With the start dot's right neighbour missing, the next one
    # along the row (2.8 nominal steps) and the diagonal one (off the row) are not taken
    j, i = np.meshgrid(np.arange(7), np.arange(5))
    pts = np.stack([14.0 * j, 8.0 * i], axis=-1).reshape(-1, 2)
    start = 2 * 7 + 3
    index = _grow_lattice(pts, (10.0, 8.0 / 1.4), start)
    assert len(index) == len(pts)
    for (a, b), k in index.items():
        assert divmod(int(k), 7) == (2 + a, 3 + b)
    keep = np.ones(len(pts), bool)
    keep[2 * 7 + 4] = False  # dot (2, 4) missing
    kept = np.flatnonzero(keep)
    index = _grow_lattice(pts[keep], (10.0, 8.0 / 1.4), start)
    assert len(index) == keep.sum()  # (2, 5) .. reached around the gap, at the right index
    for (a, b), k in index.items():
        assert divmod(int(kept[k]), 7) == (2 + a, 3 + b)
