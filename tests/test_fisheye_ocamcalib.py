"""OCamCalib's (Scaramuzza) calibration and the omni board detector against rendered truth.

The truth lens is omnidev.sim.chessboard's catadioptric Scaramuzza lens (rays 67 to 140
degrees off the axis over the image: a mirror camera seeing the room around it); boards are
posed around it from 75 to 135 degrees (default_pose_options("scaramuzza")).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from omnidev.errors import CalibrationError
from omnidev.fisheye import ocamcalib as ocam
from omnidev.fisheye.board_detect import detect_chessboard
from omnidev.fisheye.calibrate import Detection, calibrate_views, detect_corners
from omnidev.fisheye.models import Scaramuzza
from omnidev.fisheye.pattern import parse_pattern
from omnidev.sim.chessboard import default_lens, default_pose_options, render_sequence

SIZE = (640, 640)
PATTERN = parse_pattern("chessboard:7x11,30")


def truth_lens() -> Scaramuzza:
    lens = default_lens("scaramuzza", SIZE)
    assert isinstance(lens, Scaramuzza)
    return lens


def projection_error(est: Scaramuzza, truth: Scaramuzza, lo_deg: float, hi_deg: float) -> float:
    """Largest pixel distance between the two lenses' images of rays lo..hi deg off the axis."""
    t = np.radians(np.linspace(lo_deg, hi_deg, 60))
    az = np.radians(np.arange(0, 360, 5))
    tt, aa = np.meshgrid(t, az)
    rays = np.stack([np.sin(tt) * np.cos(aa), np.sin(tt) * np.sin(aa), np.cos(tt)], -1)
    a, ok_a = est.project(rays)
    b, ok_b = truth.project(rays)
    assert ok_a.all() and ok_b.all()
    return float(np.hypot(*(a - b).reshape(-1, 2).T).max())


def detections(seq, corners) -> list[Detection]:
    return [Detection(f"view{i}", c, PATTERN.object_points()) for i, c in enumerate(corners)]


def test_exact_corners_give_back_the_lens() -> None:
    truth = truth_lens()
    seq = render_sequence(
        truth, SIZE, PATTERN, 10, seed=3, images=False, **default_pose_options("scaramuzza")
    )
    res = calibrate_views(detections(seq, [v.corners_uv for v in seq.views]), SIZE, "scaramuzza")
    est = res.camera.lens
    assert isinstance(est, Scaramuzza) and est.invpol is not None
    err = projection_error(ocam.lens_from_vector(ocam.vector_of(est)), truth, 70, 135)
    print(f"exact corners: train {res.train_rms_px:.2e} px, held-out {res.heldout_rms_px:.2e} px, "
          f"projection vs truth (70-135 deg) max {err:.2e} px")  # fmt: skip
    assert res.train_rms_px < 1e-4 and res.heldout_rms_px < 1e-3 and err < 1e-2
    # the written lens's world2cam polynomial follows the model over the image
    inv_err = projection_error(est, ocam.lens_from_vector(ocam.vector_of(est)), 60, 140)
    assert inv_err < 0.01


def test_noisy_corners_reach_the_noise_floor() -> None:
    truth = truth_lens()
    seq = render_sequence(
        truth, SIZE, PATTERN, 14, seed=11, images=False, **default_pose_options("scaramuzza")
    )
    res = calibrate_views(detections(seq, seq.noisy_corners(0.2, seed=4)), SIZE, "scaramuzza")
    est = ocam.lens_from_vector(ocam.vector_of(res.camera.lens))
    err = projection_error(est, truth, 80, 130)
    floor = 0.2 * math.sqrt(2)
    print(f"0.2 px noise: train {res.train_rms_px:.3f} px, held-out {res.heldout_rms_px:.3f} px "
          f"(2-D noise {floor:.3f}), projection vs truth (80-130 deg) max {err:.3f} px, "
          f"centre error {est.yc - truth.yc:+.2f}, {est.xc - truth.xc:+.2f} px")  # fmt: skip
    assert floor * 0.9 < res.train_rms_px < floor and res.heldout_rms_px < floor * 1.08
    assert err < 0.25
    assert abs(est.yc - truth.yc) < 1.0 and abs(est.xc - truth.xc) < 1.0


def test_rendered_mirror_images_detected_and_calibrated() -> None:
    """From pixels: 6 rendered mirror views (corners 6 px apart and more) through the whole
    detector cascade, matched to the truth by position (the detector may label the board
    turned or mirrored), then calibrated."""
    truth = truth_lens()
    seq = render_sequence(
        truth, SIZE, PATTERN, 6, seed=7, supersample=2, **default_pose_options("scaramuzza")
    )
    dets = [detect_corners(img, PATTERN, name=f"view{i}") for i, img in enumerate(seq.images)]
    errs = []
    for d, v in zip(dets, seq.views, strict=True):
        if d is None:
            continue
        dist = np.hypot(*(v.corners_uv[:, None] - d.image_points[None]).transpose(2, 0, 1))
        assert len(set(dist.argmin(axis=1))) == len(v.corners_uv)  # one detected corner each
        errs.append(dist.min(axis=1))
    e = np.concatenate(errs)
    rms = float(np.sqrt(np.mean(e**2)))
    methods = sorted({d.method for d in dets if d is not None})
    print(f"rendered mirror views: {len(errs)} of {len(dets)} boards ({', '.join(methods)}), "
          f"corners vs truth RMS {rms:.3f} px, max {e.max():.3f} px")  # fmt: skip
    assert len(errs) >= 4 and rms < 0.25 and e.max() < 1.0
    res = calibrate_views(dets, SIZE, "scaramuzza", holdout=0)
    est = ocam.lens_from_vector(ocam.vector_of(res.camera.lens))
    err = projection_error(est, truth, 80, 130)
    print(f"calibrated on {len(errs)} views: train {res.train_rms_px:.3f} px, projection vs "
          f"truth (80-130 deg) max {err:.3f} px")  # fmt: skip
    assert res.train_rms_px < 0.25 and err < 1.0


def test_refusals() -> None:
    truth = truth_lens()
    seq = render_sequence(
        truth, SIZE, PATTERN, 4, seed=1, images=False, **default_pose_options("scaramuzza")
    )
    dets = detections(seq, [v.corners_uv for v in seq.views])
    with pytest.raises(CalibrationError, match="found in only 2"):
        calibrate_views([dets[0], dets[1], None], SIZE, "scaramuzza")
    blank = np.full((200, 200), 128, np.uint8)
    assert detect_chessboard(blank, (7, 11)) is None
    with pytest.raises(ValueError, match="unknown detector"):
        detect_chessboard(blank, (7, 11), methods=("magic",))
