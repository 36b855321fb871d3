"""The radial calibration's edges, dot centroids and residual correction on randomized
scenes (issue 12). Seeds from the tuning range 50000-50199; the held-out figures are in
docs/screen-calibration.md."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from omnidev.evaluation.tasks.screen import _captures, _to_ref, draw_layout, heldout_points
from omnidev.screencal import dots as dots_mod
from omnidev.screencal.calibration import ScreenFeatures, detect_screen, fit_calibration
from omnidev.screencal.features import BorderPolygon, edge_points
from omnidev.screencal.patterns import DotGrid
from omnidev.screencal.transform import RadialMap, _radial_apply, residual_predictability
from omnidev.sim.screen_scenes import ScreenScene, draw_scene


@cache
def _scene(seed: int) -> tuple[ScreenScene, DotGrid, list[np.ndarray]]:
    scene = draw_scene(seed)
    grid = draw_layout(seed, scene.screen_px, "random")
    return scene, grid, _captures(scene, grid, 3)


def _detect(seed: int) -> tuple[ScreenScene, ScreenFeatures]:
    scene, grid, caps = _scene(seed)
    return scene, detect_screen(caps[0], caps[1], caps[2], layout=grid)


@pytest.mark.parametrize("seed", [50012, 50027, 50054])
def test_scenes_that_missed_the_bound_now_meet_it(seed: int) -> None:
    # before (radial, one edge offset, correction always): RMS / max 0.46 / 2.52,
    # 0.92 / 3.08 and 0.49 / 1.67 screen px of a 1920x1080 screen
    scene, feat = _detect(seed)
    xy = heldout_points(scene.screen_px)
    xy = xy[scene.visible(xy)]
    est = fit_calibration(feat, "radial").image_to_screen(scene.screen_to_image(xy))
    e = np.hypot(*_to_ref(est - xy, scene.screen_px).T)
    assert np.isfinite(e).all()
    assert float(np.sqrt(np.mean(e**2))) <= 0.5
    assert float(e.max()) <= 1.5


def test_outer_dots_beside_the_screen_edge_are_not_pulled_toward_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # seed 50027: 4 x 12 dots whose outer rows end 2 screen px from the screen's edge;
    # dividing by w - b pixel by pixel pulled them 0.2-0.76 image px (0.5 on average)
    # toward the edge
    scene, grid, caps = _scene(50027)

    def outer_rows_off() -> float:
        feat = detect_screen(caps[0], caps[1], caps[2], layout=grid)
        err = (feat.dots.centers - scene.screen_to_image(feat.screen_dots)).reshape(4, 12, 2)
        return float(np.mean(np.abs(err[[0, -1], :, 1])))

    assert outer_rows_off() < 0.12
    monkeypatch.setattr(dots_mod, "EDGE_FLOOR", 0.0)  # the bare per-pixel ratio
    assert outer_rows_off() > 0.3


def _edge_scatter(scene: ScreenScene, feat: ScreenFeatures, **kw: float) -> float:
    """Std (image px along the normal) of the edge points about each side's median
    offset from the true edge."""
    caps = _scene(scene.seed)[2]
    sw, sh = scene.screen_px
    devs = []
    sides = edge_points(caps[0], caps[1], feat.border, **kw)
    for e, axis, val in zip(sides, (1, 0, 1, 0), (-0.5, sw - 0.5, sh - 0.5, -0.5), strict=True):
        xy = scene.image_to_screen(e[:, :2])
        step = np.abs(scene.image_to_screen(e[:, :2] + 0.5 * e[:, 2:])[:, axis] - xy[:, axis]) / 0.5
        off = (xy[:, axis] - val) / step
        devs.append(off - np.median(off))
    return float(np.concatenate(devs).std())


def test_edge_points_averaged_over_a_strip_scatter_less() -> None:
    # seed 50012 (960x540, no codec): 0.10 px with one line per profile, 0.05 with nine
    scene, feat = _detect(50012)
    one = _edge_scatter(scene, feat, strip=0.0)
    strip = _edge_scatter(scene, feat)
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
