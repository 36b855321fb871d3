"""vivid's video loop: frames written to its output node come back on its capture node.

For the in-VM tests (vivid loaded with ``n_devs=1 node_types=0x101``). Both
sides are switched to HDMI (capture input 3, output 1) with DV timings index 0
(640x480p59.94), pixel format BGR3, and ``loop_video=1`` on the capture side;
then ``v4l2-ctl --stream-out-mmap --stream-from=RAW --stream-loop`` feeds the
raw frames of RAW (width x height x 3 bytes each, BGR, top row first) to the
output over and over. Seen in the VM: colour and position survive (a white
disc on black and pure red/green/blue boxes come back in place and colour);
vivid's on-screen status text is switched off (``osd_text_mode=2``).

    capture, proc = start_loop(raw_path)   # capture is e.g. "/dev/video0"
    ... open f"v4l2:{capture}?width=640&height=480" ...
    stop(proc)
"""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

SYS_V4L = Path("/sys/class/video4linux")
HDMI_INPUT = 3  # vivid capture inputs: 0 webcam, 1 TV, 2 S-Video, 3 HDMI
HDMI_OUTPUT = 1  # vivid outputs: 0 S-Video, 1 HDMI
DV_640X480 = 0  # DV timings index 0: 640x480p59.94 (CTA-861 VIC 1)
LOG = Path("/tmp/vivid-stream-out.log")


def vivid_nodes() -> tuple[str, str]:
    """(capture, output) device nodes of vivid instance 000, found by sysfs name."""
    names = {p.name: (p / "name").read_text().strip() for p in SYS_V4L.glob("video*")}
    by_name = {v: f"/dev/{k}" for k, v in names.items()}
    try:
        return by_name["vivid-000-vid-cap"], by_name["vivid-000-vid-out"]
    except KeyError:
        raise RuntimeError(f"vivid is not loaded (video nodes: {names})") from None


def write_raw(path: str | Path, frames: list[NDArray[np.uint8]]) -> Path:
    """Write H x W x 3 BGR uint8 frames as one raw file for ``start_loop``."""
    path = Path(path)
    with path.open("wb") as fh:
        for f in frames:
            fh.write(np.ascontiguousarray(f, np.uint8).tobytes())
    return path


def _ctl(*args: str) -> None:
    out = subprocess.run(["v4l2-ctl", *args], capture_output=True, text=True, timeout=120)
    if out.returncode != 0:
        raise RuntimeError(f"v4l2-ctl {' '.join(args)} failed: {out.stderr.strip()}")


def configure_loop(width: int = 640, height: int = 480) -> tuple[str, str]:
    """Select HDMI in/out, 640x480 timings, BGR3 on both sides, and loop_video=1."""
    if (width, height) != (640, 480):
        raise ValueError("only 640x480 (DV timings index 0) is set up; larger is too slow in TCG")
    cap, out = vivid_nodes()
    fmt = f"width={width},height={height},pixelformat=BGR3"
    _ctl("-d", cap, "-i", str(HDMI_INPUT))
    _ctl("-d", cap, f"--set-dv-bt-timings=index={DV_640X480}", f"--set-fmt-video={fmt}")
    # loop_video feeds the output into the capture; osd_text_mode=2 turns off the
    # white status text vivid otherwise draws over the top-left of every frame
    # (it would be the brightest thing in a dark fixture).
    _ctl("-d", cap, "--set-ctrl=loop_video=1,osd_text_mode=2")
    _ctl("-d", out, "-o", str(HDMI_OUTPUT))
    _ctl("-d", out, f"--set-dv-bt-timings=index={DV_640X480}", f"--set-fmt-video-out={fmt}")
    return cap, out


def start_loop(
    raw_path: str | Path, width: int = 640, height: int = 480, *, timeout_s: float = 60.0
) -> tuple[str, subprocess.Popen[bytes]]:
    """Start feeding ``raw_path`` into vivid's output; returns (capture node, process).

    Returns once v4l2-ctl has queued its first frames and a little more (streaming
    must run a while before capture starts); stop it with :func:`stop`.
    """
    size = Path(raw_path).stat().st_size
    if size == 0 or size % (width * height * 3):
        raise ValueError(
            f"{raw_path}: {size} bytes is not a whole number of {width}x{height} BGR frames"
        )
    cap, out = configure_loop(width, height)
    log = LOG.open("wb")
    proc = subprocess.Popen(
        ["v4l2-ctl", "-d", out, "--stream-out-mmap", f"--stream-from={raw_path}", "--stream-loop"],
        stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
    )  # fmt: skip
    log.close()
    deadline = time.monotonic() + timeout_s
    while LOG.read_bytes().count(b">") < 30:  # one '>' per frame handed to the driver
        if proc.poll() is not None:
            raise RuntimeError(f"v4l2-ctl stream-out exited {proc.returncode}: {LOG.read_text()}")
        if time.monotonic() > deadline:
            stop(proc)
            raise RuntimeError(f"v4l2-ctl streamed nothing within {timeout_s} s: {LOG.read_text()}")
        time.sleep(0.1)
    return cap, proc


def stop(proc: subprocess.Popen[bytes]) -> None:
    """Stop the feeding process."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
