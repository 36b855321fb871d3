"""``omnidev calibrate screen`` then ``omnidev laser`` on the committed screen fixtures into
the record sink: the whole chain (pattern images -> calibration -> spot detection ->
screen position through the calibration -> pipeline -> sink) against the rendered truth."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from omnidev.cli.main import main
from omnidev.sinks.record import read_events

SCREEN = Path(__file__).resolve().parents[1] / "fixtures" / "screen"
FIXTURES = [("k1-0.25-1280x720", "red"), ("k1+0.10-640x480", "green")]


def run_chain(tmp: Path, name: str, colour: str) -> tuple[np.ndarray, int, int]:
    """Errors (screen px) of the positions recorded, spot frames, frames without spot."""
    fx = SCREEN / name
    calib = tmp / f"{name}.yml.gz"
    argv = [
        "calibrate", "screen", "--white", str(fx / "white.png"), "--black",
        str(fx / "black.png"), "--dots", str(fx / "dots.png"), "-o", str(calib),
    ]  # fmt: skip
    assert main(argv) == 0
    rec = tmp / f"{name}.jsonl"
    argv = [
        "laser", str(fx / "laser.avi"), "--calibration", str(calib), "--colour", colour,
        "--sink-option", f"path={rec}", "--filter", "none",
    ]  # fmt: skip
    assert main(argv) == 0
    frames = json.loads((fx / "truth.json").read_text())["laser"]["per_frame"]
    spots = [f["spot"] for f in frames if f.get("spot") is not None]
    moves = [e for e in read_events(rec) if e["kind"] == "move"]
    # a file source keeps every frame: one position per frame with a spot, none without
    assert len(moves) == len(spots)
    err = np.array(
        [
            np.hypot(m["x"] * 1919 - s[0], m["y"] * 1079 - s[1])
            for m, s in zip(moves, spots, strict=True)
        ]
    )
    return err, len(spots), len(frames) - len(spots)


@pytest.fixture(scope="module")
def chains(tmp_path_factory):
    """The chain run once per fixture: name -> (errors px, spot frames, empty frames)."""
    tmp = tmp_path_factory.mktemp("laser")
    return {name: run_chain(tmp, name, colour) for name, colour in FIXTURES}


@pytest.mark.parametrize("name,colour", FIXTURES)
def test_laser_cli_on_fixture_into_record(chains, name, colour):
    err, spots, empty = chains[name]
    within = float(np.mean(err <= 1.5))
    print(
        f"\nomnidev laser on {name}: {len(err)} positions for {spots} spot frames, no position "
        f"on the {empty} frames without spot; error RMS {np.sqrt(np.mean(err**2)):.2f} px, "
        f"max {err.max():.2f} px, {100 * within:.1f} % within 1.5 px"
    )
    # at 640x480, 1.5 screen px is 0.4 camera px: per video >= 95 %; the issue's
    # >= 99 % holds over the fixture videos together (next test)
    assert within >= 0.95


def test_laser_over_the_fixture_videos_together(chains):
    err = np.concatenate([chains[name][0] for name, _ in FIXTURES])
    ok = int(np.sum(err <= 1.5))
    print(f"\nomnidev laser over the fixture videos: {ok}/{len(err)} within 1.5 px")
    assert ok / len(err) >= 0.99


def test_laser_cli_errors(tmp_path, capsys):
    assert main(["laser", "x.avi", "--calibration", str(tmp_path / "none.yml")]) == 2
    assert "screen calibration file not found" in capsys.readouterr().err
    assert main(["laser", "x.avi", "--calibration", str(tmp_path)]) == 2
    assert f"{tmp_path}: is a folder, not a screen calibration file" in capsys.readouterr().err
    assert main(["laser", "x.avi", "--calibration", "/dev/null"]) == 2
    assert "/dev/null: is a device, not a regular file" in capsys.readouterr().err


def test_laser_cli_detector_options(tmp_path, capsys):
    cal = tmp_path / "screen.yml"
    cal.write_text("%YAML:1.0\n")
    assert main(["laser", "x.avi", "--calibration", str(cal), "--detector-option", "bogus"]) == 2
    assert "--detector-option 'bogus': expected KEY=VALUE" in capsys.readouterr().err
    argv = ["laser", "x.avi", "--calibration", str(cal), "--detector-option", "method=colour"]
    assert main(argv) == 2
    assert "use --method" in capsys.readouterr().err
