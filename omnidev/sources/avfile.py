"""Video files decoded by FFmpeg's libraries through PyAV, on several threads.

A :class:`~omnidev.sources.Source` like ``video:`` (omnidev.sources.video,
through OpenCV), which it can stand in for where speed matters: ``omnidev
unwarp`` reads a plain video file through it. Compared with cv2.VideoCapture
it decodes on ``threads`` threads (FFmpeg's frame and slice threading), and
it can hand out the decoder's own 4:2:0 planes (:meth:`AvVideoSource.frames`
with layout ``yuv420p`` / ``yuvj420p``, omnidev.outputs) instead of
converting every frame to BGR: for a 1920x1920 MJPEG frame that conversion
costs about a quarter of the decoding time (docs/outputs.md).

Frames come in file order, each exactly once; a file whose frames end before
the count its container announces is a :class:`SourceError` naming the last
good frame, as is a frame that cannot be decoded.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from omnidev.errors import SourceError
from omnidev.frame import Frame
from omnidev.sources import SourceBase

PLANAR = ("yuv420p", "yuvj420p")


def frame_image(vf: Any, fmt: str, size: tuple[int, int], name: str, index: int) -> np.ndarray:
    """A decoded PyAV frame's pixels in ``fmt`` (``bgr24``, ``gray``, ``yuv420p``, ...).

    A frame whose size is not the stream's ``size`` (width, height; px) is refused naming it:
    a damaged file's picture header can say another size mid-stream, which no map fits (and
    PyAV asserts on an odd width in 4:2:0).
    """
    if size[0] > 0 and size[1] > 0 and (vf.width, vf.height) != size:
        raise SourceError(
            f"{name}: frame {index} is {vf.width}x{vf.height}, not the stream's "
            f"{size[0]}x{size[1]} (damaged file, or a size change mid-stream)"
        )
    if vf.format.name != fmt:
        vf = vf.reformat(format=fmt)
    return np.asarray(vf.to_ndarray(), np.uint8)


def available() -> bool:
    """True when PyAV can be imported."""
    try:
        import av  # noqa: F401
    except ImportError:
        return False
    return True


class AvVideoSource(SourceBase):
    """A video file read by PyAV (see the module docstring).

    Attributes:
        native_layout: ``yuv420p`` or ``yuvj420p`` when the decoder produces
            4:2:0 planes (limited or full range), else ``bgr``.
        size: (width, height) of the frames, px.
    """

    def __init__(self, path: str | Path, *, threads: int = 1) -> None:
        import av

        self.path = Path(path)
        self.name = f"video:{path}"
        if not self.path.is_file():
            raise SourceError(f"{self.name}: file not found")
        try:
            self._container: Any = av.open(str(self.path))
        except (av.FFmpegError, UnicodeDecodeError) as exc:
            raise SourceError(
                f"{self.name}: FFmpeg cannot read this file as a video ({exc})"
            ) from None
        if not self._container.streams.video:
            self._container.close()
            raise SourceError(f"{self.name}: the file has no video stream")
        stream = self._container.streams.video[0]
        stream.thread_type = "AUTO"
        stream.thread_count = max(1, threads)
        self._stream = stream
        n = int(stream.frames or 0)
        self.frame_count = n if n > 0 else None
        rate = stream.average_rate or stream.guessed_rate
        self.fps = float(rate) if rate else None
        cc = stream.codec_context
        self.size = (int(cc.width), int(cc.height))
        pix = cc.pix_fmt
        self.native_layout = pix if pix in PLANAR and not (cc.width % 2 or cc.height % 2) else "bgr"

    def __iter__(self) -> Iterator[Frame]:
        return self.frames("bgr")

    def frames(self, layout: str = "bgr") -> Iterator[Frame]:
        """Frames in ``layout``: ``bgr``, ``gray``, or the native 4:2:0 layout."""
        import av

        if layout not in ("bgr", "gray", *PLANAR):
            raise ValueError(f"unknown layout {layout!r}")
        if layout in PLANAR and layout != self.native_layout:
            raise ValueError(f"{self.name}: decodes to {self.native_layout}, not {layout}")
        fmt = {"bgr": "bgr24", "gray": "gray"}.get(layout, layout)
        index = 0
        try:
            for vf in self._container.decode(self._stream):
                image = frame_image(vf, fmt, self.size, self.name, index)
                yield Frame(image, time.monotonic_ns(), index)
                index += 1
        except av.FFmpegError as exc:
            last = f"last good frame {index - 1}" if index else "no frame decoded"
            raise SourceError(
                f"{self.name}: frame {index} cannot be decoded ({exc}); {last}"
            ) from None
        if self.frame_count is not None and index < self.frame_count:
            last = f"last good frame {index - 1}" if index else "no frame decoded"
            raise SourceError(
                f"{self.name}: frame {index} is corrupt or missing (truncated file?): read "
                f"{index} of {self.frame_count} frames, {last}"
            )

    def close(self) -> None:
        self._container.close()
