"""``omnidev nonsvp-ring`` and ``omnidev calibrate nonsvp-hyper`` then ``omnidev unwarp``:
the ring pattern rendered as the camera sees it at the dissertation's pose, calibrated
back from the picture, the written file unwarping the fixture like the true camera."""

from __future__ import annotations

import math

import cv2
import numpy as np

from omnidev.cli.main import main
from omnidev.nonsvp.camfile import read_camera_file
from omnidev.nonsvp.model import DISSERTATION_CAMERA
from omnidev.nonsvp.ring_pattern import RingLayout, render_ring_view


def test_ring_sheet(tmp_path, capsys):
    assert main(["nonsvp-ring", str(tmp_path / "ring"), "--mirror-radius-mm", "29"]) == 0
    assert (tmp_path / "ring" / "ring.png").exists() and (tmp_path / "ring" / "ring.pdf").exists()


def test_calibrate_from_the_ring_picture_then_unwarp(tmp_path, capsys):
    cam = DISSERTATION_CAMERA
    img = render_ring_view(RingLayout(cam.mirror.m), cam.lens, cam.pose)
    ring = tmp_path / "ring_view.png"
    cv2.imwrite(str(ring), img)
    m = cam.mirror
    out = tmp_path / "cam.yml"
    argv = [
        "calibrate", "nonsvp-hyper", "--image", str(ring),
        "--mirror", f"{m.a!r},{m.b!r},{m.m!r}",
        "--lens", f"{cam.lens.f},{cam.lens.sensor[0]},{cam.lens.sensor[1]}",
        "--size", "640x480", "-o", str(out),
    ]  # fmt: skip
    assert main(argv) == 0
    got = read_camera_file(out).pose
    dt = math.dist(got.T, cam.pose.T)
    da = 1e3 * max(
        abs(got.pitch - cam.pose.pitch), abs(got.yaw - cam.pose.yaw), abs(got.tilt - cam.pose.tilt)
    )
    print(f"\ncalibrated from the rendered ring picture: T off {dt:.3f} mm, angles {da:.2f} mrad")
    assert dt < 0.1 and da < 1.0
    view = tmp_path / "top.png"
    argv = [
        "unwarp", "fixtures/nonsvp/dissertation-textured-640x480/omni.png", "--camera", str(out),
        "--view", "top:160x120,x=4000,y=4000,z=-2000", "-o", str(view),
    ]  # fmt: skip
    assert main(argv) == 0
    assert cv2.imread(str(view)).shape == (120, 160, 3)


def test_calibrate_errors(tmp_path, capsys):
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((480, 640), 128, np.uint8))
    argv = [
        "calibrate", "nonsvp-hyper", "--image", str(blank), "--mirror", "28.3646,32.0661,29",
        "--lens", "2.9,3.2,2.4", "--size", "640x480", "-o", str(tmp_path / "c.yml"),
    ]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "blank.png" in err and err.count("\n") == 0
    argv[argv.index("--mirror") + 1] = "20,30"
    assert main(argv) == 2
    assert "--mirror must be 3 comma-separated" in capsys.readouterr().err
