"""``omnidev mouse`` on a rendered fixture into the record sink, against the fixture's truth."""

from __future__ import annotations

import json

import numpy as np

from omnidev.cli.main import main
from omnidev.sim import monitor as mon
from omnidev.sim.monitor import make_mouse_fixture
from omnidev.sinks.record import read_events


def layout_dict():
    return mon.landmark_layout()


def test_mouse_cli_errors(tmp_path, capsys):
    assert main(["mouse", "nope.avi", "--layout", str(tmp_path / "l.json")]) == 2
    assert "landmark layout file not found" in capsys.readouterr().err
    assert main(["mouse", "nope.avi", "--layout", str(tmp_path)]) == 2
    assert f"{tmp_path}: is a folder, not a landmark layout file" in capsys.readouterr().err
    layout = tmp_path / "l.json"
    layout.write_text(json.dumps(layout_dict()))
    assert main(["mouse", str(tmp_path / "missing.avi"), "--layout", str(layout)]) == 2
    err = capsys.readouterr().err
    assert "missing.avi" in err and err.strip().count("\n") == 0
    bad = tmp_path / "bad.avi"
    bad.write_bytes(b"not a video")
    assert main(["mouse", str(bad), "--layout", str(layout)]) == 2
    err = capsys.readouterr().err
    assert "bad.avi: OpenCV cannot read this file as a video" in err
    assert err.strip().count("\n") == 0
    no_offsets = tmp_path / "no_offsets.json"
    no_offsets.write_text(json.dumps({k: v for k, v in layout_dict().items() if k != "offsets_mm"}))
    fx = tmp_path / "fx"
    make_mouse_fixture(fx, trajectory="drift", frames=1, fps=30)
    assert main(["mouse", str(fx / "mouse.avi"), "--layout", str(no_offsets)]) == 2
    err = capsys.readouterr().err
    assert "no_offsets.json" in err and "missing key 'offsets_mm'" in err
    assert err.strip().count("\n") == 0


def test_landmark_sheet_is_true_size(tmp_path, capsys):
    import re

    import cv2

    from omnidev.mouse.landmarks import LandmarkLayout

    out = tmp_path / "sheet"
    argv = ["mouse-landmarks", str(out), "--screen-mm", "527x296", "--circle-mm", "20"]
    assert main(argv) == 0
    page = cv2.imread(str(out / "landmarks.png"), cv2.IMREAD_GRAYSCALE)
    assert page.shape == (3508, 2480)  # A4 at 300 dpi
    _, _, stats, _ = cv2.connectedComponentsWithStats((page < 60).astype(np.uint8))
    *_, c1, c2, c3, c4, bar = sorted(stats[1:, cv2.CC_STAT_WIDTH])  # 4 circles, the scale bar
    want = 20.0 / 25.4 * 300
    assert all(abs(w - want) <= 2 for w in (c1, c2, c3, c4)), ((c1, c2, c3, c4), want)
    assert abs(bar - 100.0 / 25.4 * 300) <= 6  # the 100 mm scale bar (ticks add a few px)
    box = re.search(rb"MediaBox \[ ?0 0 ([\d.]+) ([\d.]+)", (out / "landmarks.pdf").read_bytes())
    assert box and abs(float(box[1]) - 595.276) < 0.01 and abs(float(box[2]) - 841.89) < 0.01
    layout = LandmarkLayout.from_dict(json.loads((out / "landmarks.json").read_text()))
    assert layout.screen_width_mm == 527 and layout.circle_diameter_mm == 20
    assert main(argv) == 2  # exists: not overwritten without --force
    assert "--force" in capsys.readouterr().err


def test_mouse_cli_frame_size_change_is_one_line_error(tmp_path, capsys):
    import cv2

    fx = tmp_path / "fx"
    make_mouse_fixture(fx, trajectory="drift", frames=3, fps=30)
    frames = tmp_path / "frames"
    frames.mkdir()
    cap = cv2.VideoCapture(str(fx / "mouse.avi"))
    for i in range(3):
        ok, img = cap.read()
        assert ok
        cv2.imwrite(str(frames / f"f{i}.png"), img)
    cv2.imwrite(str(frames / "f3.png"), cv2.resize(img, (320, 240)))
    layout = tmp_path / "landmarks.json"
    layout.write_text(json.dumps(layout_dict()))
    rec = tmp_path / "events.jsonl"
    argv = ["mouse", f"images:{frames}", "--layout", str(layout), "--sink-option", f"path={rec}"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "frame 3 is 320x240, the stream was 640x480" in err[-1], err
    events = list(read_events(rec))
    assert [e for e in events if e["kind"] == "move"]  # a still-image source may drop frames
    assert events[-1]["kind"] == "close"


def test_mouse_cli_dwell_click_on_a_still_hand(tmp_path, capsys):
    """A still hand (tremor only) rests the cursor: one dwell click, after the dwell time."""
    fx = tmp_path / "still"
    make_mouse_fixture(fx, trajectory="still", size=(320, 240), frames=40, fps=30)
    rec = tmp_path / "events.jsonl"
    argv = [
        "mouse", f"video:{fx}/mouse.avi?rate=30", "--layout", str(fx / "landmarks.json"),
        "--sink-option", f"path={rec}", "--fov-deg", "56.1", "--dwell", "--dwell-s", "0.8",
    ]  # fmt: skip
    assert main(argv) == 0
    assert "1 dwell clicks" in capsys.readouterr().err
    events = list(read_events(rec))
    moves = [e for e in events if e["kind"] == "move"]
    buttons = [(e["button"], e["down"], e["frame_ns"]) for e in events if e["kind"] == "button"]
    assert [(b, d) for b, d, _ in buttons] == [("left", True), ("left", False)]
    # on the frames' timestamps, which the dwell runs on (the write times of a loaded
    # machine can bunch up)
    rested = (buttons[0][2] - moves[0]["frame_ns"]) / 1e9
    print(f"\ndwell click {rested:.2f} s after the first cursor position (dwell 0.8 s)")
    assert 0.8 <= rested <= 1.3
