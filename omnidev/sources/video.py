"""``video:PATH`` — frames of a video file through OpenCV."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from omnidev.budget import check_pixels
from omnidev.errors import OmnidevError, SourceError
from omnidev.frame import Frame
from omnidev.sources import SourceBase, check_options

MAX_RATE = 1000.0
"""Highest ``rate`` accepted, frames per second."""


class VideoSource(SourceBase):
    """A video file; a :class:`SourceError` when frames end before the announced count.

    Options: ``loop`` (1: start again at the end, for ever) and ``rate``
    (``realtime``: deliver frames at the file's frame rate, or a number of
    frames per second), which make a file behave like a live camera. A paced
    frame's timestamp is the moment it is delivered, as a camera's would be.
    """

    def __init__(self, path: str, *, loop: bool = False, rate: float | None = None) -> None:
        self.path = Path(path)
        self.name = f"video:{path}"
        self.loop = loop
        if not self.path.is_file():
            raise SourceError(f"{self.name}: file not found")
        self._cap = cv2.VideoCapture(str(self.path))
        if not self._cap.isOpened():
            raise SourceError(f"{self.name}: OpenCV cannot read this file as a video")
        w, h = (
            int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH)),
            int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT)),
        )
        try:
            check_pixels(w, h, 12, f"{self.name}: decoding {w}x{h} frames")
        except OmnidevError:
            self._cap.release()
            raise
        n = int(self._cap.get(cv2.CAP_PROP_FRAME_COUNT))
        self.frame_count = n if n > 0 else None
        fps = float(self._cap.get(cv2.CAP_PROP_FPS))
        self.fps = fps if 0 < fps <= MAX_RATE else None
        if rate is not None:
            self.fps = rate
        self._period_ns = round(1e9 / rate) if rate else 0
        self.live = loop or bool(rate)
        if loop:
            self.frame_count = None

    def __iter__(self) -> Iterator[Frame]:
        index = 0
        next_ns = time.monotonic_ns()
        while True:
            in_file = 0
            while True:
                grabbed = self._cap.grab()
                if not grabbed:
                    break
                ok, image = self._cap.retrieve()
                if not ok or image is None or image.size == 0:
                    raise SourceError(f"{self.name}: frame {index} is corrupt (cannot be decoded)")
                if self._period_ns:
                    delay = next_ns - time.monotonic_ns()
                    if delay > 0:
                        time.sleep(delay / 1e9)
                    next_ns = max(next_ns + self._period_ns, time.monotonic_ns())
                yield Frame(np.asarray(image, np.uint8), time.monotonic_ns(), index)
                index += 1
                in_file += 1
            total = int(self._cap.get(cv2.CAP_PROP_FRAME_COUNT))
            if total > 0 and in_file < total:
                last = f"last good frame {index - 1}" if index else "no frame decoded"
                raise SourceError(
                    f"{self.name}: frame {index} is corrupt or missing (truncated file?): "
                    f"read {in_file} of {total} frames, {last}"
                )
            if not self.loop or in_file == 0:
                break
            self._cap.set(cv2.CAP_PROP_POS_FRAMES, 0)

    def close(self) -> None:
        self._cap.release()


def open_video(rest: str, options: dict[str, str]) -> VideoSource:
    uri = f"video:{rest}"
    check_options(uri, options, {"loop", "rate"})
    loop = options.get("loop", "0").lower()
    if loop not in ("0", "1", "yes", "no", "true", "false"):
        raise SourceError(f"{uri}: option loop must be 0 or 1, got {loop!r}")
    rate: float | None = None
    text = options.get("rate")
    if text is not None:
        source = VideoSource(rest)
        try:
            rate = source.fps if text == "realtime" else float(text)
        except ValueError:
            rate = None
        finally:
            source.close()
        if rate is None or not 0 < rate <= MAX_RATE:
            raise SourceError(
                f"{uri}: option rate must be 'realtime' or frames per second in (0, {MAX_RATE:g}]"
            )
    return VideoSource(rest, loop=loop in ("1", "yes", "true"), rate=rate)
