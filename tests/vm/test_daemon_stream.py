"""The daemon's ``[[stream]]`` on a real kernel: a camera in, a camera out.

vivid's video loop plays a rendered 640x480 fisheye clip as a camera (N frames,
each turned a further 360/N degrees, so every frame differs); a streams-only
daemon, in its own process as systemd runs it, unwarps it into a perspective view
on v4l2loopback's /dev/video10; v4l2-ctl, a separate program, reads the device
as a camera. Every frame it reads must be one of the clip's frames unwarped
offline (Python API, the same maps and interpolation) at >= 40 dB PSNR (vivid's
loop and the bgr24 loopback pass pixels unchanged: in the runs so far they were
identical); the share of captured frames written, the reader's rate and the
capture -> output latency (p50, p99) are reported (under TCG they follow the host's
load, so they are not bounds here).
Then the camera is unplugged (unbind + rmmod vivid) and comes back (modprobe):
the stream waits, retries, and resumes into the same output device without a
restart, and the reader gets the right frames again.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

import omnidev
from omnidev.daemon.control import request
from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
from omnidev.fisheye.camfile import write_camera_file
from omnidev.fisheye.models import IdealFisheye
from omnidev.sim.fisheye import EquidistantFisheyeCamera
from omnidev.sim.render import render_omni
from omnidev.sim.scene import RoomScene
from omnidev.viewspec import parse_view
from tests.vm.frames import torn_runs
from tests.vm.test_daemon import _replug_vivid, _unplug_vivid, _wait
from tests.vm.vivid import start_loop, stop, write_raw

NODE = "/dev/video10"
W_IN, H_IN = 640, 480  # vivid's loop runs at 640x480 (tests/vm/vivid.py)
N = 30  # frames in the clip (the loop)
K = 180  # frames the reader takes each time (about 3.5 s)
# Under TCG the emulated CPU remaps about 40x slower than the host: a 320x240 view
# with linear interpolation kept up with 21 of vivid's 53 fps, 320x240 nearest 40,
# 160x120 linear 54 of 56, 160x120 nearest 52.7 of 53.0 (measured in this VM).
# The test is of the kernel path and the daemon's stream, not of the emulated CPU:
# it takes the size the VM can keep up with, and a queue of 8 frames (the default 2
# dropped 1-5 % of the frames when the emulated CPU stalled for a few frame times
# while the host was busy).
W, H = 160, 120
VIEW = f"perspective:{W}x{H},fov=100,tilt=35,pan=20"
INTERPOLATION = "nearest"
SOCK = "/tmp/vm-stream.sock"
LOG = Path("/tmp/omnidevd-stream.log")


def _clip(tmp: Path) -> tuple[Path, Path, list[np.ndarray]]:
    """The raw clip for vivid, its camera file, and its frames unwarped offline."""
    max_angle = math.radians(95)
    f = 0.5 * H_IN / max_angle
    cx, cy = (W_IN - 1) / 2, (H_IN - 1) / 2
    sim = EquidistantFisheyeCamera(f, (W_IN, H_IN), (cx, cy), max_angle)
    base = render_omni(sim, RoomScene(seed=7), supersample=1)
    frames = []
    for i in range(N):
        turn = cv2.getRotationMatrix2D((cx, cy), 360.0 * i / N, 1.0)
        frames.append(cv2.warpAffine(base, turn, (W_IN, H_IN)))
    raw = write_raw(tmp / "clip.raw", frames)
    cam = tmp / "fisheye.yml"
    lens = IdealFisheye("equidistant", f, cx, cy)
    write_camera_file(cam, FisheyeCamera(lens, (W_IN, H_IN), MOUNTS["up"], max_angle_deg=95.0))
    maps = omnidev.build_maps(omnidev.load_camera(cam), parse_view(VIEW))
    return raw, cam, [omnidev.unwarp(fr, maps, interpolation=INTERPOLATION) for fr in frames]


def _config(tmp: Path, capture: str, cam: Path) -> Path:
    path = tmp / "omnidev.toml"
    path.write_text(
        f"""[[stream]]
name = "cam"
source = "v4l2:{capture}?width={W_IN}&height={H_IN}&buffers=2"
camera = "{cam}"
interpolation = "{INTERPOLATION}"
queue = 8

[[stream.view]]
name = "flat"
view = "{VIEW}"
output = "v4l2:{NODE}?format=bgr24"

[daemon]
socket = "{SOCK}"
retry_initial_s = 0.5
retry_max_s = 2.0
"""
    )
    return path


def _stream() -> dict[str, Any]:
    st: dict[str, Any] = request(Path(SOCK), "status", timeout=10.0)["streams"][0]
    return st


def _read(tmp: Path, name: str, offline: list[np.ndarray]) -> dict[str, Any]:
    """K frames read from the loopback by v4l2-ctl, each matched to the clip; the
    daemon's capture and output rates over the same time (from its status) and the
    reader's own (its frames arriving in its file)."""
    raw = tmp / f"{name}.raw"
    size = W * H * 3
    before, t0 = _stream(), time.monotonic()
    reader = subprocess.Popen(
        ["v4l2-ctl", "-d", NODE, "--stream-mmap=4", f"--stream-count={K}", f"--stream-to={raw}"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
    )  # fmt: skip
    # the reader's own rate: from its first frame in the file to its last
    first = None
    while reader.poll() is None and time.monotonic() - t0 < 600:
        n = raw.stat().st_size // size if raw.exists() else 0
        if n >= 1 and first is None:
            first = (time.monotonic(), n)
        time.sleep(0.005)
    last = (time.monotonic(), raw.stat().st_size // size if raw.exists() else 0)
    out = reader.communicate(timeout=60)[0].decode(errors="replace")
    after, wall = _stream(), time.monotonic() - t0
    assert reader.returncode == 0, out
    assert first is not None, "the reader wrote no frame"
    reader_fps = (last[1] - first[1]) / (last[0] - first[0])
    data = raw.read_bytes()
    assert len(data) == K * W * H * 3, f"{len(data)} bytes"
    frames = np.frombuffer(data, np.uint8).reshape(K, H, W, 3)
    best = [max(cv2.PSNR(fr, o) for o in offline) for fr in frames]
    torn = [torn_runs(fr, offline) for fr, b in zip(frames, best, strict=True) if b < 40.0]
    keep = os.environ.get("OMNIDEV_VM_OUT")
    for i in np.flatnonzero(np.array(best) < 40.0) if keep else []:
        j = int(np.argmax([cv2.PSNR(frames[i], o) for o in offline]))
        pair = np.concatenate([frames[i], offline[j]], axis=1)
        cv2.imwrite(str(Path(keep).parent / f"stream-{name}-{i}-vs-clip-{j}.png"), pair)
    captured = after["frames"] - before["frames"]
    written = after["written"] - before["written"]
    return {
        "frames_read": K,
        "reader_fps": round(reader_fps, 2),
        "reader_s": round(wall, 2),
        "capture_fps": round(captured / wall, 2),
        "output_fps": round(written / wall, 2),
        "written_of_captured": round(written / max(captured, 1), 4),
        "dropped_frames": after["dropped_frames"],
        "latency_p50_ms": after["latency_p50_ms"],
        "latency_p99_ms": after["latency_p99_ms"],
        "psnr_db_min": round(min(min(best), 99.0), 2),
        "psnr_db_median": round(min(float(np.median(best)), 99.0), 2),
        "frames_below_40db": len(torn),
        "torn_frames": [t for t in torn if t is not None],
    }


def _check(fig: dict[str, Any]) -> None:
    # Every frame read is the right frame at >= 40 dB (in practice identical), or a
    # torn read of the loopback's shared buffers (:func:`tests.vm.frames.torn_runs`):
    # 0-3 % of the frames in runs here, more the busier the host. (A raw file output
    # beside the loopback, to check every frame written, cost the emulated CPU 10 % of
    # the frames.)
    assert len(fig["torn_frames"]) == fig["frames_below_40db"], fig
    assert fig["frames_below_40db"] <= 0.1 * fig["frames_read"], fig
    # The rates are reported, not asserted: under TCG on a shared host they follow the
    # host's load (written of captured 100 % in one CI run, 86 % in the next; vivid's
    # own 59.9 fps is out of reach of the emulated capture either way: docs/outputs.md).
    assert fig["written_of_captured"] > 0 and fig["reader_fps"] > 0, fig
    assert fig["latency_p50_ms"] is not None and fig["latency_p99_ms"] is not None, fig


def test_daemon_stream_from_vivid_to_loopback_survives_an_unplug(tmp_path, vm_figures):
    raw, cam, offline = _clip(tmp_path)
    capture, feeder = start_loop(raw)
    config = _config(tmp_path, capture, cam)
    with LOG.open("w") as log_file:
        daemon = subprocess.Popen(
            [sys.executable, "-m", "omnidev.daemon.main", "--config", str(config)],
            stderr=log_file,
        )
    try:
        # 180 s: the daemon's start (Python imports under TCG) can take over a minute
        _wait(lambda: _stream()["written"] >= 30, 180, "the stream's first frames")
        first = _read(tmp_path, "before", offline)
        vm_figures["vm_stream"] = first
        _check(first)

        stop(feeder)
        _unplug_vivid()
        _wait(lambda: _stream()["state"] == "waiting for camera", 60, "the stream to notice")
        retries = _stream()["camera_retries"]
        _wait(lambda: _stream()["camera_retries"] >= retries + 2, 30, "retries")
        assert daemon.poll() is None
        written = _stream()["written"]
        feeder = _replug_vivid(daemon, raw, capture)
        _wait(lambda: _stream()["written"] >= written + 30, 120, "the stream to resume")
        assert _stream()["state"] == "running"
        again = _read(tmp_path, "after", offline)
        vm_figures["vm_stream_after_replug"] = again
        _check(again)
        daemon.send_signal(signal.SIGTERM)
        assert daemon.wait(60) == 0
    finally:
        stop(feeder)
        if daemon.poll() is None:
            daemon.kill()
            daemon.wait()
    log = LOG.read_text()
    assert "retrying" in log, log[-2000:]
