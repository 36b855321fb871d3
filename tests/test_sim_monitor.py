"""The camera-mouse fixture renderer against its own geometric truth (omnidev.sim.monitor)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from omnidev.errors import OutputError
from omnidev.sim.handcam import HandCamera, Pose, project_points
from omnidev.sim.monitor import (
    LANDMARK_SQUARE,
    SCREEN_H,
    SCREEN_PX,
    SCREEN_W,
    TRAJECTORIES,
    MonitorScene,
    frame_truth,
    landmark_centers,
    landmark_labels,
    make_mouse_fixture,
    render_frame,
    render_pose,
    trajectory_pose,
)

CAM = HandCamera.default(640, 480)
CENTER = np.array([(CAM.width - 1) / 2, (CAM.height - 1) / 2])


def _opencv_project(pose: Pose, X: np.ndarray) -> np.ndarray:
    """Project world points with cv2.projectPoints (an independent implementation)."""
    rvec, _ = cv2.Rodrigues(pose.R)
    tvec = -pose.R @ pose.C
    uv, _ = cv2.projectPoints(X.reshape(-1, 1, 3), rvec, tvec, CAM.matrix(), CAM.distortion())
    return np.asarray(uv).reshape(-1, 2)


@pytest.mark.parametrize("name", TRAJECTORIES)
def test_cursor_truth_reprojects_to_image_center(name: str) -> None:
    worst = 0.0
    for i in range(0, 300, 7):
        pose = trajectory_pose(name, i / 30)
        truth = frame_truth(CAM, pose, i, i / 30)
        assert truth.screen_px is not None and truth.screen_xy is not None
        px, py = truth.screen_px
        X = np.array(
            [(px + 0.5) * SCREEN_W / SCREEN_PX[0], (py + 0.5) * SCREEN_H / SCREEN_PX[1], 0.0]
        )
        assert truth.screen_xy == pytest.approx((px / 1919, py / 1079))
        worst = max(worst, float(np.max(np.abs(_opencv_project(pose, X)[0] - CENTER))))
    assert worst < 0.01


def test_landmark_truth_matches_opencv_projection() -> None:
    for name in TRAJECTORIES:
        for i in range(0, 300, 11):
            pose = trajectory_pose(name, i / 30)
            truth = frame_truth(CAM, pose)
            ref = _opencv_project(pose, landmark_centers())
            for k, uv in enumerate(truth.landmarks_uv):
                if truth.visible[k]:
                    assert uv is not None
                    assert np.allclose(uv, ref[k], atol=1e-6)


def _dark_centroid(img: np.ndarray, labels: np.ndarray, k: int) -> tuple[float, float]:
    """Centroid of the dark disc inside landmark k's white square (grey-level weighted)."""
    mask = cv2.erode((labels == k).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(float)
    w = np.where(mask, np.clip(150.0 - grey, 0, None), 0.0)
    vv, uu = np.mgrid[0 : img.shape[0], 0 : img.shape[1]]
    return float((w * uu).sum() / w.sum()), float((w * vv).sum() / w.sum())


@pytest.mark.parametrize(("name", "t"), [("drift", 0.0), ("roll", 1.0), ("oblique", 3.0)])
def test_rendered_landmark_centroids_match_truth(name: str, t: float) -> None:
    pose = trajectory_pose(name, t)
    img = np.clip(render_pose(CAM, MonitorScene(0), pose, t) + 0.5, 0, 255).astype(np.uint8)
    truth = frame_truth(CAM, pose)
    assert all(truth.visible)
    labels = landmark_labels(CAM, pose)
    for k in range(4):
        uv = truth.landmarks_uv[k]
        assert uv is not None
        cu, cv = _dark_centroid(img, labels, k)
        assert math.hypot(cu - uv[0], cv - uv[1]) < 0.5, (name, k, (cu, cv), uv)


def test_trajectories_cover_the_issue_cases() -> None:
    def truths(name: str) -> list:  # type: ignore[type-arg]
        return [frame_truth(CAM, trajectory_pose(name, i / 30)) for i in range(300)]

    roll = [
        abs(math.degrees(math.atan2(-t.rotation[0][1], t.rotation[1][1]))) for t in truths("roll")
    ]
    assert 28.0 < max(roll) <= 31.0
    assert max(t.view_angle_deg for t in truths("oblique")) == pytest.approx(45.0, abs=0.5)
    missing = np.bincount([4 - sum(t.visible) for t in truths("partial")], minlength=5)
    assert missing[1] > 10 and missing[2] > 100
    assert all(all(t.visible) for t in truths("drift"))


def test_visibility_flags_agree_with_the_picture() -> None:
    cam = HandCamera.default(320, 240)
    h = LANDMARK_SQUARE / 2
    edge = np.linspace(-h, h, 33)
    ring = np.concatenate(
        [np.stack([edge, np.full(33, s)], 1) for s in (-h, h)]
        + [np.stack([np.full(33, s), edge], 1) for s in (-h, h)]
    )
    seen = {True: 0, False: 0}
    for i in range(0, 300, 4):
        pose = trajectory_pose("partial", i / 30)
        truth = frame_truth(cam, pose)
        labels = landmark_labels(cam, pose)
        for k, c in enumerate(landmark_centers()):
            uv, _ = project_points(
                cam, pose, np.concatenate([c[:2] + ring, np.zeros((len(ring), 1))], 1)
            )
            margin = np.min(
                np.concatenate(
                    [
                        uv[:, 0] + 0.5,
                        cam.width - 0.5 - uv[:, 0],
                        uv[:, 1] + 0.5,
                        cam.height - 0.5 - uv[:, 1],
                    ]
                )
            )
            if abs(margin) < 1.5:
                continue  # the square's edge is within a pixel of the border: ambiguous
            region = labels == k
            touches = (
                region[0].any() or region[-1].any() or region[:, 0].any() or region[:, -1].any()
            )
            in_picture = bool(region.any() and not touches)
            assert truth.visible[k] == in_picture, (i, k)
            seen[in_picture] += 1
    assert seen[True] > 50 and seen[False] > 50


def test_frames_are_deterministic_from_the_seed() -> None:
    cam = HandCamera.default(160, 120)
    kw = {"supersample": 2, "blur_samples": 2}
    a, ta = render_frame(cam, MonitorScene(3), "sweep", 5, seed=3, **kw)  # type: ignore[arg-type]
    b, tb = render_frame(cam, MonitorScene(3), "sweep", 5, seed=3, **kw)  # type: ignore[arg-type]
    c, _ = render_frame(cam, MonitorScene(4), "sweep", 5, seed=4, **kw)  # type: ignore[arg-type]
    assert np.array_equal(a, b) and ta == tb
    assert not np.array_equal(a, c)


def test_fixture_writer(tmp_path: Path) -> None:
    out = tmp_path / "mouse"
    doc = make_mouse_fixture(out, trajectory="sweep", size=(160, 120), frames=3, seed=1)
    assert sorted(p.name for p in out.iterdir()) == [
        "landmarks.json",
        "mouse.avi",
        "mouse_0000.png",
        "truth.json",
    ]
    truth = json.loads((out / "truth.json").read_text())
    assert truth == json.loads(json.dumps(doc))
    assert len(truth["per_frame"]) == 3 and truth["camera"]["distortion"][0] == CAM.k1
    assert "omnidev sim mouse" in truth["regenerate"]
    cap = cv2.VideoCapture(str(out / "mouse.avi"))
    n = 0
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        assert frame.shape == (120, 160, 3)
        n += 1
    assert n == 3
    with pytest.raises(OutputError, match="not empty"):
        make_mouse_fixture(out, frames=1, size=(160, 120))
    with pytest.raises(OutputError, match="trajectory"):
        make_mouse_fixture(tmp_path / "x", trajectory="loop")
    assert not (tmp_path / ".mouse.tmp").exists() and not (tmp_path / "x").exists()


def test_no_false_lock_variants_have_what_they_say() -> None:
    cam = HandCamera.default(320, 240)
    pose = trajectory_pose("drift", 0.0)
    normal = render_pose(cam, MonitorScene(0, content=False), pose, 0.0, supersample=2)
    three = render_pose(
        cam, MonitorScene(0, content=False, variant="three-landmarks"), pose, 0.0, supersample=2
    )
    empty = render_pose(cam, MonitorScene(0, variant="no-monitor"), pose, 0.0, supersample=2)
    truth = frame_truth(cam, pose)
    t3 = frame_truth(cam, pose, variant="three-landmarks")
    t0 = frame_truth(cam, pose, variant="no-monitor")
    assert truth.visible == [True] * 4 and t3.visible == [True, True, True, False]
    assert t3.landmarks_uv[3] is None and t3.screen_xy == truth.screen_xy
    assert t0.visible == [False] * 4 and t0.screen_xy is None and not t0.on_screen
    # only bottom_left's square differs between normal and three-landmarks
    lab = landmark_labels(cam, pose)
    diff = np.abs(normal - three).max(axis=2) > 1.0
    assert diff.any() and np.all(lab[diff] == 3)
    assert np.all(landmark_labels(cam, pose, "three-landmarks") != 3)
    # without the monitor no pixel is as dark as a landmark disc
    assert float(empty.mean(axis=2).min()) > 60.0 and float(normal.mean(axis=2).min()) < 20.0
    with pytest.raises(OutputError, match="scene"):
        MonitorScene(0, variant="two")


def test_sweep_frames_are_motion_blurred() -> None:
    cam = HandCamera.default(160, 120)
    scene = MonitorScene(0, content=False)
    sharp, _ = render_frame(cam, scene, "sweep", 0, blur_samples=1, supersample=2, noise_sigma=0)
    blurred, _ = render_frame(cam, scene, "sweep", 0, blur_samples=5, supersample=2, noise_sigma=0)
    grad = [float(np.abs(np.diff(i.astype(float), axis=1)).mean()) for i in (sharp, blurred)]
    assert grad[1] < 0.9 * grad[0]
