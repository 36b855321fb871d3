"""Camera-mouse speed at 640x480, single-threaded: tracking vs full detection per frame.

Frames come from omnidev.sim.monitor (drift trajectory, 30 frames). Figures:
- track_ms_per_frame: the tracking stage (sec. 6.2.4, four landmarks; ``predict="flow"``,
  the plugin's default) + cursor;
  track_parts_ms splits it (medians): to_gray (BGR to grey, whole frame),
  landmarks (LandmarkTracker.update), cursor (corners and homography).
- detect_ms_per_frame: the detection stage (sec. 6.2.1) + cursor.
- dissertation_ms_per_frame_320x240: the dissertation's reported 11-14 ms per
  320x240 frame for its whole process (Pentium 4, 3 GHz; sec. 6.3), for reference.
- detect_vs_track: detection / tracking.
Targets: tracking <= 1 ms, detection <= 15 ms.
"""

from __future__ import annotations

import time
from typing import Any

import cv2
import numpy as np

from omnidev.mouse.detect import detect_landmarks, to_gray
from omnidev.mouse.geometry import cursor_homography, image_center, screen_corners_from_landmarks
from omnidev.mouse.landmarks import LandmarkLayout
from omnidev.mouse.track import LandmarkTracker
from omnidev.sim import monitor as mon
from omnidev.sim.handcam import HandCamera


def run(quick: bool = False) -> dict[str, Any]:
    cv2.setNumThreads(1)
    cam = HandCamera.default()
    layout = LandmarkLayout(
        mon.SCREEN_W * 1000,
        mon.SCREEN_H * 1000,
        tuple((ox * 1000, oy * 1000) for ox, oy in mon.LANDMARK_OFFSETS),
        mon.LANDMARK_RADIUS * 2000,
        mon.LANDMARK_SQUARE * 1000,
    )
    n = 10 if quick else 30
    frames = [
        mon.render_frame(cam, mon.MonitorScene(0), "drift", i, supersample=2, blur_samples=2)[0]
        for i in range(n)
    ]
    center = image_center(cam.width, cam.height)
    det_ms: list[float] = []
    trk_ms: list[float] = []
    parts: dict[str, list[float]] = {"to_gray": [], "landmarks": [], "cursor": []}
    tracker = LandmarkTracker(predict="flow")  # the camera-mouse plugin's default
    first = detect_landmarks(frames[0], layout)
    assert first is not None, "no landmarks detected in the benchmark's first frame"
    radius = (
        mon.LANDMARK_RADIUS
        * 2000
        / 2
        * float(
            np.mean(np.linalg.norm(np.diff(first.centers[[0, 1, 2, 3, 0]], axis=0), axis=1))
            / np.mean(
                np.linalg.norm(
                    np.diff(layout.landmark_centers_mm()[[0, 1, 2, 3, 0]], axis=0), axis=1
                )
            )
        )
    )
    for _ in range(3 if quick else 5):
        # the clip replays from its first frame: lock again there, so that every
        # frame times a tracker that follows the landmarks (not one lost after the jump)
        tracker.lock(first.centers, radius)
        for img in frames:
            t0 = time.perf_counter_ns()
            d = detect_landmarks(img, layout)
            if d is not None:
                cursor_homography(d.screen_corners, center)
            t1 = time.perf_counter_ns()
            gray = to_gray(img)
            tg = time.perf_counter_ns()
            c = tracker.update(gray)
            tl = time.perf_counter_ns()
            if c is not None:
                cursor_homography(screen_corners_from_landmarks(c, layout), center)
            t2 = time.perf_counter_ns()
            det_ms.append((t1 - t0) / 1e6)
            trk_ms.append((t2 - t1) / 1e6)
            parts["to_gray"].append((tg - t1) / 1e6)
            parts["landmarks"].append((tl - tg) / 1e6)
            parts["cursor"].append((t2 - tl) / 1e6)
    track, detect = float(np.median(trk_ms)), float(np.median(det_ms))
    return {
        "frame": "640x480 BGR (omnidev.sim.monitor, drift)",
        "threads": 1,
        "track_ms_per_frame": round(track, 3),
        "track_parts_ms": {k: round(float(np.median(v)), 3) for k, v in parts.items()},
        "detect_ms_per_frame": round(detect, 3),
        "detect_vs_track": round(detect / track, 1),
        "dissertation_ms_per_frame_320x240": "11-14 (Pentium 4, whole process)",
    }
