"""``video:PATH`` — frames of a video file through OpenCV."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from omnidev.errors import SourceError
from omnidev.frame import Frame
from omnidev.sources import SourceBase, check_options


class VideoSource(SourceBase):
    """A video file; a :class:`SourceError` when frames end before the announced count."""

    def __init__(self, path: str) -> None:
        self.path = Path(path)
        self.name = f"video:{path}"
        if not self.path.is_file():
            raise SourceError(f"{self.name}: file not found")
        self._cap = cv2.VideoCapture(str(self.path))
        if not self._cap.isOpened():
            raise SourceError(f"{self.name}: OpenCV cannot read this file as a video")
        n = int(self._cap.get(cv2.CAP_PROP_FRAME_COUNT))
        self.frame_count = n if n > 0 else None
        fps = float(self._cap.get(cv2.CAP_PROP_FPS))
        self.fps = fps if fps > 0 else None

    def __iter__(self) -> Iterator[Frame]:
        index = 0
        while True:
            grabbed = self._cap.grab()
            if not grabbed:
                break
            ok, image = self._cap.retrieve()
            if not ok or image is None or image.size == 0:
                raise SourceError(f"{self.name}: frame {index} is corrupt (cannot be decoded)")
            yield Frame(np.asarray(image, np.uint8), time.monotonic_ns(), index)
            index += 1
        if self.frame_count is not None and index < self.frame_count:
            last = f"last good frame {index - 1}" if index else "no frame decoded"
            raise SourceError(
                f"{self.name}: frame {index} is corrupt or missing (truncated file?): "
                f"read {index} of {self.frame_count} frames, {last}"
            )

    def close(self) -> None:
        self._cap.release()


def open_video(rest: str, options: dict[str, str]) -> VideoSource:
    check_options(f"video:{rest}", options, set())
    return VideoSource(rest)
