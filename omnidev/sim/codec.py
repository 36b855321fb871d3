"""Lossy compression of rendered frames as webcams deliver them: JPEG / MJPEG, MPEG-4, H.264.

The adapter between the scene renderers and the codecs: JPEG through OpenCV
(``cv2.imencode``, quality and chroma subsampling chosen), MPEG-4 part 2 and
H.264 through the ``ffmpeg`` program (its ``mpeg4`` and ``libx264`` encoders,
installed by scripts/install-system-deps.sh), encoded at a bit rate and decoded
back, so the frames carry the codec's real artefacts (blocking, ringing, chroma
bleeding, smearing of small bright details, rate-control changes between
frames). Frames are H x W x 3 BGR uint8; ``ffmpeg`` needs even W and H.
The encoders run on one thread: libx264's sliced threads made the same frames
decode differently from run to run (a scene's figures changed between runs).

Example:
    >>> import numpy as np
    >>> frames = [np.full((48, 64, 3), 128, np.uint8)]
    >>> out = compress_frames(frames, Compression("jpeg", quality=80))
    >>> out[0].shape, abs(int(out[0][10, 10, 1]) - 128) <= 2
    ((48, 64, 3), True)
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.errors import OmnidevError

Codec = Literal["none", "jpeg", "mpeg4", "h264"]
CODECS: tuple[Codec, ...] = ("none", "jpeg", "mpeg4", "h264")
U8 = NDArray[np.uint8]
_SAMPLING = {
    "444": "IMWRITE_JPEG_SAMPLING_FACTOR_444",
    "422": "IMWRITE_JPEG_SAMPLING_FACTOR_422",
    "420": "IMWRITE_JPEG_SAMPLING_FACTOR_420",
}


@dataclass(frozen=True)
class Compression:
    """How a sequence is compressed.

    ``codec``: ``none``, ``jpeg`` (each frame a JPEG, as MJPEG webcams send),
    ``mpeg4`` or ``h264`` (a video stream). ``quality``: JPEG quality 1-100.
    ``chroma``: JPEG chroma subsampling ``444``, ``422`` or ``420``.
    ``bits_per_pixel``: the video bit rate over (width x height x fps), e.g.
    0.05-0.15 for H.264 webcams (0.5-1.4 Mbit/s at 640x480, 30 fps).
    ``gop``: frames between key frames of the video codecs.
    """

    codec: Codec = "none"
    quality: int = 90
    chroma: str = "420"
    bits_per_pixel: float = 0.1
    gop: int = 30

    def describe(self) -> str:
        """A short label: ``jpeg q72 420``, ``h264 0.08 bpp``, ``none``."""
        if self.codec == "jpeg":
            return f"jpeg q{self.quality} {self.chroma}"
        if self.codec in ("mpeg4", "h264"):
            return f"{self.codec} {self.bits_per_pixel:.3f} bpp"
        return "none"


def ffmpeg_path() -> str:
    """The ``ffmpeg`` program, or an OmnidevError saying how to install it."""
    exe = shutil.which("ffmpeg")
    if exe is None:
        raise OmnidevError(
            "ffmpeg not found: MPEG-4 and H.264 scenes need it "
            "(sh scripts/install-system-deps.sh installs the Debian ffmpeg package)"
        )
    return exe


def _jpeg(frame: U8, quality: int, chroma: str) -> U8:
    if chroma not in _SAMPLING:
        raise ValueError(f"JPEG chroma subsampling {chroma!r}: one of {', '.join(_SAMPLING)}")
    params = [cv2.IMWRITE_JPEG_QUALITY, int(quality)]
    flag = getattr(cv2, _SAMPLING[chroma], None)
    if flag is not None:
        params += [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, int(flag)]
    ok, buf = cv2.imencode(".jpg", frame, params)
    if not ok:
        raise OmnidevError("JPEG encoding failed")
    out = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    return np.asarray(out, np.uint8)


def _video(frames: Sequence[U8], comp: Compression, fps: float) -> list[U8]:
    h, w = frames[0].shape[:2]
    if w % 2 or h % 2:
        raise ValueError(f"video compression needs an even frame size, got {w}x{h}")
    exe = ffmpeg_path()
    rate = max(int(comp.bits_per_pixel * w * h * fps), 20_000)
    if comp.codec == "h264":
        codec_args = [
            "-c:v",
            "libx264",
            "-preset",
            "veryfast",
            "-tune",
            "zerolatency",
            "-x264-params",
            f"keyint={comp.gop}:min-keyint={comp.gop}:scenecut=0",
        ]
        fmt, ext = "h264", ".h264"
    else:
        codec_args = ["-c:v", "mpeg4", "-g", str(comp.gop), "-bf", "0"]
        fmt, ext = "m4v", ".m4v"
    with tempfile.TemporaryDirectory(prefix="omnidev-codec-") as tmp:
        path = Path(tmp) / f"v{ext}"
        enc = [
            exe,
            "-v",
            "error",
            "-f",
            "rawvideo",
            "-pix_fmt",
            "bgr24",
            "-s",
            f"{w}x{h}",
            "-r",
            f"{fps:g}",
            "-i",
            "-",
            *codec_args,
            "-threads",
            "1",
            "-b:v",
            str(rate),
            "-maxrate",
            str(rate),
            "-bufsize",
            str(max(rate // 2, 10_000)),
            "-pix_fmt",
            "yuv420p",
            "-f",
            fmt,
            "-y",
            str(path),
        ]
        data = b"".join(np.ascontiguousarray(f, np.uint8).tobytes() for f in frames)
        done = subprocess.run(enc, input=data, capture_output=True, check=False)
        if done.returncode != 0:
            raise OmnidevError(
                f"ffmpeg {comp.codec} encoding failed: {done.stderr.decode()[-300:]}"
            )
        dec = [exe, "-v", "error", "-f", fmt, "-i", str(path)]
        dec += ["-f", "rawvideo", "-pix_fmt", "bgr24", "-"]
        got = subprocess.run(dec, capture_output=True, check=False)
        if got.returncode != 0:
            raise OmnidevError(f"ffmpeg {comp.codec} decoding failed: {got.stderr.decode()[-300:]}")
    raw = np.frombuffer(got.stdout, np.uint8)
    n = raw.size // (w * h * 3)
    if n < len(frames):
        raise OmnidevError(f"ffmpeg {comp.codec}: {n} frames decoded of {len(frames)} encoded")
    video = raw[: len(frames) * w * h * 3].reshape(len(frames), h, w, 3)
    return [np.array(f) for f in video]


def compress_frames(frames: Sequence[U8], comp: Compression, *, fps: float = 30.0) -> list[U8]:
    """The frames after compression ``comp`` and decoding (BGR uint8, same sizes).

    A video codec sees the frames as one stream at ``fps`` (its rate control
    spends ``comp.bits_per_pixel`` on average, the first frame is a key frame).
    """
    if not frames:
        return []
    if comp.codec == "none":
        return [np.array(f, np.uint8) for f in frames]
    if comp.codec == "jpeg":
        return [_jpeg(f, comp.quality, comp.chroma) for f in frames]
    if comp.codec in ("mpeg4", "h264"):
        return _video(frames, comp, fps)
    raise ValueError(f"codec {comp.codec!r}: one of {', '.join(CODECS)}")
