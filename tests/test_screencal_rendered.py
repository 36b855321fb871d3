"""Screen calibration on rendered screens (omnidev.sim.screen) against the exact truth.

Issue 5's acceptance: on a 1920x1080 screen at k1 = -0.25 (1280x720 and 640x480), the
default method's error over a dense grid of held-out screen points (every 20 px,
border pixels included, never a dot) is RMS <= 0.5 px and max <= 1.5 px. Tsai, the
global homography and the dissertation's IDW are measured beside it (printed with -s).
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import cv2
import numpy as np
import pytest

from omnidev.cli.main import main
from omnidev.errors import CalibrationError
from omnidev.screencal.calibration import (
    DEFAULT_METHOD,
    METHODS,
    ScreenFeatures,
    calibrate_screen,
    detect_screen,
    fit_calibration,
    load_screen_calibration,
)
from omnidev.screencal.evaluate import MethodErrors, compare_methods, heldout_grid, table
from omnidev.screencal.features import find_border, threshold_map
from omnidev.screencal.patterns import black_pattern, dot_pattern, white_pattern
from omnidev.screencal.plots import plot_error_vectors
from omnidev.sim.screen import ScreenRig, load_screen_fixture, render, screen_rig, screen_to_image

REPO = Path(__file__).resolve().parents[1]
FIX = REPO / "fixtures" / "screen"
SCREEN = (1920, 1080)


def _grey(img: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)


@cache
def _case(name: str) -> tuple[ScreenRig, np.ndarray, np.ndarray, np.ndarray]:
    """(rig, white, black, dots): a committed fixture folder or 'WxH/k1' rendered."""
    if (FIX / name).is_dir():
        rig, _ = load_screen_fixture(FIX / name)
        imgs = [
            cv2.imread(str(FIX / name / f), cv2.IMREAD_GRAYSCALE)
            for f in ("white.png", "black.png", "dots.png")
        ]
        return rig, imgs[0], imgs[1], imgs[2]
    size_txt, k1 = name.split("/")
    w, h = (int(x) for x in size_txt.split("x"))
    rig = screen_rig((w, h), float(k1))
    pats = (white_pattern(*SCREEN), black_pattern(*SCREEN), dot_pattern(*SCREEN)[0])
    imgs = [_grey(render(rig, p, frame_seed=k + 1)) for k, p in enumerate(pats)]
    return rig, imgs[0], imgs[1], imgs[2]


@cache
def _features(name: str) -> ScreenFeatures:
    _, w, b, d = _case(name)
    return detect_screen(w, b, d, n=9, screen_size=SCREEN)


@cache
def _compare(name: str) -> dict[str, MethodErrors]:
    rig = _case(name)[0]
    xy = heldout_grid(SCREEN)
    rows = compare_methods(_features(name), screen_to_image(rig, xy), xy)
    print(f"\n{name}: {len(xy)} held-out points\n{table(rows)}")
    return {r.method: r for r in rows}


ACCEPTANCE = ["k1-0.25-1280x720", "640x480/-0.25"]
OTHERS = ["k1+0.10-640x480", "1280x720/0.10", "640x480/-0.30", "1280x720/-0.30"]


@pytest.mark.parametrize("name", ACCEPTANCE)
def test_default_method_meets_the_acceptance(name: str) -> None:
    r = _compare(name)[DEFAULT_METHOD]
    assert r.missed == 0
    assert r.rms <= 0.5 and r.max <= 1.5, (r.rms, r.max)
    # measured: RMS 0.023 / 0.037 px, max 0.35 / 0.52 px
    assert r.rms <= 0.1 and r.max <= 0.8


@pytest.mark.parametrize("name", ACCEPTANCE + OTHERS)
def test_every_method_measured_and_default_is_best(name: str) -> None:
    rows = _compare(name)
    best = rows[DEFAULT_METHOD]
    assert best.missed == 0 and best.rms <= 0.5 and best.max <= 1.6
    for m in METHODS:
        assert rows[m].rms >= best.rms
    # the baselines as measured (Fig. 5.13's comparison, on held-out points)
    assert rows["homography"].max > 10  # no lens distortion in the model
    assert rows["idw"].rms > 15  # eqs. 5.4-5.5 are exact only at the grid nodes
    assert rows["tsai"].rms < 2.0 and rows["bilinear"].rms < 4.0


def test_dot_centres_within_a_fiftieth_of_a_pixel() -> None:
    rig = _case("k1-0.25-1280x720")[0]
    f = _features("k1-0.25-1280x720")
    truth = screen_to_image(rig, f.screen_dots)
    err = np.hypot(*(f.dots.centers - truth).T)
    assert f.dots.count == 81 and err.max() < 0.05, err.max()


def test_border_coarse_to_fine_equals_exhaustive_search() -> None:
    _, w, b, _ = _case("k1+0.10-640x480")
    t = threshold_map(w, b)
    np.testing.assert_array_equal(find_border(t, step=1).vertices, find_border(t, step=3).vertices)


def test_recaptured_dot_image_fig_5_14(tmp_path: Path) -> None:
    name = "k1-0.25-1280x720"
    _, w, b, _ = _case(name)
    d2 = cv2.imread(str(FIX / name / "dots_recaptured.png"), cv2.IMREAD_GRAYSCALE)
    again = detect_screen(w, b, d2, n=9, screen_size=SCREEN)
    f = _features(name)
    rows = [
        MethodErrors(m, f.screen_dots, fit_calibration(f, m).image_to_screen(again.dots.centers))
        for m in METHODS
    ]
    print("\nre-captured dots (Fig. 5.14)\n" + table(rows))
    by = {r.method: r for r in rows}
    # the camera moved (0.03 deg, f +0.15 %): about half an image pixel, 1-2 screen px
    assert by["radial"].rms < 2.0 and by["radial"].max < 3.0
    assert by["idw"].rms > by["radial"].rms and by["homography"].rms > by["radial"].rms
    out = tmp_path / "fig514.png"
    plot_error_vectors(rows, out, SCREEN, dots=f.screen_dots)
    img = cv2.imread(str(out))
    assert img is not None and img.shape[0] > 500 and img.shape[1] > 1000


def test_partial_grid_calibrates_and_counts_dots() -> None:
    rig, w, b, d = _case("k1+0.10-640x480")
    occ = d.copy()
    occ[100:260, 120:300] = b[100:260, 120:300]  # a person standing in front
    c = calibrate_screen(w, b, occ)
    assert 41 <= c.dots_used < 81
    xy = heldout_grid(SCREEN, 40)
    e = MethodErrors("radial", xy, c.image_to_screen(screen_to_image(rig, xy)))
    # measured: 58 dots (3 cut by the occluder's edge dropped), RMS 0.23 px, max 2.5 px
    # (in the corner the occluder hides, the model extrapolates)
    assert e.missed == 0 and e.rms < 0.5 and e.max < 3.0, (c.dots_used, e.rms, e.max)
    for m in ("idw", "bilinear"):  # missing grid nodes come from the radial model
        assert fit_calibration(_features_of(w, b, occ), m).dots_used == c.dots_used


def _features_of(w: np.ndarray, b: np.ndarray, d: np.ndarray) -> ScreenFeatures:
    return detect_screen(w, b, d)


@pytest.mark.parametrize(
    ("which", "message"),
    [
        ("swapped", "black image is brighter than the white image"),
        ("white-as-dots", "is it the white image"),
        ("black-as-dots", "dots not found"),
        ("no-screen", "screen not found"),
        ("occluded", "dots occluded"),
        ("other-scene", "do not line up with the screen border"),
    ],
)
def test_bad_input_gets_one_clear_error(which: str, message: str) -> None:
    _, w, b, d = _case("k1+0.10-640x480")
    args = {
        "swapped": (b, w, d),
        "white-as-dots": (w, b, w),
        "black-as-dots": (w, b, b),
        "no-screen": (w, w, d),
    }.get(which)
    if which == "occluded":
        occ = d.copy()
        occ[:, :330] = b[:, :330]
        args = (w, b, occ)
    if which == "other-scene":
        other = _grey(render(screen_rig((640, 480), 0.10, tilt_deg=5.0), dot_pattern(*SCREEN)[0]))
        args = (w, b, other)
    assert args is not None
    with pytest.raises(CalibrationError, match=message) as exc:
        calibrate_screen(*args)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("method", METHODS)
def test_save_load_round_trip(tmp_path: Path, method: str) -> None:
    c = fit_calibration(_features("k1+0.10-640x480"), method)
    path = tmp_path / "calib.yml.gz"
    c.save(path)
    back = load_screen_calibration(path)
    assert (back.method, back.image_size, back.screen_size, back.dots_used) == (
        method,
        (640, 480),
        SCREEN,
        81,
    )
    uv = np.stack(np.meshgrid(np.arange(0, 640, 37.0), np.arange(0, 480, 29.0)), -1).reshape(-1, 2)
    np.testing.assert_allclose(back.image_to_screen(uv), c.image_to_screen(uv), atol=1e-6)
    np.testing.assert_array_equal(back.screen_mask(), c.screen_mask())


def test_load_errors_name_file_and_key(tmp_path: Path) -> None:
    path = tmp_path / "bad.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("kind", "screen-calibration")
    fs.write("format_version", 1)
    fs.write("method", "radial")
    fs.release()
    with pytest.raises(CalibrationError, match=r"bad\.yml: missing number key 'image_width'"):
        load_screen_calibration(path)


def test_cli_calibrates_a_fixture_and_writes_patterns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fx = FIX / "k1+0.10-640x480"
    out = tmp_path / "c.yml.gz"
    plot = tmp_path / "err.png"
    rc = main(
        [
            "calibrate",
            "screen",
            "--white",
            str(fx / "white.png"),
            "--black",
            str(fx / "black.png"),
            "--dots",
            str(fx / "dots.png"),
            "-o",
            str(out),
            "--truth",
            str(fx / "truth.json"),
            "--plot",
            str(plot),
        ]
    )
    text = capsys.readouterr().out
    assert rc == 0 and out.is_file() and cv2.imread(str(plot)) is not None
    assert "dots used: 81 of 81; method radial" in text and "tsai" in text
    assert load_screen_calibration(out).method == "radial"
    pats = tmp_path / "pats"
    assert (
        main(
            [
                "calibrate",
                "screen",
                "--write-patterns",
                str(pats),
                "--screen",
                "800x600",
                "--n",
                "5",
            ]
        )
        == 0
    )
    dots = cv2.imread(str(pats / "dots.png"), cv2.IMREAD_GRAYSCALE)
    np.testing.assert_array_equal(dots, dot_pattern(800, 600, 5)[0])
    assert cv2.imread(str(pats / "white.png"), cv2.IMREAD_GRAYSCALE).min() == 255
    rc = main(
        [
            "calibrate",
            "screen",
            "--white",
            str(fx / "black.png"),
            "--black",
            str(fx / "white.png"),
            "--dots",
            str(fx / "dots.png"),
            "-o",
            str(tmp_path / "x.yml"),
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2 and "swapped" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.yml").exists()
