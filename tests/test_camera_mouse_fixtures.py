"""Issue 4 acceptance on the committed camera-mouse fixtures (fixtures/mouse/).

Every video is tracked frame by frame (``omnidev mouse-eval``'s code path: the
camera-mouse tracker, no filter, no frame dropped) and the cursor is compared
with the rendered truth on a 1920x1080 screen:

- frames with all four landmarks visible: homography RMS <= 2 px (the
  dissertation's affine reported beside it);
- frames with one or two landmarks missing (predicted): RMS <= 10 px;
- frames with three or more missing: no cursor (the pointer holds);
- scenes with no monitor or only three landmarks: no cursor at all.

The tracker runs with its defaults (prediction by the monitor plane's image motion,
flow, whose fallback is the camera's rotation with a 60 degree field of view: the
fixtures' camera has 56.1 degrees, so the prior is deliberately not the truth).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from omnidev.cli.main import main
from omnidev.cli.mouse_cmd import evaluate_fixture
from omnidev.sinks.record import read_events

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "mouse"
NORMAL = sorted(
    p
    for p in FIXTURES.iterdir()
    if p.is_dir() and not p.name.startswith(("no-monitor", "three-landmarks"))
)
NEGATIVE = sorted(p for p in FIXTURES.iterdir() if p.name.startswith(("no-monitor", "three-")))


def test_the_fixtures_are_there():
    names = {p.name for p in NORMAL}
    assert {"drift-640x480", "sweep-640x480", "oblique-640x480", "partial-640x480"} <= names
    assert {"roll-320x240", "sweep-320x240", "excursion-320x240"} <= names
    assert len(NEGATIVE) == 2


@pytest.mark.parametrize("fixture", NORMAL, ids=lambda p: p.name)
def test_cursor_against_truth(fixture):
    hom = evaluate_fixture(fixture, "homography")
    aff = evaluate_fixture(fixture, "affine")
    a, p = hom["all4"], hom["predicted"]
    print(
        f"\n{fixture.name}: all four visible {a['frames']} frames, cursor on "
        f"{a['with_cursor']}: homography RMS {a['rms_px']:.2f} px (max {a['max_px']:.2f}), "
        f"affine {aff['all4']['rms_px']:.2f} px; predicted {p['frames']} frames, cursor on "
        f"{p['with_cursor']}: RMS {p['rms_px']:.2f} px (max {p['max_px']:.2f}); "
        f"3+ missing {hom['hold_frames']} frames, cursors there {hom['hold_violations']}"
    )
    assert a["frames"] > 0
    assert a["with_cursor"] >= 0.95 * a["frames"]  # at most the first frame or so lost
    assert a["rms_px"] <= 2.0
    if p["frames"] and not hom["hold_frames"]:
        assert p["with_cursor"] >= 0.9 * p["frames"]  # (after a hold, detection needs all 4)
    if p["with_cursor"]:
        assert p["rms_px"] <= 10.0
    assert hom["hold_violations"] == 0
    assert hom["false_cursors"] == 0


def test_predictions_compared_on_the_partial_fixture():
    """The dissertation's translation against similarity, camera rotation (the default
    before 2026-12-06) and the monitor plane's image motion (flow, the default). Flow
    once gave 15.3 px here: its homography, fitted to features bunched on one side and
    on drifting screen content, extrapolated up to 100 px off; with no features on the
    screen and a camera turn where that extrapolates the features nearest the missing
    landmarks better, 3.5 px."""
    fx = FIXTURES / "partial-640x480"
    rms = {m: evaluate_fixture(fx, "homography", m)["predicted"] for m in ("translation",
           "similarity", "rotation", "flow")}  # fmt: skip
    print(
        "\npartial-640x480, frames with landmarks predicted: "
        + ", ".join(f"{m} RMS {r['rms_px']:.2f} px (max {r['max_px']:.2f})" for m, r in rms.items())
    )
    for m in ("rotation", "flow"):
        assert rms[m]["with_cursor"] == rms[m]["frames"] > 50
        assert rms[m]["rms_px"] < rms["translation"]["rms_px"]
        assert rms[m]["rms_px"] <= 10.0
    assert rms["flow"]["rms_px"] <= 5.0


def test_three_or_more_missing_holds_then_relocks():
    """excursion: the aim leaves the screen (one landmark left in view) and comes back."""
    r = evaluate_fixture(FIXTURES / "excursion-320x240", "homography")
    truth = json.loads((FIXTURES / "excursion-320x240" / "truth.json").read_text())["per_frame"]
    back = [i for i in range(1, len(truth)) if sum(truth[i]["visible"]) == 4 and
            sum(truth[i - 1]["visible"]) < 4]  # fmt: skip
    assert r["hold_frames"] >= 30 and r["hold_violations"] == 0
    assert back, "the fixture never comes back to all four landmarks"
    assert r["all4"]["with_cursor"] >= r["all4"]["frames"] - 2


@pytest.mark.parametrize("fixture", NEGATIVE, ids=lambda p: p.name)
def test_no_false_lock_over_whole_videos(fixture):
    r = evaluate_fixture(fixture, "homography")
    n = r["all4"]["with_cursor"] + r["predicted"]["with_cursor"] + r["hold_violations"]
    print(f"\n{fixture.name}: {r['frames']} frames, {n} cursors")
    assert r["frames"] >= 30 and n == 0


def test_mouse_cli_on_a_fixture_into_record(tmp_path, capsys, caplog):
    """``omnidev mouse`` (the threaded pipeline, paced at 30 fps) into the record sink."""
    fx = FIXTURES / "drift-640x480"
    rec = tmp_path / "events.jsonl"
    argv = [
        "mouse", f"video:{fx}/mouse.avi?rate=30", "--layout", str(fx / "landmarks.json"),
        "--sink", "record", "--sink-option", f"path={rec}", "--filter", "none",
    ]  # fmt: skip
    assert main(argv) == 0
    # the end of a file ends the run; no "camera lost, retrying" on the way
    assert not [r for r in caplog.records if "retrying" in r.getMessage()]
    truth = json.loads((fx / "truth.json").read_text())["per_frame"]
    moves = [e for e in read_events(rec) if e["kind"] == "move"]
    # paced at 30 fps the source is live: a frame the tracker was too slow for (a loaded
    # machine) is dropped and counted; every other frame gave a cursor, named by index
    summary = re.search(r"(\d+) frames, (\d+) dropped", capsys.readouterr().err)
    assert summary is not None and int(summary[1]) == len(truth)
    assert len(moves) + int(summary[2]) == len(truth) and len(moves) >= 0.8 * len(truth)
    frames = [m["frame"] for m in moves]
    assert frames == sorted(set(frames))
    err = [
        np.hypot(
            (m["x"] - truth[i]["screen_xy"][0]) * 1919, (m["y"] - truth[i]["screen_xy"][1]) * 1079
        )
        for m, i in zip(moves, frames, strict=True)
    ]
    rms = float(np.sqrt(np.mean(np.square(err))))
    print(f"\nomnidev mouse on {fx.name} into record: RMS {rms:.2f} px, max {max(err):.2f} px")
    assert rms <= 2.0
