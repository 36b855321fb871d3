"""Laser pointer speed at 1280x720, single-threaded: spot detection per frame, and the
screen calibration.

Frames come from omnidev.sim.screen.laser_video (k1 = -0.25, red laser over changing
slides, frames without a spot included). Figures:
- detect_ms_per_frame: SpotDetector.detect (median over every frame, the first
  frame of each pass excluded: it starts the background model); target <= 2 ms.
- detect_reference_ms_per_frame: the same with step=1 (every pixel a candidate
  pixel, the straightforward reference path); detect_speedup: reference / fast.
- slide_change_ms: detect on the frames judged a slide change (median).
- colour_detect_ms_per_frame: ColourSpotDetector.detect (the default method, no
  white core needed), median over the same frames (the first of each pass
  excluded); target <= 2 ms.
- anchor_minmaxloc_ms: what a user would write instead, the brightest pixel of the
  laser channel (cv2.extractChannel + cv2.minMaxLoc, no background, no tests);
  colour_vs_anchor: colour_detect_ms_per_frame / anchor_minmaxloc_ms.
- calibrate_ms: calibrate_screen on the rendered white, black and 9 x 9 dot images
  (median of the runs).
"""

from __future__ import annotations

import time
from typing import Any

import cv2
import numpy as np

from omnidev.laser.colour_spot import ColourSpotDetector
from omnidev.laser.spot import SpotDetector
from omnidev.screencal.calibration import calibrate_screen
from omnidev.screencal.patterns import black_pattern, dot_pattern, white_pattern
from omnidev.sim.screen import laser_video, render, screen_rig


def run(quick: bool = False) -> dict[str, Any]:
    cv2.setNumThreads(1)
    rig = screen_rig((1280, 720), -0.25)
    sw, sh = rig.screen_px
    white = render(rig, white_pattern(sw, sh), frame_seed=1)
    black = render(rig, black_pattern(sw, sh), frame_seed=2)
    dots = render(rig, dot_pattern(sw, sh, 9)[0], frame_seed=3)
    cal_ms: list[float] = []
    cal = None
    for _ in range(1 if quick else 3):
        t0 = time.perf_counter_ns()
        cal = calibrate_screen(white, black, dots, n=9, screen_size=(sw, sh))
        cal_ms.append((time.perf_counter_ns() - t0) / 1e6)
    assert cal is not None
    mask = cal.screen_mask()
    frames = [img for img, _, _ in laser_video(rig, 40 if quick else 120, colour="red", seed=0)]
    timing: dict[str, list[float]] = {"fast": [], "reference": [], "change": []}
    for name, step in (("fast", None), ("reference", 1)):
        for _ in range(1 if quick else 3):
            det = SpotDetector("red", mask, step=step)
            for i, img in enumerate(frames):
                changes = det.slide_changes
                t0 = time.perf_counter_ns()
                det.detect(img)
                ms = (time.perf_counter_ns() - t0) / 1e6
                if i == 0:
                    continue
                if det.slide_changes != changes:
                    if name == "fast":
                        timing["change"].append(ms)
                else:
                    timing[name].append(ms)
    colour_ms: list[float] = []
    anchor_ms: list[float] = []
    for _ in range(1 if quick else 3):
        cdet = ColourSpotDetector("red", mask)
        for i, img in enumerate(frames):
            t0 = time.perf_counter_ns()
            cdet.detect(img)
            ms = (time.perf_counter_ns() - t0) / 1e6
            t1 = time.perf_counter_ns()
            cv2.minMaxLoc(cv2.extractChannel(img, 2))
            anchor = (time.perf_counter_ns() - t1) / 1e6
            if i:
                colour_ms.append(ms)
                anchor_ms.append(anchor)
    fast, ref = float(np.median(timing["fast"])), float(np.median(timing["reference"]))
    col, anc = float(np.median(colour_ms)), float(np.median(anchor_ms))
    return {
        "frame": "1280x720 BGR (omnidev.sim.screen.laser_video, k1 -0.25, red)",
        "threads": 1,
        "detect_ms_per_frame": round(fast, 3),
        "detect_reference_ms_per_frame": round(ref, 3),
        "detect_speedup": round(ref / fast, 1),
        "slide_change_ms": round(float(np.median(timing["change"])), 3)
        if timing["change"]
        else None,
        "colour_detect_ms_per_frame": round(col, 3),
        "anchor_minmaxloc_ms": round(anc, 3),
        "colour_vs_anchor": round(col / anc, 1),
        "colour_detect_p95_ms": round(float(np.percentile(colour_ms, 95)), 3),
        "calibrate_ms": round(float(np.median(cal_ms)), 1),
        "calibration_method": cal.method,
        "dots_used": cal.dots_used,
    }
