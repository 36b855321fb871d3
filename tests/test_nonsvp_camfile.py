"""``nonsvp-hyper`` calibration files through the common camera API: ``omnidev unwarp``
with such a file gives the dense-map view, checked against the renderer's truth."""

from __future__ import annotations

from pathlib import Path

import cv2
import pytest

from omnidev.calibfile import load_camera
from omnidev.cli.main import main
from omnidev.errors import CalibrationError
from omnidev.metrics import psnr
from omnidev.nonsvp.camfile import read_camera_file, write_camera_file
from omnidev.sim import nonsvp as sim_nonsvp

FX = Path(__file__).resolve().parents[1] / "fixtures" / "nonsvp" / "dissertation-textured-640x480"


def test_round_trip_and_load_camera(tmp_path):
    cam = sim_nonsvp.preset_camera("dissertation", (640, 480))
    path = tmp_path / "cam.yml.gz"
    write_camera_file(path, cam)
    back = read_camera_file(path)
    assert back.to_dict() == cam.to_dict()
    model = load_camera(path)
    assert model.kind == "nonsvp-hyper" and model.image_size == (640, 480)


def test_omnidev_unwarp_with_a_nonsvp_file(tmp_path, capsys):
    cam = sim_nonsvp.preset_camera("dissertation", (640, 480))
    path = tmp_path / "cam.yml"
    write_camera_file(path, cam)
    out = tmp_path / "top.png"
    argv = [
        "unwarp", str(FX / "omni.png"), "--camera", str(path),
        "--view", "top:320x240,x=4000,y=4000,z=-2000", "-o", str(out),
    ]  # fmt: skip
    assert main(argv) == 0
    got = cv2.imread(str(out), cv2.IMREAD_COLOR)
    truth = cv2.imread(str(FX / "top.png"), cv2.IMREAD_COLOR)
    mask = cv2.imread(str(FX / "top_mask.png"), cv2.IMREAD_GRAYSCALE) > 0
    view = sim_nonsvp.dissertation_planes()["top"]
    cx, cy, ok = sim_nonsvp.view_plane_map(cam, view)
    omni = cv2.imread(str(FX / "omni.png"), cv2.IMREAD_COLOR)
    ceiling = cv2.remap(omni, cx, cy, cv2.INTER_LINEAR)
    m = mask & ok
    p, c = psnr(got, truth, m), psnr(ceiling, truth, m)
    print(f"\nomnidev unwarp, nonsvp-hyper file, top view: {p:.2f} dB (ceiling {c:.2f} dB)")
    assert p >= c - 0.1


def test_bad_files_name_the_file(tmp_path):
    cam = sim_nonsvp.preset_camera("dissertation", (640, 480))
    good = tmp_path / "good.yml"
    write_camera_file(good, cam)
    text = good.read_text()
    inside = tmp_path / "inside.yml"  # the lens moved into the mirror
    inside.write_text(
        "\n".join(
            "pose_tz: 10." if line.startswith("pose_tz:") else line for line in text.splitlines()
        )
    )
    with pytest.raises(CalibrationError, match="inside.yml: pose puts the lens centre inside"):
        read_camera_file(inside)
    short = tmp_path / "short.yml"
    short.write_text("%YAML:1.0\nkind: nonsvp-hyper\nformat_version: 1\nmirror_a: 20\n")
    with pytest.raises(CalibrationError, match="short.yml.*mirror_b"):
        read_camera_file(short)
    argv = [
        "unwarp", str(FX / "omni.png"), "--camera", str(inside),
        "--view", "top:32x24,x=4000,y=4000,z=-2000", "-o", str(tmp_path / "x.png"),
    ]  # fmt: skip
    assert main(argv) == 2
