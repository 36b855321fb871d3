"""omnidev's ``v4l2:`` output on a real kernel: ``omnidev unwarp`` writes to v4l2loopback's
/dev/video10 and separate programs (v4l2-ctl, ffmpeg) read it as a camera.

run-in-vm.sh loads ``v4l2loopback video_nr=10 card_label="omnidev loopback"
exclusive_caps=1 max_buffers=8`` (Debian's v4l2loopback-dkms, built for the VM's
kernel by scripts/install-system-deps.sh), the setting docs/outputs.md gives
users. A rendered fisheye clip of N frames (each turned a further 360/N degrees,
so every frame differs) plays in a loop at RATE frames per second through
``omnidev unwarp "video:clip.avi?loop=1&rate=RATE" ... -o v4l2:/dev/video10?format=F``;
the reader (v4l2-ctl for ``bgr24``, ffmpeg for ``yuyv``), started once the
device shows its format, takes K frames. Each is matched to the clip's frames
unwarped offline (the same decoder and maps through the Python API): they must be
K consecutive frames of the loop, none missing or repeated (but for frames among
the first four, a reader joining the stream, that repeat the last or are torn:
made of two frames' bytes), each at >= 40 dB PSNR (byte for byte in the device's
format, in practice). The tests run one after another on the same device,
so the second also shows that a new writer takes the device over from the last
one (with exclusive_caps=1).
"""

from __future__ import annotations

import itertools
import math
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

import omnidev
from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
from omnidev.fisheye.camfile import write_camera_file
from omnidev.fisheye.models import IdealFisheye
from omnidev.outputs.pixels import bgr_to_yuyv, yuyv_to_bgr
from omnidev.sim.fisheye import EquidistantFisheyeCamera
from omnidev.sim.render import render_omni
from omnidev.sim.scene import RoomScene
from omnidev.viewspec import parse_view
from tests.vm.frames import torn_runs

NODE = "/dev/video10"
CARD = "omnidev loopback"
SIZE = 320  # fisheye frames, px
N = 36  # frames in the clip (the loop)
K = 24  # frames each reader takes
RATE = 6.0  # frames per second the source is paced at
JOIN = 4  # the first frames a reader takes, where repeated or torn frames are the join
W, H = 320, 240
VIEW = f"perspective:{W}x{H},fov=100,tilt=35,pan=20"
OMNIDEV = Path(sys.executable).parent / "omnidev"

Clip = tuple[Path, Path, list[np.ndarray]]


@pytest.fixture(scope="module")
def clip(tmp_path_factory: pytest.TempPathFactory) -> Clip:
    """A fisheye clip (MJPG .avi), its camera file and its frames unwarped offline (BGR)."""
    tmp = tmp_path_factory.mktemp("clip")
    f = 0.5 * SIZE / math.radians(95)
    c = (SIZE - 1) / 2
    sim = EquidistantFisheyeCamera(f, (SIZE, SIZE), (c, c), math.radians(95))
    base = render_omni(sim, RoomScene(seed=5), supersample=1)
    cam = tmp / "fisheye.yml"
    lens = IdealFisheye("equidistant", f, c, c)
    write_camera_file(cam, FisheyeCamera(lens, (SIZE, SIZE), MOUNTS["up"], max_angle_deg=95.0))
    path = tmp / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), RATE, (SIZE, SIZE))
    for i in range(N):
        turn = cv2.getRotationMatrix2D((c, c), 360.0 * i / N, 1.0)
        writer.write(cv2.warpAffine(base, turn, (SIZE, SIZE)))
    writer.release()
    maps = omnidev.build_maps(omnidev.load_camera(cam), parse_view(VIEW))
    cap = cv2.VideoCapture(str(path))  # the decoder that video: sources use
    offline = []
    while True:
        ok, image = cap.read()
        if not ok:
            break
        offline.append(omnidev.unwarp(image, maps))
    assert len(offline) == N
    return path, cam, offline


def _loopback() -> None:
    name = Path("/sys/class/video4linux") / Path(NODE).name / "name"
    if not name.exists():
        pytest.fail(f"{NODE} is missing: run-in-vm.sh did not load v4l2loopback (stages.log)")
    assert name.read_text().strip() == CARD


def _wait_for_format(writer: subprocess.Popen[bytes], log: Path, timeout_s: float = 900) -> None:
    """Until the writer has set the device's format and sent a frame (capture side shows it)."""
    deadline = time.monotonic() + timeout_s
    out = None
    while time.monotonic() < deadline:
        if writer.poll() is not None:
            raise AssertionError(f"omnidev unwarp exited {writer.returncode}: {log.read_text()}")
        out = subprocess.run(["v4l2-ctl", "-d", NODE, "--get-fmt-video"], capture_output=True)
        if f"{W}/{H}".encode() in out.stdout:
            return
        time.sleep(0.05)
    raise AssertionError(f"the writer never set {NODE}'s format: {out}; {log.read_text()}")


def _stream(clip: Clip, fmt: str, reader: list[str], tmp: Path) -> tuple[float, str]:
    """Run the writer, then the reader; returns the reader's wall time and its output."""
    path, cam, _ = clip
    cmd = [
        str(OMNIDEV), "unwarp", f"video:{path}?loop=1&rate={RATE:g}", "--camera", str(cam),
        "--view", VIEW, "-o", f"v4l2:{NODE}?format={fmt}",
    ]  # fmt: skip
    log = tmp / f"unwarp-{fmt}.log"
    with log.open("wb") as fh:
        writer = subprocess.Popen(cmd, stdout=fh, stderr=subprocess.STDOUT)
    try:
        _wait_for_format(writer, log)
        t0 = time.monotonic()
        read = subprocess.run(reader, capture_output=True, text=True, timeout=600)
        wall = time.monotonic() - t0
        assert read.returncode == 0, f"{reader[0]} failed: {read.stderr}{read.stdout}"
        writer.send_signal(signal.SIGINT)  # a user's Ctrl-C: the device is released
        assert writer.wait(timeout=60) == 130, log.read_text()
    finally:
        if writer.poll() is None:
            writer.kill()
            writer.wait()
    return wall, read.stdout + read.stderr


def _check(
    read: list[np.ndarray],
    written: list[np.ndarray],
    decode: Callable[[np.ndarray], np.ndarray],
    offline: list[np.ndarray],
    key: str,
    figures: Any,
) -> None:
    """``read``: the reader's frames and ``written``: the clip's frames unwarped offline,
    both in the device's pixel format (what the writer puts in the buffers, byte for byte);
    ``decode`` turns that format into BGR to compare with ``offline`` where bytes differ."""
    assert len(read) == K, f"{len(read)} of {K} frames came back"
    indices: list[int] = []
    exact, psnrs, join = 0, [], []
    for i, f in enumerate(read):
        same = [j for j, w in enumerate(written) if np.array_equal(f, w)]
        if same:
            exact += 1
            index, psnr = same[0], 99.0
        else:
            scores = [cv2.PSNR(decode(f), o) for o in offline]
            index, psnr = int(np.argmax(scores)), float(max(scores))
        # A reader that joins a running stream may be handed its first frames more than
        # once (v4l2loopback 0.12 in the VM, ffmpeg: 8, 8, 8, 9, ... in one run, 7, 8, 8,
        # 9, ... in one CI run) or a buffer the writer was filling (one CI run of ffmpeg: a
        # first frame at 26 dB, made of two clip frames' bytes). Such frames among the
        # first JOIN are the join; after them, every frame once, in order, at >= 40 dB
        # (the same frame's bytes in practice).
        if i < JOIN:
            if indices and index == indices[-1] and same:
                join.append("repeat")
                continue
            runs = torn_runs(f, written) if psnr < 40.0 else None
            if runs is not None:
                join.append(f"torn {runs}")
                continue
        indices.append(index)
        psnrs.append(psnr)
    steps = [(b - a) % N for a, b in itertools.pairwise(indices)]
    figures[key] = {
        "frames_read": len(read),
        "exact_frames": exact,
        "join": join,
        "first_index": indices[0],
        "steps_not_1": sum(s != 1 for s in steps),
        "psnr_db_min": round(min(min(psnrs), 99.0), 2),
        "psnr_db_median": round(min(float(np.median(psnrs)), 99.0), 2),
    }
    assert all(s == 1 for s in steps), f"lost or repeated: {join} {indices}"
    assert min(psnrs) >= 40.0, psnrs


def test_bgr24_read_by_v4l2_ctl_byte_for_byte(clip: Clip, tmp_path: Path, vm_figures) -> None:
    _loopback()
    raw = tmp_path / "read.raw"
    reader = ["v4l2-ctl", "-d", NODE, "--stream-mmap=4", f"--stream-count={K}",
              f"--stream-to={raw}"]  # fmt: skip
    wall, log = _stream(clip, "bgr24", reader, tmp_path)
    data = raw.read_bytes()
    assert len(data) == K * W * H * 3, f"{len(data)} bytes"
    frames = list(np.frombuffer(data, np.uint8).reshape(K, H, W, 3))
    _check(frames, clip[2], lambda f: f, clip[2], "v4l2_output_bgr24_v4l2ctl", vm_figures)
    rates = [float(x) for x in re.findall(r"([0-9.]+) fps", log)]
    vm_figures["v4l2_output_bgr24_v4l2ctl"].update(
        {"reader_fps_reports": rates, "reader_s": round(wall, 2), "source_fps": RATE}
    )
    fig = vm_figures["v4l2_output_bgr24_v4l2ctl"]
    torn = sum(j.startswith("torn") for j in fig["join"])
    assert fig["exact_frames"] == K - torn, fig  # byte for byte, but a torn join


def test_yuyv_read_by_ffmpeg(clip: Clip, tmp_path: Path, vm_figures) -> None:
    _loopback()
    raw = tmp_path / "read.yuyv"
    # -fps_mode passthrough: each frame once (the rawvideo muxer's default, constant frame
    # rate, duplicates frames to fill the gaps of a writer slower than the device's rate)
    reader = [
        "ffmpeg", "-hide_banner", "-loglevel", "error", "-f", "v4l2", "-input_format",
        "yuyv422", "-i", NODE, "-frames:v", str(K), "-fps_mode", "passthrough", "-c:v",
        "rawvideo", "-f", "rawvideo", "-y", str(raw),
    ]  # fmt: skip
    _stream(clip, "yuyv", reader, tmp_path)
    data = raw.read_bytes()
    assert len(data) == K * W * H * 2, f"{len(data)} bytes"
    packed = np.frombuffer(data, np.uint8).reshape(K, H, W * 2)
    written = [bgr_to_yuyv(o) for o in clip[2]]
    _check(list(packed), written, yuyv_to_bgr, clip[2], "v4l2_output_yuyv_ffmpeg", vm_figures)


def test_udev_rule_gives_the_loopback_device_a_name_and_group_video() -> None:
    """udev/62-omnidev-v4l2loopback.rules (copied to /run/udev/rules.d by run-in-vm.sh)."""
    import grp
    import os
    import stat

    _loopback()
    link = Path("/dev/omnidev-video10")
    assert link.is_symlink() and os.path.realpath(link) == NODE, sorted(os.listdir("/dev"))
    st = os.stat(NODE)
    assert grp.getgrgid(st.st_gid).gr_name == "video"
    assert stat.S_IMODE(st.st_mode) == 0o660
