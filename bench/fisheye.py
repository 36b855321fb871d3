"""Fisheye map building for a 1920x1080 perspective view, single-threaded (issue 7).

Cameras: the Mei paracatadioptric camera of shared/realdata (1280x1024, xi 1.443,
radial-tangential distortion and skew, as cv2.omnidir calibrated it) and the
TUM-VI cam0 KB4 lens (512x512), both mounted looking forward; the view is
``perspective:1920x1080,fov=100,pan=10,tilt=5,roll=2``. OpenCV gets the same view as R
and P (omnidev.fisheye.maps.rotation_for_opencv / camera_matrix_for_opencv); its maps
agree with omnidev's within 0.05 px (tests/test_fisheye_maps.py).

Figures (medians over interleaved repetitions, ms; cv2.setNumThreads(1); numpy's
elementwise arithmetic is single-threaded):
- mei_view_maps_ms: omnidev.fisheye.maps.view_maps (float32 maps + validity mask).
- omnidir_ms: cv2.omnidir.initUndistortRectifyMap(..., CV_32FC1, RECTIFY_PERSPECTIVE),
  the anchor. ratio_vs_omnidir = mei_view_maps_ms / omnidir_ms (target <= 1.0).
- kb4_view_maps_ms, cv_fisheye_ms: the same for KB4 and cv2.fisheye.initUndistortRectifyMap;
  ratio_vs_fisheye = kb4_view_maps_ms / cv_fisheye_ms.
- mei_reference_ms: the plain float64 path (view points -> FisheyeCamera.project ->
  maps), the numpy reference the fast path is tested against; reference_vs_omnidir.
- remap_ms: cv2.remap of a 1280x1024 BGR frame with the float maps (bilinear);
  remap_fixed_ms: omnidev.camera.Remapper (fixed-point maps), per frame.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from omnidev.camera import Remapper
from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
from omnidev.fisheye.maps import (
    camera_matrix_for_opencv,
    reference_maps,
    rotation_for_opencv,
    view_maps,
)
from omnidev.fisheye.models import KannalaBrandt, Unified
from omnidev.views import Perspective

VIEW = Perspective(1920, 1080, 100.0, pan_deg=10.0, tilt_deg=5.0, roll_deg=2.0)
MEI = Unified(
    366.0786746575819,
    366.1677891988819,
    643.7193980161953,
    521.3166467512945,
    1.44309762366835,
    skew=-1.730277473341805,
    k1=0.1097909284122646,
    k2=0.216601395090228,
    p1=0.0008254647531474698,
    p2=-0.0002583633785147333,
)
KB4 = KannalaBrandt(
    190.97847715128717,
    190.9733070521226,
    254.93170605935475,
    256.8974428996504,
    (0.0034823894022493434, 0.0007150348452162257, -0.0020532361418706202, 0.00020293673591811182),
)


def _interleaved_ms(fns: dict[str, Callable[[], object]], reps: int) -> dict[str, float]:
    """Median ms of each function, run in turn reps times (after one warm-up each)."""
    for fn in fns.values():
        fn()
    times: dict[str, list[float]] = {k: [] for k in fns}
    for _ in range(reps):
        for key, fn in fns.items():
            t0 = time.perf_counter_ns()
            fn()
            times[key].append((time.perf_counter_ns() - t0) / 1e6)
    return {k: float(np.median(v)) for k, v in times.items()}


def _opencv_mei(camera: FisheyeCamera) -> Callable[[], object]:
    lens = camera.lens
    assert isinstance(lens, Unified)
    K = np.array([[lens.fx, lens.skew, lens.cx], [0, lens.fy, lens.cy], [0, 0, 1.0]])
    D = np.array([[lens.k1, lens.k2, lens.p1, lens.p2]])
    xi = np.array([[lens.xi]])
    R, P = rotation_for_opencv(VIEW, camera.mount), camera_matrix_for_opencv(VIEW)
    size = (VIEW.width, VIEW.height)
    flags = cv2.omnidir.RECTIFY_PERSPECTIVE
    return lambda: cv2.omnidir.initUndistortRectifyMap(K, D, xi, R, P, size, cv2.CV_32FC1, flags)


def _opencv_kb4(camera: FisheyeCamera) -> Callable[[], object]:
    lens = camera.lens
    assert isinstance(lens, KannalaBrandt)
    K = np.array([[lens.fx, lens.skew, lens.cx], [0, lens.fy, lens.cy], [0, 0, 1.0]])
    D = np.array(lens.k)
    R, P = rotation_for_opencv(VIEW, camera.mount), camera_matrix_for_opencv(VIEW)
    size = (VIEW.width, VIEW.height)
    return lambda: cv2.fisheye.initUndistortRectifyMap(K, D, R, P, size, cv2.CV_32FC1)


def run(quick: bool = False) -> dict[str, Any]:
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        reps = 5 if quick else 21
        mei = FisheyeCamera(MEI, (1280, 1024), MOUNTS["forward"])
        kb4 = FisheyeCamera(KB4, (512, 512), MOUNTS["forward"])
        t = _interleaved_ms(
            {
                "mei": lambda: view_maps(mei, VIEW),
                "omnidir": _opencv_mei(mei),
                "kb4": lambda: view_maps(kb4, VIEW),
                "fisheye": _opencv_kb4(kb4),
            },
            reps,
        )
        ref = _interleaved_ms({"ref": lambda: reference_maps(mei, VIEW)}, max(1, reps // 7))
        maps = view_maps(mei, VIEW)
        rng = np.random.default_rng(7)
        frame = rng.integers(0, 256, (1024, 1280, 3), dtype=np.uint8)
        remapper = Remapper(maps)
        r = _interleaved_ms(
            {
                "remap": lambda: cv2.remap(
                    frame, maps.map_x, maps.map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT
                ),
                "fixed": lambda: remapper(frame),
            },
            reps,
        )
    finally:
        cv2.setNumThreads(threads)
    return {
        "threads": 1,
        "view": "perspective:1920x1080,fov=100,pan=10,tilt=5,roll=2",
        "mei_view_maps_ms": round(t["mei"], 2),
        "omnidir_ms": round(t["omnidir"], 2),
        "ratio_vs_omnidir": round(t["mei"] / t["omnidir"], 3),
        "kb4_view_maps_ms": round(t["kb4"], 2),
        "cv_fisheye_ms": round(t["fisheye"], 2),
        "ratio_vs_fisheye": round(t["kb4"] / t["fisheye"], 3),
        "mei_reference_ms": round(ref["ref"], 1),
        "reference_vs_omnidir": round(ref["ref"] / t["omnidir"], 2),
        "valid_fraction": round(float(maps.valid.mean()), 4),
        "remap_ms": round(r["remap"], 2),
        "remap_fixed_ms": round(r["fixed"], 2),
    }
