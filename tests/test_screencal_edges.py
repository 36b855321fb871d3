"""The radial calibration's edges, dot centroids and residual correction on randomized
scenes (issue 12). Seeds from the tuning range 50000-50199; the held-out figures are in
docs/screen-calibration.md."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from omnidev.screencal import calibration
from omnidev.screencal import dots as dots_mod
from omnidev.screencal.calibration import ScreenFeatures, detect_screen
from omnidev.screencal.features import (
    BorderPolygon,
    border_from_edges,
    border_from_region,
    edge_points,
    screen_region,
)
from omnidev.screencal.transform import (
    RadialMap,
    _radial_apply,
    invert,
    residual_predictability,
)
from omnidev.sim.screen_scenes import ScreenScene
from tests.screen_scene import assert_within_bound, detect, heldout_errors, scene


@pytest.mark.parametrize("seed", [50012, 50027, 50054])
def test_scenes_that_missed_the_bound_now_meet_it(seed: int) -> None:
    # before (radial, one edge offset, correction always): RMS / max 0.46 / 2.52,
    # 0.92 / 3.08 and 0.49 / 1.67 screen px of a 1920x1080 screen
    sc, _, feat = detect(seed)
    e = heldout_errors(sc, feat)
    assert_within_bound(e)


def test_outer_dots_beside_the_screen_edge_are_not_pulled_toward_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # seed 50027: 4 x 12 dots whose outer rows end 2 screen px from the screen's edge;
    # dividing by w - b pixel by pixel pulled them 0.2-0.76 image px (0.5 on average)
    # toward the edge. With the floor 0.09 px; 0.15 since w - b is taken with the black
    # capture at the white one's exposure (auto-exposure: gain 0.48 here), which over
    # the 285 auto-exposure scenes of the looked-at ranges passed 272 against 268
    sc, grid, caps = scene(50027)

    def outer_rows_off() -> float:
        feat = detect_screen(caps[0], caps[1], caps[2], layout=grid)
        err = (feat.dots.centers - sc.screen_to_image(feat.screen_dots)).reshape(4, 12, 2)
        return float(np.mean(np.abs(err[[0, -1], :, 1])))

    assert outer_rows_off() < 0.2
    monkeypatch.setattr(dots_mod, "EDGE_FLOOR", 0.0)  # the bare per-pixel ratio
    assert outer_rows_off() > 0.3


def _edge_scatter(sc: ScreenScene, feat: ScreenFeatures, **kw: float) -> float:
    """Std (image px along the normal) of the edge points about each side's median
    offset from the true edge."""
    caps = scene(sc.seed)[2]
    sw, sh = sc.screen_px
    devs = []
    sides = edge_points(caps[0], caps[1], feat.border, **kw)
    for e, axis, val in zip(sides, (1, 0, 1, 0), (-0.5, sw - 0.5, sh - 0.5, -0.5), strict=True):
        xy = sc.image_to_screen(e[:, :2])
        step = np.abs(sc.image_to_screen(e[:, :2] + 0.5 * e[:, 2:])[:, axis] - xy[:, axis]) / 0.5
        off = (xy[:, axis] - val) / step
        devs.append(off - np.median(off))
    return float(np.concatenate(devs).std())


def test_edge_points_averaged_over_a_strip_scatter_less() -> None:
    # seed 50012 (960x540, no codec): 0.10 px with one line per profile, 0.05 with nine
    sc, _, feat = detect(50012)
    one = _edge_scatter(sc, feat, strip=0.0)
    strip = _edge_scatter(sc, feat)
    assert strip < 0.07
    assert strip < 0.7 * one


def _lattice(rows: int = 7, cols: int = 9) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Screen dots of a 1920x1080 lattice and their images through a radial lens +
    homography (the model's own form), with the lattice parameters."""
    sx, sy = 1920 / (cols + 1), 1080 / (rows + 1)
    j, i = np.meshgrid(np.arange(cols), np.arange(rows))
    xy = np.c_[(j.ravel() + 1) * sx, (i.ravel() + 1) * sy]
    uv = 100 + xy * np.array([0.5, 0.48])
    c = uv.mean(axis=0)
    d = (uv - c) / 600
    uv = c + d * (1 - 0.08 * (d**2).sum(axis=1))[:, None] * 600
    return uv, xy, np.array([sx, sy, sx, sy])


def test_residual_correction_is_kept_only_for_a_field_the_neighbours_predict() -> None:
    rng = np.random.default_rng(3)
    uv, xy, lattice = _lattice()
    found = np.ones(len(xy), bool)
    noisy = uv + rng.normal(0, 0.1, uv.shape)
    m = RadialMap.fit(noisy, xy, (1280, 720), lattice, (7, 9), found)
    assert not m.residual.any()  # detection noise: left out
    assert (
        residual_predictability((xy - _radial_apply(m.p, noisy, m.scale)).reshape(7, 9, 2), found)
        > 0.9
    )
    # a smooth warp the lens model cannot take (a bump of 1.5 px across the middle)
    bump = 1.5 * np.exp(-(((uv[:, 0] - uv[:, 0].mean()) / 150) ** 2))
    warped = uv + np.c_[np.zeros(len(uv)), bump]
    m = RadialMap.fit(warped, xy, (1280, 720), lattice, (7, 9), found)
    assert np.abs(m.residual).max() > 1.0  # kept
    plain = np.hypot(*(_radial_apply(m.p, warped, m.scale) - xy).T)
    corrected = np.hypot(*(m(warped) - xy).T)
    assert corrected.max() < 0.01 < plain.max()
    forced = RadialMap.fit(noisy, xy, (1280, 720), lattice, (7, 9), found, correct=True)
    assert forced.residual.any()
    with pytest.raises(ValueError, match="edge_offset"):
        RadialMap.fit(noisy, xy, (1280, 720), lattice, (7, 9), found, edge_offset="x")


def _lattice_image(xy: np.ndarray) -> np.ndarray:
    """Screen px -> image px of :func:`_lattice`'s camera, for any screen points."""
    c = np.array([580.0, 359.2])  # the image of the lattice's centre
    d = (100 + xy * np.array([0.5, 0.48]) - c) / 600
    return np.asarray(c + d * (1 - 0.08 * (d**2).sum(axis=1))[:, None] * 600, np.float64)


def test_a_side_scattering_more_than_the_dots_weighs_less() -> None:
    # 28 edge points per side; the top side's scattered by 0.6 image px along its normal
    # (a codec's blocks), the others by 0.03, the dots by 0.05: at the fixed weight the
    # noisy side bends the map 0.30-0.57 screen px off along the border (5 seeds), with
    # each side weighed by its scatter 0.15-0.30 (mean 0.21 against 0.39)
    uv, xy, lattice = _lattice()
    assert np.allclose(_lattice_image(xy), uv)
    t = np.linspace(0.03, 0.97, 28)
    s = np.linspace(0.0, 1.0, 200)
    top, bottom = np.c_[s * 1919, 0 * s], np.c_[s * 1919, 0 * s + 1079]
    left, right = np.c_[0 * s, s * 1079], np.c_[0 * s + 1919, s * 1079]
    border = np.concatenate([top, bottom, left, right])
    worst: dict[bool, list[float]] = {True: [], False: []}
    for seed in range(5):
        rng = np.random.default_rng(seed)
        sides = []
        plan = [(1, -0.5, -1, 0.6), (0, 1919.5, 1, 0.03), (1, 1079.5, 1, 0.03), (0, -0.5, -1, 0.03)]
        for axis, value, out, noise in plan:  # top (noisy), right, bottom, left
            p = np.zeros((len(t), 2))
            p[:, axis] = value
            p[:, 1 - axis] = t * (1920 if axis == 1 else 1080)
            q = p.copy()
            q[:, axis] += out
            a, b = _lattice_image(p), _lattice_image(q)
            nrm = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)
            a = a + rng.normal(0, noise, (len(a), 1)) * nrm
            sides.append((np.c_[a, nrm], axis, value))
        noisy = uv + rng.normal(0, 0.05, uv.shape)
        for scatter in (True, False):
            m = RadialMap.fit(
                noisy, xy, (1280, 720), lattice, (7, 9), np.ones(len(xy), bool),
                edges=sides, edge_scatter=scatter,
            )  # fmt: skip
            worst[scatter].append(float(np.hypot(*(m(_lattice_image(border)) - border).T).max()))
    assert all(a < b for a, b in zip(worst[True], worst[False], strict=True))
    assert float(np.mean(worst[True])) < 0.7 * float(np.mean(worst[False]))


def test_a_side_with_no_edge_gives_no_points_and_no_error() -> None:
    # a lit rectangle whose polygon's top side lies 20 px above its top edge: no profile
    # there crosses an edge; the other sides give their points
    white = np.full((120, 160), 20, np.uint8)
    white[30:100, 20:140] = 220
    black = np.full((120, 160), 20, np.uint8)
    v = np.array(
        [[20, 10], [80, 10], [140, 10], [140, 55], [140, 100], [80, 100], [20, 100], [20, 55]],
        np.float64,
    ) - np.array([0.5, 0.5])
    top, right, bottom, left = edge_points(white, black, BorderPolygon(v))
    assert top.shape == (0, 4)
    for side, axis, value in ((right, 0, 139.5), (bottom, 1, 99.5), (left, 0, 19.5)):
        assert len(side) > 10
        assert np.abs(side[:, axis] - value).max() < 0.05


def test_border_refitted_to_the_edge_points_finds_the_corners_the_outline_misses() -> None:
    # where the light falls off toward a corner the thresholded outline turns ragged and
    # cuts in: its fitted corners were 9-18 image px off (50159, 424x240); refitted to
    # the sub-pixel edge points, 1.2 px. Since the black capture is taken to the white
    # one's exposure the refit is 1.7 px off at one corner and the calibration closer
    # (max 1.41 -> 1.14 screen px); 50183, here before, has its outline within 1.1 px now.
    sc, _, caps = scene(50159)
    sw, sh = sc.screen_px
    true = sc.screen_to_image(
        np.array([[-0.5, -0.5], [sw - 0.5, -0.5], [sw - 0.5, sh - 0.5], [-0.5, sh - 0.5]])
    )
    region = screen_region(caps[0], caps[1])
    outline = border_from_region(region)
    refit = border_from_edges(caps[0], caps[1], outline, region.black_gain)

    def worst(b: BorderPolygon) -> float:
        return float(np.hypot(*(b.vertices[[0, 2, 4, 6]] - true).T).max())

    assert worst(outline) > 4.0
    assert worst(refit) < 2.0


def test_corner_check_extrapolates_with_the_lens_model_that_agrees() -> None:
    # seed 50140: 10 x 8 dots with one spacing of margin; the three-term radial model of
    # the dots put the border's corner 0.48-0.55 spacings off (refused; 0.39 since the
    # dots are weighed at the dot capture's exposure), the one-term model 0.03; with the
    # edges the calibration meets the bound
    sc, _, feat = detect(50140)
    e = heldout_errors(sc, feat)
    assert_within_bound(e)
    d = feat.dots
    sw, sh = sc.screen_px
    corners = feat.border.vertices[[0, 2, 4, 6]]
    screen = np.array([[-0.5, -0.5], [sw - 0.5, -0.5], [sw - 0.5, sh - 0.5], [-0.5, sh - 0.5]])
    args = (
        d.centers[d.found],
        feat.screen_dots[d.found],
        feat.image_size,
        feat.lattice,
        d.shape,
        d.found,
    )
    off = {}
    for terms in (1, 3):
        m = RadialMap.fit(*args, correct=True, terms=terms)
        off[terms] = float(np.hypot(*(m(corners) - screen).T).max()) / float(feat.lattice[2:].min())
    assert off[3] > 0.3 > 0.1 > off[1]
    with pytest.raises(ValueError, match="terms"):
        RadialMap.fit(*args, terms=4)


def test_edge_profiles_reach_into_the_corners(monkeypatch: pytest.MonkeyPatch) -> None:
    # seed 50060 (1600x900, 9 x 9 dots): the worst error was at the screen's corner, where
    # the polynomial model's three terms extrapolated beyond the last edge profile (6 % of
    # the side from it): 1.92 px; with profiles to 3 % 1.16. The forward lens form's two
    # terms (the default since) hold the corner either way: 0.77 px with profiles to 6 %
    sc, grid, caps = scene(50060)
    e = heldout_errors(sc, detect(50060)[2])
    assert float(e.max()) <= 1.5
    assert float(heldout_errors(sc, detect(50060)[2], lens_form="poly").max()) <= 1.5
    monkeypatch.setattr(calibration, "EDGE_ENDS", 0.06)
    feat = detect_screen(caps[0], caps[1], caps[2], layout=grid)
    assert float(heldout_errors(sc, feat, lens_form="poly").max()) > 1.5
    assert float(heldout_errors(sc, feat).max()) <= 1.5


def test_invert_is_nan_without_a_warning_where_the_map_folds() -> None:
    """Newton's inversion of a map whose Jacobian is singular at a point: NaN there (the
    callers check for finite points), the exact inverse elsewhere, and no RuntimeWarning
    (it reached the CLI's stderr as "divide by zero")."""

    def fold(uv: np.ndarray) -> np.ndarray:  # x = u for u > 0, flat (0) for u <= 0; y = v
        return np.stack([np.maximum(uv[:, 0], 0.0), uv[:, 1]], axis=1)

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = invert(fold, np.array([[2.0, 1.0], [3.0, 2.0]]), np.array([[1.5, 0.0], [-5.0, 0.0]]))
    np.testing.assert_allclose(out[0], [2.0, 1.0], atol=1e-6)
    assert not np.isfinite(out[1]).all()


def test_corner_of_a_wildly_curved_side_is_found_without_overflow() -> None:
    """Held-out scene 59013 (an occluder over the bottom of a 424x240 picture): the
    bottom side's fit bends so far that the alternating projections onto it and the
    right side swung away to infinity (overflow, a NaN polygon). Corner 2 is now where
    the two fits pass closest."""
    from omnidev.screencal.features import _corners_and_mids, _side_point

    quad = np.array([[163.86, 91.65], [291.4, 72.85], [284.14, 130.06], [167.46, 165.8]])
    coefs = [
        np.array([1.63479e-01, -1.63200e-03, 1.50000e-05]),
        np.array([-5.3315e-02, 8.6730e-03, -7.0000e-05]),
        np.array([1.54317179e02, -3.08156600e00, 1.56390000e-02]),
        np.array([-3.26343e-01, 1.48100e-03, 6.10000e-05]),
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        corners, mids = _corners_and_mids(quad, coefs)
    assert np.isfinite(corners).all() and np.isfinite(mids).all()
    for i in (0, 1):  # away from the bottom side
        assert np.hypot(*(corners[i] - quad[i])) < 2.0, (i, corners[i])
    # corner 2 halfway between the fits where they pass closest (they do not meet here)
    t = np.linspace(0.75, 1.25, 2001)
    right = np.array([_side_point(coefs[1], quad[1], quad[2], x) for x in t])
    bottom = np.array([_side_point(coefs[2], quad[2], quad[3], x - 1.0) for x in t])
    gap = np.hypot(*(right[:, None] - bottom[None, :]).transpose(2, 0, 1)).min()
    to_right, to_bottom = (np.hypot(*(c - corners[2]).T).min() for c in (right, bottom))
    assert abs(to_right - gap / 2) < 0.5 and abs(to_bottom - gap / 2) < 0.5, (gap, to_right)
