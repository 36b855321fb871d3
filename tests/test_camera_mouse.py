"""The camera-mouse tracker plugin on frames of omnidev.sim.monitor, against the truth
cursor (the screen point under the image center) on a 1920x1080 screen."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from omnidev.frame import Frame
from omnidev.mouse.evaluate import cursor_error_px
from omnidev.sim import monitor as mon
from omnidev.sim.handcam import HandCamera
from omnidev.tracking import open_tracker

LAYOUT = mon.landmark_layout()
CAM = HandCamera.default()


@pytest.fixture(scope="module")
def layout_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("cm") / "landmarks.json"
    path.write_text(json.dumps(LAYOUT))
    return path


def run(layout_file, trajectory, frames, method, variant="normal", step=1, predict=None):
    tracker = open_tracker("camera-mouse", {"method": method}, layout_file)
    if predict is not None:
        tracker.tracker.predict = predict
    out = []
    for i in range(0, frames * step, step):
        img, truth = mon.render_frame(
            CAM, mon.MonitorScene(0, variant=variant), trajectory, i, supersample=2, blur_samples=2
        )
        s = tracker.track(Frame(img, i, i))
        out.append((s, truth, list(tracker.tracker.found) if tracker.locked else None))
    return out


def err_px(sample, truth):
    return float(
        np.hypot((sample.x - truth.screen_xy[0]) * 1919, (sample.y - truth.screen_xy[1]) * 1079)
    )


def test_drift_all_landmarks_visible(layout_file):
    res = {m: run(layout_file, "drift", 12, m) for m in ("homography", "affine")}
    errs = {m: [err_px(s, t) for s, t, _ in r if s is not None] for m, r in res.items()}
    rms = {m: float(np.sqrt(np.mean(np.square(e)))) for m, e in errs.items()}
    print(
        f"\ndrift, 12 frames: cursor RMS homography {rms['homography']:.2f} px, "
        f"affine {rms['affine']:.2f} px (1920x1080)"
    )
    assert len(errs["homography"]) == 12
    assert rms["homography"] <= 2.0


def test_partial_predicts_missing_landmarks(layout_file):
    """The partial trajectory loses one or two landmarks: they are predicted (sec. 6.2.5)."""
    res = run(layout_file, "partial", 15, "homography")
    pred = [err_px(s, t) for s, t, found in res if s is not None and found and not all(found)]
    diss = run(layout_file, "partial", 15, "homography", predict="translation")
    pred_d = [err_px(s, t) for s, t, found in diss if s is not None and found and not all(found)]
    print(
        f"\npartial, dissertation's translation prediction: {len(pred_d)} frames, "
        f"RMS {np.sqrt(np.mean(np.square(pred_d))):.2f} px"
    )
    print(
        f"\npartial: {len(pred)} frames with predicted landmarks, "
        f"RMS {np.sqrt(np.mean(np.square(pred))) if pred else float('nan'):.2f} px"
    )
    assert pred, "no frame tracked with a landmark missing"
    assert float(np.sqrt(np.mean(np.square(pred)))) <= 10.0


@pytest.mark.parametrize("variant", ["no-monitor", "three-landmarks"])
def test_no_false_lock(layout_file, variant):
    assert all(s is None for s, _, _ in run(layout_file, "drift", 4, "homography", variant))


def test_needs_its_layout(tmp_path):
    from omnidev.errors import TrackerError

    with pytest.raises(TrackerError, match="landmark layout"):
        open_tracker("camera-mouse", {}, None)
    bad = tmp_path / "l.json"
    bad.write_text(json.dumps({k: v for k, v in LAYOUT.items() if k != "offsets_mm"}))
    with pytest.raises(TrackerError, match="offsets_mm"):
        open_tracker("camera-mouse", {}, bad)


@pytest.mark.parametrize(
    ("value", "message"),
    [("x", "max_rigid_error must be a number, got 'x'"), ("-1", "must be 0 \\(off\\) .. 10")],
)
def test_max_rigid_error_is_checked(layout_file, value, message):
    from omnidev.errors import TrackerError

    with pytest.raises(TrackerError, match=message):
        open_tracker("camera-mouse", {"max_rigid_error": value}, layout_file)


def test_redetects_when_confidence_falls(layout_file):
    """A landmark whose prediction went wrong (pushed 60 px off, marked missing) is not
    found near there; while it is predicted the detection stage runs every
    ``redetect_every`` frames and re-locks on all four (sec. 6.2.5's re-detection)."""
    import cv2

    fx = Path(__file__).resolve().parents[1] / "fixtures" / "mouse" / "drift-640x480"
    truth = json.loads((fx / "truth.json").read_text())["per_frame"]
    cap = cv2.VideoCapture(str(fx / "mouse.avi"))
    frames = [cap.read()[1] for _ in range(12)]
    tracker = open_tracker("camera-mouse", {"redetect_every": 5}, fx / "landmarks.json")
    assert tracker.track(Frame(frames[0], 0, 0)) is not None
    tracker.tracker.centers[0] += (60.0, 40.0)  # a prediction gone wrong
    tracker.tracker.found[0] = False
    out, tl_found = [], []
    for i, f in enumerate(frames[1:], 1):
        out.append(tracker.track(Frame(f, i, i)))
        tl_found.append(tracker.tracker.found[0])
    print(f"\ntop-left found per frame after the bad prediction: {tl_found}")
    assert not any(tl_found[:4])  # predicted, not found near the wrong place
    assert tracker.relocks == 1, "no re-detection while a landmark was predicted"
    assert all(tl_found[5:])  # re-locked on all four at the 5th weak frame
    last = out[-1]
    assert last is not None and cursor_error_px((last.x, last.y), truth[11]["screen_xy"]) < 1.0
