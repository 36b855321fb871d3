"""``omnidev unwarp`` on video files: the threaded pipeline, PyAV decoding, 4:2:0 planes.

A rendered fisheye clip (each frame turned a further 360/N degrees about the
image centre, so that every frame differs) is unwarped by the command line and
compared frame by frame with the same frames unwarped through the Python API
(cv2 decoding, BGR maps): order and count must be exact, and the 4:2:0 path must
agree with the BGR path to the precision of 4:2:0 itself.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

import omnidev
from omnidev.cli.main import main
from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
from omnidev.fisheye.camfile import write_camera_file
from omnidev.fisheye.models import IdealFisheye
from omnidev.outputs.pixels import i420_planes, to_layout
from omnidev.sim.fisheye import EquidistantFisheyeCamera
from omnidev.sim.render import render_omni
from omnidev.sim.scene import RoomScene
from omnidev.viewspec import parse_view
from tests.conftest import psnr

SIZE = 256


def fisheye_clip(tmp: Path, frames: int = 24, seed: int = 11) -> tuple[Path, Path]:
    """An MJPG clip of a 190-degree equidistant fisheye looking up, and its camera file."""
    f = 0.5 * SIZE / math.radians(95)
    c = (SIZE - 1) / 2
    sim = EquidistantFisheyeCamera(f, (SIZE, SIZE), (c, c), math.radians(95))
    base = render_omni(sim, RoomScene(seed=seed), supersample=1)
    cam = tmp / "fisheye.yml"
    lens = IdealFisheye("equidistant", f, c, c)
    write_camera_file(cam, FisheyeCamera(lens, (SIZE, SIZE), MOUNTS["up"], max_angle_deg=95.0))
    clip = tmp / "clip.avi"
    writer = cv2.VideoWriter(str(clip), cv2.VideoWriter.fourcc(*"MJPG"), 25, (SIZE, SIZE))
    for i in range(frames):
        turn = cv2.getRotationMatrix2D((c, c), 360.0 * i / frames, 1.0)
        writer.write(cv2.warpAffine(base, turn, (SIZE, SIZE)))
    writer.release()
    return clip, cam


def offline(clip: Path, cam: Path, view: str, interpolation: str = "linear") -> list[np.ndarray]:
    maps = omnidev.build_maps(omnidev.load_camera(cam), parse_view(view))
    cap = cv2.VideoCapture(str(clip))
    out = []
    while True:
        ok, image = cap.read()
        if not ok:
            return out
        out.append(omnidev.unwarp(image, maps, interpolation=interpolation))  # type: ignore[arg-type]


def read_video(path: Path) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, image = cap.read()
        if not ok:
            return frames
        frames.append(image)


def best_match(frames: list[np.ndarray], truth: list[np.ndarray]) -> list[int]:
    return [int(np.argmax([cv2.PSNR(f, t) for t in truth])) for f in frames]


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    return fisheye_clip(tmp_path_factory.mktemp("clip"))


@pytest.mark.parametrize("threads", [1, 2])
def test_frames_arrive_in_order_each_once(clip, tmp_path, capsys, threads):
    src, cam = clip
    view = "equirect:256x128"
    out = tmp_path / "eq.mp4"
    args = ["unwarp", str(src), "--camera", str(cam), "--view", view, "-o", str(out)]
    assert main([*args, "--threads", str(threads), "--stats"]) == 0
    stats = json.loads(capsys.readouterr().err.strip().splitlines()[-1])
    assert stats["layout"] == "yuvj420p" and stats["frames"] == 24  # MJPEG's own planes
    assert set(stats["stages"]) == {"read", "remap", f"write:{out}"}
    truth = offline(src, cam, view)
    got = read_video(out)
    assert best_match(got, truth) == list(range(24))
    assert min(psnr(g, t) for g, t in zip(got, truth, strict=True)) > 33


def test_planar_path_agrees_with_the_bgr_path(clip, tmp_path):
    """4:2:0 planes remapped with derived chroma maps = BGR remapped, to 4:2:0's precision."""
    src, cam = clip
    view = "perspective:192x144,fov=100,tilt=40,pan=30"
    raw = tmp_path / "v.bgr"
    assert main(["unwarp", str(src), "--camera", str(cam), "--view", view, "-o", f"raw:{raw}"]) == 0
    got = np.frombuffer(raw.read_bytes(), np.uint8).reshape(-1, 144, 192, 3)
    truth = offline(src, cam, view)
    assert len(got) == len(truth) == 24
    values = [psnr(g, t) for g, t in zip(got, truth, strict=True)]
    assert min(values) > 36, values
    # Chroma alone: a chroma map off by one source pixel costs several dB here.
    for g, t in zip(got[:4], truth[:4], strict=True):
        _, gu, gv = i420_planes(to_layout(g, "bgr", "yuv420p"))
        _, tu, tv = i420_planes(to_layout(t, "bgr", "yuv420p"))
        assert psnr(gu, tu) > 38 and psnr(gv, tv) > 38, (psnr(gu, tu), psnr(gv, tv))


def test_nearest_on_planes_picks_the_same_pixels(clip, tmp_path):
    src, cam = clip
    view = "equirect:128x64"
    y4m = tmp_path / "v.y4m"
    args = ["unwarp", str(src), "--camera", str(cam), "--view", view, "-o", f"y4m:{y4m}"]
    assert main([*args, "--interpolation", "nearest", "--frames", "3"]) == 0
    data = y4m.read_bytes()
    header, _, body = data.partition(b"\n")
    assert header.startswith(b"YUV4MPEG2 W128 H64 F25:1")
    frames = body.split(b"FRAME\n")[1:]
    assert len(frames) == 3
    truth = offline(src, cam, view, "nearest")[:3]
    for f, t in zip(frames, truth, strict=True):
        y = np.frombuffer(f, np.uint8)[: 128 * 64].reshape(64, 128)
        ty = to_layout(t, "bgr", "yuv420p")[:64]
        assert psnr(y, ty) > 40  # luma of the same source pixels (MJPEG vs cv2 decoding)


def test_frames_limit_and_two_views(clip, tmp_path):
    src, cam = clip
    a, b = tmp_path / "a.avi", tmp_path / "b.png"
    assert main([
        "unwarp", str(src), "--camera", str(cam), "--frames", "1",
        "--view", "equirect:128x64", "-o", str(a), "--view", "panorama:200x50", "-o", str(b),
    ]) == 0  # fmt: skip
    assert len(read_video(a)) == 1 and cv2.imread(str(b)).shape == (50, 200, 3)
    c = tmp_path / "c.mkv"
    assert main(["unwarp", str(src), "--camera", str(cam), "--frames", "7", "--view",
                 "equirect:128x64", "-o", str(c)]) == 0  # fmt: skip
    truth = offline(src, cam, "equirect:128x64")
    assert best_match(read_video(c), truth) == list(range(7))


def test_truncated_video_is_one_line_and_writes_nothing(clip, tmp_path, capsys):
    src, cam = clip
    cut = tmp_path / "cut.avi"
    data = src.read_bytes()
    cut.write_bytes(data[: len(data) * 2 // 3])
    out = tmp_path / "eq.mp4"
    assert main(["unwarp", str(cut), "--camera", str(cam), "--view", "equirect:128x64",
                 "-o", str(out)]) == 2  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()[-1]  # after the progress bar
    assert err.startswith("omnidev unwarp: error: video:") and "cut.avi: frame 16" in err, err
    assert not out.exists() and [p.name for p in tmp_path.iterdir()] == ["cut.avi"]


def test_two_outputs_to_stdout_are_refused(clip, capsys):
    src, cam = clip
    assert main(["unwarp", str(src), "--camera", str(cam), "--view", "equirect:64x32", "-o", "-",
                 "--view", "equirect:64x32", "-o", "raw:-"]) == 2  # fmt: skip
    assert "two views write the same output" in capsys.readouterr().err
