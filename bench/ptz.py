"""Virtual PTZ: how long a map rebuild takes per camera kind, against a frame's time.

A steerable view (``[[stream.view]]`` with a perspective view, ``omnidev ctl view``)
rebuilds its maps on the stream's steer thread while the remap thread goes on
with the old ones; a move is smooth when a rebuild fits in a frame time. Cameras of
1920x1920 images (bench/video.py's: an equidistant fisheye looking up, a
pano-mapping table of an SVP hyperbolic mirror, the dissertation's non-SVP mirror),
view ``perspective:1280x720,fov=70`` at a pose stepped like a move (pan +3 degrees
per rebuild, tilt 20 degrees from the horizon towards the camera's side).

Figures per kind (``fisheye_*``, ``pano_table_*``, ``nonsvp_*``), medians over
repetitions of the same run:
- ``rebuild_ms``: what the steer thread does for one pose (:meth:`LiveView.rebuild
  <omnidev.daemon.streams.LiveView.rebuild>`: ``build_maps`` and the fixed-point
  conversion of :class:`~omnidev.camera.Remapper`); ``rebuild_p95_ms``.
- ``moving_rebuild_ms`` (``_p95_ms``), ``ratio_moving_rebuild_vs_frame_30fps``: the
  same for a pose passed through during a move (:func:`omnidev.ptz.coarse_maps`,
  rays at every ``moving_map_step_timed``-th pixel: the view's choice, at least 4),
  and how far those maps are from the exact ones:
  ``moving_map_err_px_p99``/``_max`` (source pixels, over pixels valid in both) and
  ``moving_valid_lost_share`` (valid pixels next to the camera's edge left black);
  ``moving_map_step_chosen``: what a running view uses while moving (1: exact maps;
  4 or 8: coarse ones, when it measured them faster at its start).
- ``remap_ms``: the frame thread's remap of one 1920x1920 BGR frame with those maps
  (the anchor measured in the same run: the work a rebuild competes with).
- ``ratio_rebuild_vs_remap``; ``ratio_rebuild_vs_frame_30fps``: rebuild over 33.3 ms
  (< 1: a rebuild fits in a frame time of a 30 fps camera, so every frame of a move
  can show a new pose); ``frames_per_rebuild_30fps``: ceil of that ratio.
All on one thread (``cv2.setNumThreads(1)``) as the steer thread runs beside the
remap thread on a 2-core machine.
"""

from __future__ import annotations

import importlib.util
import math
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

import omnidev
from omnidev.camera import Remapper, build_maps
from omnidev.daemon.streams import LiveView, ViewConfig, perspective_at
from omnidev.ptz import Pose, coarse_maps
from omnidev.viewspec import parse_view

VIEW = "perspective:1280x720,fov=70"
FRAME_30FPS_MS = 1000 / 30


def _video_bench() -> Any:
    path = Path(__file__).with_name("video.py")
    spec = importlib.util.spec_from_file_location("omnidev_bench_video_helpers", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _kind(camera: Any, tilt: float, reps: int) -> dict[str, float]:
    view = parse_view(VIEW)
    live = LiveView(ViewConfig("bench", VIEW, view, ("raw:-",), 90.0), camera, "linear")
    frame = np.random.default_rng(0).integers(0, 256, (*camera.image_size[::-1], 3), np.uint8)
    chosen = live.moving_step
    rebuild, moving, remap = [], [], []
    for i in range(reps):
        t0 = time.perf_counter()
        live.moving_step = max(chosen, 4)  # time coarse maps even where exact ones won
        live.rebuild(Pose(3.0 * i + 1.5, tilt, 70.0), exact=False)
        moving.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        live.rebuild(Pose(3.0 * i, tilt, 70.0))
        rebuild.append(time.perf_counter() - t0)
        r: Remapper = live.remapper
        t0 = time.perf_counter()
        r(frame)
        remap.append(time.perf_counter() - t0)
    assert live.built == Pose(3.0 * (reps - 1), tilt, 70.0)
    assert perspective_at(view, live.built).pan_deg == live.built.pan
    rb = float(np.median(rebuild)) * 1000
    mv = float(np.median(moving)) * 1000
    rm = float(np.median(remap)) * 1000
    pose_view = perspective_at(view, Pose(10.0, tilt, 70.0))
    exact = build_maps(camera, pose_view)
    coarse = coarse_maps(camera, pose_view, live.moving_step)
    both = exact.valid & coarse.valid
    err = np.hypot(exact.map_x - coarse.map_x, exact.map_y - coarse.map_y)[both]
    return {
        "moving_map_step_chosen": chosen,
        "moving_map_step_timed": live.moving_step,
        "moving_rebuild_ms": round(mv, 3),
        "moving_rebuild_p95_ms": round(float(np.percentile(moving, 95)) * 1000, 3),
        "ratio_moving_rebuild_vs_frame_30fps": round(mv / FRAME_30FPS_MS, 3),
        "moving_map_err_px_p99": round(float(np.percentile(err, 99)), 4),
        "moving_map_err_px_max": round(float(err.max()), 4),
        "moving_valid_lost_share": round(
            float((exact.valid & ~coarse.valid).sum() / max(1, exact.valid.sum())), 5
        ),
        "rebuild_ms": round(rb, 3),
        "rebuild_p95_ms": round(float(np.percentile(rebuild, 95)) * 1000, 3),
        "remap_ms": round(rm, 3),
        "ratio_rebuild_vs_remap": round(rb / rm, 3),
        "ratio_rebuild_vs_frame_30fps": round(rb / FRAME_30FPS_MS, 3),
        "frames_per_rebuild_30fps": math.ceil(rb / FRAME_30FPS_MS),
    }


def run(quick: bool = False) -> dict[str, Any]:
    reps = 5 if quick else 30
    cv2.setNumThreads(1)
    video = _video_bench()
    result: dict[str, Any] = {
        "view": VIEW,
        "source": f"{video.SIZE}x{video.SIZE}",
        "reps": reps,
        "load_avg_1min_start": round(os.getloadavg()[0], 2),
    }
    with tempfile.TemporaryDirectory(prefix="omnidev-bench-ptz-") as tmp:
        work = Path(tmp)
        # tilt: looking up for the fisheye (mounted up), down for the mirrors' band
        kinds = (
            ("fisheye", video._fisheye(work), 45.0),
            ("pano_table", video._pano_table(work), -20.0),
            ("nonsvp", video._nonsvp(work), -20.0),
        )
        for name, path, tilt in kinds:
            camera = omnidev.load_camera(path)
            for key, value in _kind(camera, tilt, reps).items():
                result[f"{name}_{key}"] = value
    result["load_avg_1min_end"] = round(os.getloadavg()[0], 2)
    return result
