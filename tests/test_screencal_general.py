"""Screen calibration beyond the fixtures: any dot layout, borders that cannot land on the
wall, errors that say what was found, the coded pattern, the CLI's --truth/--plot/--layout,
and a small sample of ``omnidev eval screen`` with real assertions."""

from __future__ import annotations

import json
from dataclasses import replace
from functools import cache
from pathlib import Path

import cv2
import numpy as np
import pytest

from omnidev.cli.main import main
from omnidev.errors import CalibrationError
from omnidev.evaluation.framework import load_task, run_one
from omnidev.screencal.calibration import (
    calibrate_screen,
    detect_screen,
    detect_screen_coded,
    fit_calibration,
    load_screen_calibration,
)
from omnidev.screencal.coded import charuco_pattern
from omnidev.screencal.features import to_gray
from omnidev.screencal.patterns import (
    black_pattern,
    dot_grid,
    dot_pattern,
    layout_from_dict,
    white_pattern,
)
from omnidev.sim.codec import Compression
from omnidev.sim.screen_scenes import SceneRanges, ScreenScene, capture_stills, draw_scene

SCREEN = (1920, 1080)
RANGES = SceneRanges(
    resolutions=((1280, 720),),
    screen_resolutions=(SCREEN,),
    occluder_prob=0.0,
    crop_prob=0.0,
    codecs=(("jpeg", 1.0),),
)


def _errors(scene: ScreenScene, calib: object) -> np.ndarray:
    W, H = SCREEN
    xy = np.stack(np.meshgrid(np.arange(0, W, 40.0), np.arange(0, H, 40.0)), -1).reshape(-1, 2)
    xy = xy[scene.visible(xy)]
    est = calib.image_to_screen(scene.screen_to_image(xy))  # type: ignore[attr-defined]
    e = np.asarray(np.hypot(*(est - xy).T))
    return e[np.isfinite(e)]  # points a grid method maps off the screen are left out


@cache
def _scene(seed: int) -> ScreenScene:
    return draw_scene(seed, RANGES)


@cache
def _shots(seed: int, rows: int, cols: int, margin: float | None) -> tuple[np.ndarray, ...]:
    grid = dot_grid(*SCREEN, rows=rows, cols=cols, margin=margin)
    pats = [white_pattern(*SCREEN), black_pattern(*SCREEN), dot_pattern(*SCREEN, layout=grid)[0]]
    pats.append(charuco_pattern(*SCREEN)[0])
    return tuple(capture_stills(_scene(seed), pats))


def test_layout_round_trips_and_is_checked() -> None:
    g = dot_grid(*SCREEN, rows=7, cols=7, margin=0.05)
    assert g.shape == (7, 7) and g.margin_px == (96.0, 54.0)
    np.testing.assert_allclose(g.centers[0], [95.5, 53.5])
    np.testing.assert_allclose(g.centers[-1], [1920 - 96.5, 1080 - 54.5])
    back = layout_from_dict(json.loads(json.dumps(g.to_dict())))
    np.testing.assert_array_equal(back.centers, g.centers)
    with pytest.raises(ValueError, match="missing key 'rows'"):
        layout_from_dict({"screen": [1920, 1080]})
    with pytest.raises(ValueError, match="outer dots would cross the screen's edge"):
        dot_grid(*SCREEN, rows=5, cols=5, margin=0.005, radius_px=20)


def test_seven_by_seven_with_five_percent_margin_calibrates_and_saves(tmp_path: Path) -> None:
    """The issue's example layout; the calibration file keeps it."""
    w, b, d, _ = _shots(3, 7, 7, 0.05)
    grid = dot_grid(*SCREEN, rows=7, cols=7, margin=0.05)
    c = calibrate_screen(w, b, d, layout=grid)
    assert c.dots_used == 49
    e = _errors(_scene(3), c)
    # measured: RMS 0.16, max 0.63 screen px (1280x720 camera, JPEG)
    assert np.sqrt(np.mean(e**2)) < 0.5 and e.max() < 1.5, (np.sqrt(np.mean(e**2)), e.max())
    path = tmp_path / "c.yml"
    c.save(path)
    back = load_screen_calibration(path)
    assert back.layout is not None and back.layout.shape == (7, 7)
    assert back.layout.margin_px == pytest.approx((96.0, 54.0))
    uv = _scene(3).screen_to_image(np.array([[500.0, 400.0], [1500.0, 900.0]]))
    np.testing.assert_allclose(back.image_to_screen(uv), c.image_to_screen(uv), atol=1e-6)


def test_rectangular_layout_every_method() -> None:
    w, b, d, _ = _shots(5, 6, 11, 0.08)
    f = detect_screen(w, b, d, layout=dot_grid(*SCREEN, rows=6, cols=11, margin=0.08))
    assert f.dots.count == 66 and f.shape == (6, 11)
    rms = {
        m: float(np.sqrt(np.mean(_errors(_scene(5), fit_calibration(f, m)) ** 2)))
        for m in ("radial", "bilinear", "idw", "homography", "tsai")
    }
    assert rms["radial"] < 0.5 and rms["idw"] > 5 * rms["radial"], rms


def test_wrong_layout_says_what_was_found() -> None:
    w, b, d, _ = _shots(3, 7, 7, 0.05)
    with pytest.raises(CalibrationError, match=r"found \d+ of the 9 x 9 = 81 dots.*7 rows x 7 col"):
        calibrate_screen(w, b, d, n=9)
    with pytest.raises(CalibrationError, match="check --layout / --n"):
        calibrate_screen(w, b, d, n=5)


def test_border_ignores_a_room_brightened_by_auto_exposure() -> None:
    """Full auto-exposure: the room is brighter in the black capture than in the white
    one; the screen's corners stay on the screen (within one image px of the truth)."""
    sc = replace(_scene(3), ae_strength=1.0, ae_lag=1.0, compression=Compression("none"))
    W, H = SCREEN
    w, b = capture_stills(sc, [white_pattern(W, H), black_pattern(W, H)])
    room = sc.image_to_screen(np.array([[3.0, 3.0]]))[0]
    assert not (0 <= room[0] < W and 0 <= room[1] < H)  # pixel (3, 3) is on the wall
    assert int(to_gray(b)[3, 3]) > int(to_gray(w)[3, 3]) + 5
    grid = dot_grid(W, H)
    d = capture_stills(sc, [white_pattern(W, H), dot_pattern(W, H)[0]])[1]
    f = detect_screen(w, b, d, layout=grid)
    truth = np.array([[-0.5, -0.5], [W - 0.5, -0.5], [W - 0.5, H - 0.5], [-0.5, H - 0.5]])
    off = np.hypot(*(f.border.vertices[[0, 2, 4, 6]] - sc.screen_to_image(truth)).T)
    # measured: 0.3-0.7 image px (the region's outline is pixel-quantized at the corners)
    assert off.max() < 1.0, off


def test_coded_pattern_identifies_corners_under_occlusion() -> None:
    w, b, _, coded = _shots(3, 9, 9, None)
    _, lay = charuco_pattern(*SCREEN)
    occ = coded.copy()
    occ[:, : occ.shape[1] // 3] = b[:, : occ.shape[1] // 3]  # a third of the board hidden
    f = detect_screen_coded(w, b, occ, lay)
    assert 0.4 < f.dots.count / lay.lattice.count < 0.8
    c = fit_calibration(f, "radial")
    found = f.dots.found
    truth = _scene(3).screen_to_image(lay.lattice.centers[found])
    assert np.hypot(*(f.dots.centers[found] - truth).T).max() < 0.5  # no corner misindexed
    e = _errors(_scene(3), c)
    assert np.median(e) < 1.0
    with pytest.raises(CalibrationError, match="ChArUco corners"):
        detect_screen_coded(w, b, b, lay)


def test_cli_layout_truth_and_plot_without_truth(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pats = tmp_path / "pats"
    assert (
        main(
            [
                "calibrate",
                "screen",
                "--write-patterns",
                str(pats),
                "--rows",
                "7",
                "--cols",
                "7",
                "--margin",
                "0.05",
            ]
        )
        == 0
    )
    lay = json.loads((pats / "layout.json").read_text())
    assert (lay["rows"], lay["cols"], lay["margin_px"]) == (7, 7, [96.0, 54.0])
    w, b, d, _ = _shots(3, 7, 7, 0.05)
    files = {}
    for name, img in (("white", w), ("black", b), ("dots", d)):
        files[name] = tmp_path / f"{name}.png"
        cv2.imwrite(str(files[name]), img)  # colour files: the CLI converts as the API does
    sc = _scene(3)
    xy = np.array([[300.0, 200.0], [1000.0, 500.0], [1700.0, 900.0]])
    truth = tmp_path / "truth.json"
    truth.write_text(
        json.dumps({"image_points": sc.screen_to_image(xy).tolist(), "screen_points": xy.tolist()})
    )
    base = [
        "calibrate",
        "screen",
        "--white",
        str(files["white"]),
        "--black",
        str(files["black"]),
        "--dots",
        str(files["dots"]),
        "--layout",
        str(pats / "layout.json"),
    ]
    out = tmp_path / "c.yml"
    plot = tmp_path / "p.png"
    assert main([*base, "-o", str(out), "--plot", str(plot)]) == 0
    assert cv2.imread(str(plot)) is not None and "dots used: 49 of 49" in capsys.readouterr().out
    api = calibrate_screen(w, b, d, layout=layout_from_dict(lay))
    uv = sc.screen_to_image(xy)
    np.testing.assert_allclose(
        load_screen_calibration(out).image_to_screen(uv), api.image_to_screen(uv), atol=1e-9
    )  # CLI = API
    assert main([*base, "-o", str(out), "--force", "--truth", str(truth)]) == 0
    assert "truth points: 3" in capsys.readouterr().out
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"image_points": [[1, 2]]}))
    assert main([*base, "-o", str(out), "--force", "--truth", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "missing key 'screen_points'" in err and len(err.strip().splitlines()) == 1
    assert main([*base[:-2], "-o", str(out), "--force", "--n", "9"]) == 2
    assert "7 rows x 7 col" in capsys.readouterr().err


@pytest.mark.parametrize("seed", [5])
def test_eval_screen_sample(seed: int) -> None:
    """A scene of the evaluation (tuning seeds): calibrated within issue 12's bounds,
    the dissertation's IDW and the homography far worse, the coded pattern measured."""
    res = run_one(load_task("screen"), seed, dict(load_task("screen").options), None)
    assert res.status == "ok", res.message
    m = res.metrics
    assert m["radial.rms"] <= 0.5 and m["radial.max"] <= 1.5, m
    assert m["idw.rms"] > 5 and m["homography.rms"] > m["radial.rms"]
    assert m["coded.ok"] == 1.0 and m["coded.radial.rms"] < 1.0
    assert res.flags["in_spec"] and res.classes["camera"] == ">=640x480"


def test_eval_screen_outline_must_leave_a_pixel_beyond_every_side() -> None:
    """A screen whose top side lies 0.03 px inside the range of pixel centres (scene
    67075) is refused as cut by the picture's edge and is not in the task's spec; one
    0.65 px inside (64180) is."""
    from omnidev.evaluation.tasks.screen import SCREEN_MARGIN_PX, screen_margin
    from omnidev.sim.screen_scenes import draw_scene

    cut, kept = draw_scene(67075), draw_scene(64180)
    assert 0.0 < screen_margin(cut) < 0.05 and 0.6 < screen_margin(kept) < 0.7
    assert cut.screen_fully_visible() and kept.screen_fully_visible()
    res = run_one(load_task("screen"), 67075, {**load_task("screen").options, "coded": False}, None)
    assert res.status == "refused" and "cut by the picture's top edge" in res.message
    assert not res.flags["in_spec"] and screen_margin(cut) < SCREEN_MARGIN_PX
