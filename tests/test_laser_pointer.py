"""The laser-pointer tracker plugin: the committed fixture videos through the screen
calibration made from the fixture's own white, black and dot images, against the
spot's true screen position (1920 x 1080 px). ``pytest -s`` prints the figures."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from omnidev.errors import TrackerError
from omnidev.frame import Frame
from omnidev.screencal.calibration import calibrate_screen
from omnidev.sim.screen import load_screen_fixture
from omnidev.tracking import open_tracker

REPO = Path(__file__).resolve().parents[1]
FIXTURES = sorted((REPO / "fixtures" / "screen").glob("k1*"))


@pytest.fixture(scope="module", params=FIXTURES, ids=[f.name for f in FIXTURES])
def calibrated(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> tuple[Path, Path]:
    folder: Path = request.param
    white, black, dots = (
        np.asarray(cv2.imread(str(folder / f"{k}.png")), np.uint8)
        for k in ("white", "black", "dots")
    )
    cal = calibrate_screen(white, black, dots, n=9, screen_size=(1920, 1080))
    path = tmp_path_factory.mktemp("laser") / "screen.yml"
    cal.save(path)
    return folder, path


def test_fixture_through_calibration(calibrated: tuple[Path, Path]) -> None:
    folder, path = calibrated
    _, doc = load_screen_fixture(folder)
    colour = doc["laser"]["colour"]
    tracker = open_tracker("laser-pointer", {"colour": colour}, path)
    cap = cv2.VideoCapture(str(folder / "laser.avi"))
    errors: list[float] = []
    missed = false = empty = 0
    for f in doc["laser"]["per_frame"]:
        ok, img = cap.read()
        assert ok, f"{folder}/laser.avi: frame {f['index']} unreadable"
        s = tracker.track(Frame(np.asarray(img, np.uint8), 1000 + f["index"], f["index"]))
        if s is not None:
            assert s.timestamp_ns == 1000 + f["index"]
        if f["spot"] is None:
            empty += 1
            false += s is not None
        elif s is None:
            missed += 1
        else:
            errors.append(float(np.hypot(s.x * 1919 - f["spot"][0], s.y * 1079 - f["spot"][1])))
    e = np.asarray(errors)
    within = float(np.sum(e <= 1.5)) / (len(e) + missed)
    print(
        f"\n{folder.name} ({colour}) through the calibration: {len(e) + missed} frames with a "
        f"spot, {100 * within:.1f} % within 1.5 screen px (RMS {np.sqrt(np.mean(e**2)):.2f}, "
        f"max {e.max():.2f} px, {missed} missed); {empty} without: {false} false spots"
    )
    assert false == 0
    assert within >= 0.9


def test_wrong_frame_size(calibrated: tuple[Path, Path]) -> None:
    _, path = calibrated
    tracker = open_tracker("laser-pointer", {}, path)
    with pytest.raises(TrackerError, match="frame 7 is 100x80, the screen calibration is for"):
        tracker.track(Frame(np.zeros((80, 100, 3), np.uint8), 0, 7))


def test_errors_are_one_line(tmp_path: Path) -> None:
    cases = [
        ({"colour": "red"}, None, "needs a screen calibration"),
        ({"color": "red"}, None, "unknown option 'color'"),
        ({"colour": "blue"}, None, "colour must be one of red, green, any"),
        ({"rise": "high"}, None, "rise must be a whole number"),
        ({}, tmp_path / "absent.yml", "does not exist"),
    ]
    for options, cal, text in cases:
        with pytest.raises(TrackerError, match=text) as info:
            open_tracker("laser-pointer", options, cal)
        assert "\n" not in str(info.value)
    bad = tmp_path / "bad.yml"
    bad.write_text("not a calibration\n")
    with pytest.raises(TrackerError, match="laser-pointer: .*bad.yml") as info:
        open_tracker("laser-pointer", {}, bad)
    assert "\n" not in str(info.value)
